//! Checkpoints of a run over several processes in pieces, none gathered: process k writes the
//! spheres it owns, with their contact history, as `checkpoint_<step>_<k>.bin` in a folder of the
//! step ([`piece_folder_for`]), and once every piece is written process 0 writes the index in the
//! checkpoint's place (`checkpoint.bin`): the scene, the run's state, the folder, and each
//! piece's sphere count and checksum. [`super::read_checkpoint`] reads an index as the whole
//! checkpoint, its pieces joined in the order of their ids, equal to the checkpoint one process
//! would write of the same run: a run resumes from it on any number of processes.
//!
//! The index replaces the last one atomically, and names a folder that no earlier index named
//! (a step written again gets a folder of its own), so the checkpoint on disk is always whole;
//! the folders no index names are removed once the new index is written.
//!
//! Index layout (little-endian, version 1): `MOCHICPI`, version u32, step u64, spheres u64,
//! scene length u64, scene TOML, state length u64, state TOML, folder name length u64, folder
//! name (UTF-8, a folder beside the index), pieces u64, each piece's spheres u64 and checksum
//! u32, then the CRC-32 of every byte before it. Piece layout (version 1): `MOCHICPP`, version
//! u32, step u64, piece u64, m u64, then the m whole-run ids (u32, ascending), m·3 f32
//! positions, m·3 f32 velocities, m·3 f32 angular velocities, m f32 radii, m·3 f32 position
//! residuals, history entries u64 and each as owner u32 (the sphere's place in the piece),
//! partner u32 (a whole-run id, or a wall's), 3 f32 tangential spring, 3 f32 rolling spring,
//! load histories u64 (0 or one an entry) and each as 3 f32 reversal force and f32 normal
//! force, materials u64 (0 or m) and each as a u8, then the CRC-32 of every byte before it
//! (the checksum the index names).

use super::checkpoint_bytes::{
    Fields, HistoryFilter, KeptHistory, SphereBytes, check_read, decode_history, from_le_words,
    is_kept, le_words, write_with_checksum,
};
use super::{Checkpoint, io_error, write_atomically};
use crate::error::{Error, Result};
use crate::particles::{ContactHistory, HistoryEntry, LoadEntry, Particles};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

pub(super) const INDEX_MAGIC: &[u8; 8] = b"MOCHICPI";
const PIECE_MAGIC: &[u8; 8] = b"MOCHICPP";
const VERSION: u32 = 1;

/// What process 0 hears of a piece another wrote: its spheres and the checksum its file ends
/// with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct CheckpointPiece {
    /// Spheres in the piece.
    pub spheres: u64,
    /// The CRC-32 its file ends with.
    pub checksum: u32,
    /// Zero (the record's padding).
    padding: u32,
}

/// One process's spheres as its piece holds them: the whole-run ids (ascending) of the spheres
/// of `spheres` (whose history is not read), and their contacts, each owner a place in
/// `spheres` and each partner a whole-run id (or a wall's), with their load histories (none, or
/// one a contact).
pub struct PieceSpheres<'a> {
    /// The whole-run id of each sphere, ascending.
    pub ids: &'a [u32],
    /// The spheres, in the order of `ids` (their history is not read).
    pub spheres: &'a Particles,
    /// Their contacts: the owner's place in `spheres`, the entry (partner by whole-run id).
    pub contacts: &'a [(u32, HistoryEntry)],
    /// The contacts' load histories: none, or one a contact.
    pub loads: &'a [LoadEntry],
}

/// A free folder beside the index at `index` for the pieces of the checkpoint of step `step`:
/// `checkpoint_<step>`, or `checkpoint_<step>-<k>` where that exists (named by an index on disk,
/// or left by a killed run).
pub fn piece_folder_for(index: &Path, step: u64) -> PathBuf {
    let dir = index.parent().unwrap_or(Path::new("."));
    let stem = folder_stem(step);
    let mut folder = dir.join(&stem);
    let mut k = 2;
    while folder.exists() {
        folder = dir.join(format!("{stem}-{k}"));
        k += 1;
    }
    folder
}

fn folder_stem(step: u64) -> String {
    format!("checkpoint_{step:08}")
}

/// The file of piece `piece` of the checkpoint of step `step` in its folder `folder`.
pub fn checkpoint_piece_path(folder: &Path, step: u64, piece: usize) -> PathBuf {
    folder.join(format!("{}_{piece}.bin", folder_stem(step)))
}

/// Whether `name` is the name of a checkpoint's folder of pieces.
pub(super) fn is_piece_folder_name(name: &str) -> bool {
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    name.strip_prefix("checkpoint_")
        .is_some_and(|rest| match rest.split_once('-') {
            Some((step, k)) => digits(step) && digits(k),
            None => digits(rest),
        })
}

/// The whole-run `step` of a checkpoint's folder of pieces named `name`.
fn folder_step(name: &str) -> Option<u64> {
    let rest = name.strip_prefix("checkpoint_")?;
    rest.split_once('-').map_or(rest, |(s, _)| s).parse().ok()
}

/// Whether the folder `folder` holds nothing but pieces of a checkpoint of the step of its name
/// (and the temporary files of killed writers).
pub(super) fn holds_only_pieces(folder: &Path) -> Result<bool> {
    let Some(step) = (folder.file_name().and_then(|n| n.to_str())).and_then(folder_step) else {
        return Ok(false);
    };
    super::pieces::holds_only_files(folder, &format!("{}_", folder_stem(step)), ".bin")
}

/// Writes `share` as piece `piece` of the checkpoint of step `share.spheres.step` into
/// `folder` (created where missing), atomically; returns what the index names of it.
pub fn write_checkpoint_piece(
    folder: &Path,
    piece: usize,
    share: &PieceSpheres,
) -> Result<CheckpointPiece> {
    let p = share.spheres;
    let m = share.ids.len();
    if p.len() != m || (!share.loads.is_empty() && share.loads.len() != share.contacts.len()) {
        return Err(Error::Usage(
            "a checkpoint's piece needs one id a sphere and none or one load a contact".into(),
        ));
    }
    std::fs::create_dir_all(folder).map_err(io_error(folder))?;
    let mut head = Vec::with_capacity(36);
    head.extend_from_slice(PIECE_MAGIC);
    head.extend_from_slice(&VERSION.to_le_bytes());
    head.extend_from_slice(&p.step.to_le_bytes());
    head.extend_from_slice(&(piece as u64).to_le_bytes());
    head.extend_from_slice(&(m as u64).to_le_bytes());
    let ids = le_words(share.ids);
    let spheres = SphereBytes::with_contacts(p, share.contacts, share.loads);
    let body = spheres.sections();
    let sections: Vec<&[u8]> = [&head[..], &ids[..]]
        .into_iter()
        .chain(body.iter().map(|s| &s[..]))
        .collect();
    let path = checkpoint_piece_path(folder, p.step, piece);
    let checksum = write_with_checksum(&path, &sections)?;
    Ok(CheckpointPiece {
        spheres: m as u64,
        checksum,
        padding: 0,
    })
}

/// Writes the index of a checkpoint in pieces at `index` (in the checkpoint's place),
/// atomically: the checkpoint of step `step` of `pieces`, whose files lie in `folder` (beside
/// the index), of the run of `scene` (TOML) with the run's `state` (TOML).
pub fn write_checkpoint_index(
    index: &Path,
    (folder, step): (&Path, u64),
    (scene, state): (&str, &str),
    pieces: &[CheckpointPiece],
) -> Result<()> {
    let name = (folder.file_name().and_then(|n| n.to_str()))
        .filter(|n| is_piece_folder_name(n))
        .ok_or_else(|| {
            Error::Usage(format!(
                "{} is not a folder of a checkpoint's pieces",
                folder.display()
            ))
        })?;
    let spheres: u64 = pieces.iter().map(|p| p.spheres).sum();
    let mut bytes = Vec::new();
    bytes.extend_from_slice(INDEX_MAGIC);
    bytes.extend_from_slice(&VERSION.to_le_bytes());
    bytes.extend_from_slice(&step.to_le_bytes());
    bytes.extend_from_slice(&spheres.to_le_bytes());
    for text in [scene, state, name] {
        bytes.extend_from_slice(&(text.len() as u64).to_le_bytes());
        bytes.extend_from_slice(text.as_bytes());
    }
    bytes.extend_from_slice(&(pieces.len() as u64).to_le_bytes());
    for piece in pieces {
        bytes.extend_from_slice(&piece.spheres.to_le_bytes());
        bytes.extend_from_slice(&piece.checksum.to_le_bytes());
    }
    let crc = crc32fast::hash(&bytes);
    bytes.extend_from_slice(&crc.to_le_bytes());
    write_atomically(index, |out| out.write_all(&bytes))
}

/// Removes the folders of checkpoints' pieces beside `index` other than `keep` (those of
/// earlier checkpoints, which no index names any more), where they hold nothing but pieces.
pub fn remove_other_piece_folders(index: &Path, keep: Option<&Path>) -> Result<()> {
    let dir = match index.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    for folder in piece_folders_in(dir)? {
        let kept = keep.is_some_and(|k| k.file_name() == folder.file_name());
        if !kept {
            std::fs::remove_dir_all(&folder).map_err(io_error(&folder))?;
        }
    }
    Ok(())
}

/// The folders of checkpoints' pieces in `dir` that hold nothing but pieces.
pub(super) fn piece_folders_in(dir: &Path) -> Result<Vec<PathBuf>> {
    super::pieces::folders_in(dir, is_piece_folder_name, holds_only_pieces)
}

/// Reads the head of a file of this format (`magic`, then its version) from `f`, naming the
/// file `what` where it is not one.
fn check_version(f: &mut Fields, magic: &[u8; 8], what: &str) -> Result<()> {
    if f.take(8, "header")? != magic {
        return Err(f.bad(format!("not a {what}")));
    }
    let version = u32::from_le_bytes(f.take(4, "version")?.try_into().expect("4 bytes"));
    if version != VERSION {
        return Err(f.bad(format!(
            "{what} version {version}; this mochi reads version {VERSION}"
        )));
    }
    Ok(())
}

/// One piece as read.
struct Piece {
    ids: Vec<u32>,
    positions: Vec<[f32; 3]>,
    velocities: Vec<[f32; 3]>,
    angular_velocities: Vec<[f32; 3]>,
    radii: Vec<f32>,
    residuals: Vec<[f32; 3]>,
    entries: Vec<[u32; 8]>,
    loads: Vec<[f32; 4]>,
    materials: Vec<u8>,
}

/// Reads the index of a checkpoint in pieces at `path` and its pieces, joined.
pub(super) fn read_checkpoint_pieces(
    path: &Path,
    bytes: &[u8],
    keep: Option<HistoryFilter>,
) -> Result<(Checkpoint, Option<KeptHistory>)> {
    let mut f = Fields::new(path, bytes);
    check_version(&mut f, INDEX_MAGIC, "mochi checkpoint index")?;
    let step = f.u64("step")?;
    let n = f.u64("sphere count")?;
    let scene = f.text("scene")?;
    let state = f.text("run's state")?;
    let name = f.text("folder of pieces")?;
    let (count, listed) = f.counted(12, "pieces")?;
    f.checksum()?;
    if !is_piece_folder_name(&name) {
        return Err(f.bad(format!("{name:?} is not a folder of a checkpoint's pieces")));
    }
    let listed: Vec<(u64, u32)> = (listed.chunks_exact(12))
        .map(|c| {
            let spheres = u64::from_le_bytes(c[..8].try_into().expect("8 bytes"));
            (spheres, u32::from_le_bytes(c[8..].try_into().expect("4")))
        })
        .collect();
    debug_assert_eq!(listed.len(), count);
    let total = listed.iter().try_fold(0u64, |s, &(m, _)| s.checked_add(m));
    if total != Some(n) || u32::try_from(n).is_err() {
        return Err(f.bad(format!("its pieces do not hold its {n} spheres")));
    }
    let folder = path.parent().unwrap_or(Path::new(".")).join(&name);
    let pieces = (listed.par_iter().enumerate())
        .map(|(k, &(m, checksum))| {
            read_piece(
                &checkpoint_piece_path(&folder, step, k),
                (step, k),
                (m, checksum),
            )
        })
        .collect::<Result<Vec<Piece>>>()?;
    let bad = |e: Error| f.bad(e.to_string());
    let (particles, kept) = join(pieces, n as usize, step, |p| match keep {
        Some(keep) => keep(&scene, p).map(Some),
        None => Ok(None),
    })
    .map_err(bad)?;
    let checkpoint = Checkpoint {
        particles,
        scene,
        state,
    };
    Ok((checkpoint, kept))
}

/// Reads piece `k` of the checkpoint of step `step` at `path`, whose index names `m` spheres
/// and the checksum `checksum`.
fn read_piece(path: &Path, (step, k): (u64, usize), (m, checksum): (u64, u32)) -> Result<Piece> {
    let bytes = std::fs::read(path).map_err(io_error(path))?;
    let mut f = Fields::new(path, &bytes);
    check_version(&mut f, PIECE_MAGIC, "piece of a mochi checkpoint")?;
    let (at_step, piece, spheres) = (f.u64("step")?, f.u64("piece")?, f.u64("sphere count")?);
    if (at_step, piece, spheres) != (step, k as u64, m) {
        return Err(f.bad(format!(
            "piece {piece} of step {at_step} with {spheres} spheres where the index names \
             piece {k} of step {step} with {m}"
        )));
    }
    let m = usize::try_from(m).map_err(|_| f.bad(format!("{m} spheres cannot fit in memory")))?;
    let ids = f.each(m, 4, "ids")?;
    let positions = f.each(m, 12, "positions")?;
    let velocities = f.each(m, 12, "velocities")?;
    let spins = f.each(m, 12, "angular velocities")?;
    let radii = f.each(m, 4, "radii")?;
    let residuals = f.each(m, 12, "position residuals")?;
    let (entries, entry_bytes) = f.counted(32, "history entries")?;
    let (loads, load_bytes) = f.counted(16, "load histories")?;
    let (materials, material_bytes) = f.counted(1, "materials")?;
    if loads != 0 && loads != entries {
        return Err(f.bad(format!(
            "{loads} load histories for {entries} history entries"
        )));
    }
    if materials != 0 && materials != m {
        return Err(f.bad(format!("{materials} materials for {m} spheres")));
    }
    let stored = f.checksum()?;
    if stored != checksum {
        return Err(f.bad(
            "this piece is not the one its index names (its checksum differs): the checkpoint's \
             pieces are of different writes"
                .into(),
        ));
    }
    Ok(Piece {
        ids: from_le_words(ids),
        positions: from_le_words(positions),
        velocities: from_le_words(velocities),
        angular_velocities: from_le_words(spins),
        radii: from_le_words(radii),
        residuals: from_le_words(residuals),
        entries: from_le_words(entry_bytes),
        loads: from_le_words(load_bytes),
        materials: material_bytes.to_vec(),
    })
}

/// The `n` spheres of `pieces` in the order of their ids, each id once, with their history:
/// every sphere's, or, where `keep` flags the spheres whose history to keep (given the spheres
/// without it), theirs beside them.
fn join(
    pieces: Vec<Piece>,
    n: usize,
    step: u64,
    keep: impl FnOnce(&Particles) -> Result<Option<Vec<bool>>>,
) -> Result<(Particles, Option<KeptHistory>)> {
    let mut place = vec![u32::MAX; n];
    for (k, piece) in pieces.iter().enumerate() {
        for &id in &piece.ids {
            match place.get_mut(id as usize) {
                Some(p) if *p == u32::MAX => *p = k as u32,
                Some(_) => return Err(Error::Usage(format!("sphere {id} is in two pieces"))),
                None => return Err(Error::Usage(format!("sphere {id} of {n}"))),
            }
        }
    }
    let mut p = Particles {
        positions: vec![[0.0; 3]; n],
        position_residuals: vec![[0.0; 3]; n],
        velocities: vec![[0.0; 3]; n],
        angular_velocities: vec![[0.0; 3]; n],
        radii: vec![0.0; n],
        step,
        ..Particles::default()
    };
    let materials = pieces.iter().any(|piece| !piece.materials.is_empty());
    if materials {
        p.materials = vec![0; n];
    }
    for piece in &pieces {
        for (j, &id) in piece.ids.iter().enumerate() {
            let i = id as usize;
            p.positions[i] = piece.positions[j];
            p.position_residuals[i] = piece.residuals[j];
            p.velocities[i] = piece.velocities[j];
            p.angular_velocities[i] = piece.angular_velocities[j];
            p.radii[i] = piece.radii[j];
            if let Some(&m) = piece.materials.get(j) {
                p.materials[i] = m;
            }
        }
        if piece.loads.is_empty()
            && !piece.entries.is_empty()
            && pieces.iter().any(|q| !q.loads.is_empty())
        {
            return Err(Error::Usage(
                "some pieces keep load histories and some do not".into(),
            ));
        }
    }
    check_read(&p)?;
    let kept = keep(&p)?;
    let (mut contacts, mut loads) = (Vec::new(), Vec::new());
    for piece in &pieces {
        let load = |k: usize| piece.loads[k];
        let place = |at: u32| match piece.ids.get(at as usize) {
            Some(&id) => Ok(id),
            None => Err(Error::Usage(format!(
                "a history entry of sphere {at} of a piece"
            ))),
        };
        let (c, l) = decode_history(
            piece.entries.len(),
            |k| piece.entries[k],
            (!piece.loads.is_empty()).then_some(&load),
            place,
            |at| is_kept(kept.as_deref(), at),
        )?;
        contacts.extend(c);
        loads.extend(l);
    }
    drop(pieces);
    match kept {
        Some(kept) => Ok((p, Some(KeptHistory::checked(n, kept, (contacts, loads))?))),
        None => {
            p.history = ContactHistory::from_contacts_with_loads(n, &contacts, &loads)?;
            Ok((p, None))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{read_checkpoint, read_checkpoint_keeping_history, write_checkpoint};
    use crate::particles::FIRST_WALL;

    fn entry(partner: u32, x: f32) -> HistoryEntry {
        HistoryEntry {
            partner,
            tangential: [x, -x, 0.5 * x],
            rolling: [0.0, x, 0.25 * x],
        }
    }

    /// Seven spheres of two materials, contacts between them and with a wall, each with its
    /// load history.
    fn whole() -> Particles {
        let n = 7;
        let f = |i: usize, k: f32| i as f32 * k;
        let contacts = [
            (0, entry(3, 1e-6)),
            (3, entry(0, -1e-6)),
            (3, entry(6, 2e-6)),
            (6, entry(3, -2e-6)),
            (5, entry(FIRST_WALL + 2, 3e-5)),
            (1, entry(2, 4e-7)),
            (2, entry(1, -4e-7)),
        ];
        let loads: Vec<LoadEntry> = (0..contacts.len())
            .map(|k| LoadEntry {
                reversal: [k as f32, 0.0, -1.0],
                normal: 0.5 + k as f32,
            })
            .collect();
        Particles {
            positions: (0..n).map(|i| [f(i, 0.1), f(i, -0.2), 0.3]).collect(),
            position_residuals: (0..n).map(|i| [f(i, 1e-9), 0.0, -3e-9]).collect(),
            velocities: (0..n).map(|i| [0.0, f(i, -1.5), 2.0]).collect(),
            angular_velocities: (0..n).map(|i| [f(i, 3.0), 1.0, 0.0]).collect(),
            radii: (0..n).map(|i| 0.01 + f(i, 1e-3)).collect(),
            materials: vec![0, 1, 0, 2, 1, 0, 0],
            history: ContactHistory::from_contacts_with_loads(n, &contacts, &loads).unwrap(),
            step: 4321,
            ..Particles::default()
        }
    }

    /// Writes `p` in pieces, sphere i in piece `piece_of[i]` of `pieces`, into `dir`, and the
    /// index `dir/checkpoint.bin`; returns the index and the folder.
    fn write_in_pieces(p: &Particles, piece_of: &[usize], pieces: usize, dir: &Path) -> PathBuf {
        let index = dir.join("checkpoint.bin");
        let folder = piece_folder_for(&index, p.step);
        let written: Vec<CheckpointPiece> = (0..pieces)
            .map(|k| {
                let ids: Vec<u32> = (0..p.len() as u32)
                    .filter(|&i| piece_of[i as usize] == k)
                    .collect();
                let at = |i: &u32| *i as usize;
                let column = |c: &[[f32; 3]]| ids.iter().map(|i| c[at(i)]).collect();
                let spheres = Particles {
                    positions: column(&p.positions),
                    position_residuals: column(&p.position_residuals),
                    velocities: column(&p.velocities),
                    angular_velocities: column(&p.angular_velocities),
                    radii: ids.iter().map(|i| p.radii[at(i)]).collect(),
                    materials: match p.materials.is_empty() {
                        true => Vec::new(),
                        false => ids.iter().map(|i| p.materials[at(i)]).collect(),
                    },
                    step: p.step,
                    ..Particles::default()
                };
                let mut contacts = Vec::new();
                let mut loads = Vec::new();
                for (j, i) in ids.iter().enumerate() {
                    contacts.extend(p.history.of(at(i)).iter().map(|&e| (j as u32, e)));
                    loads.extend_from_slice(p.history.loads_of(at(i)));
                }
                let share = PieceSpheres {
                    ids: &ids,
                    spheres: &spheres,
                    contacts: &contacts,
                    loads: &loads,
                };
                write_checkpoint_piece(&folder, k, &share).unwrap()
            })
            .collect();
        write_checkpoint_index(&index, (&folder, p.step), ("scene", "[flow]\n"), &written).unwrap();
        index
    }

    #[test]
    fn a_read_keeping_some_spheres_history_keeps_theirs_alone_whole_or_in_pieces() {
        let dir = tempfile::tempdir().unwrap();
        let p = whole();
        let index = write_in_pieces(&p, &[1, 0, 1, 0, 2, 0, 1], 3, dir.path());
        let path = dir.path().join("whole.bin");
        write_checkpoint(&path, &p, "scene", "[flow]\n").unwrap();
        // Spheres 1, 3 and 5 (a contact with a sphere, two, one with a wall), told by the
        // spheres read without their history.
        let odd = |scene: &str, q: &Particles| {
            assert_eq!(scene, "scene");
            assert_eq!(q.history.slots(), 0);
            Ok((0..q.len()).map(|i| i % 2 == 1).collect())
        };
        let wanted: Vec<(u32, HistoryEntry)> = (0..p.len())
            .filter(|i| i % 2 == 1)
            .flat_map(|i| p.history.of(i).iter().map(move |&e| (i as u32, e)))
            .collect();
        let wanted_loads: Vec<LoadEntry> = (0..p.len())
            .filter(|i| i % 2 == 1)
            .flat_map(|i| p.history.loads_of(i).to_vec())
            .collect();
        assert_eq!(wanted.len(), 4);
        for at in [&path, &index] {
            let (read, kept) = read_checkpoint_keeping_history(at, &odd).unwrap();
            let without = Particles {
                history: ContactHistory::default(),
                ..p.clone()
            };
            assert_eq!(read.particles, without);
            assert_eq!(
                kept.kept,
                (0..p.len()).map(|i| i % 2 == 1).collect::<Vec<_>>()
            );
            // Each owner's contacts in its order, with their loads (the pieces deal the
            // owners out).
            let mut both: Vec<_> = kept.contacts.into_iter().zip(kept.loads).collect();
            both.sort_by_key(|(c, _)| c.0);
            let (contacts, loads): (Vec<_>, Vec<_>) = both.into_iter().unzip();
            assert_eq!(contacts, wanted);
            assert_eq!(loads, wanted_loads);
            // A filter that does not name every sphere is refused.
            let short = |_: &str, q: &Particles| Ok(vec![true; q.len() - 1]);
            let e = read_checkpoint_keeping_history(at, &short).unwrap_err();
            assert!(e.to_string().contains("6 spheres of 7"), "{e}");
        }
    }

    #[test]
    fn a_checkpoint_in_pieces_reads_back_as_the_whole_checkpoint() {
        let dir = tempfile::tempdir().unwrap();
        let p = whole();
        assert!(p.history.has_loads());
        // Spheres dealt out of order, one piece empty.
        let index = write_in_pieces(&p, &[2, 0, 2, 0, 2, 0, 2], 4, dir.path());
        let read = read_checkpoint(&index).unwrap();
        assert_eq!(
            (read.scene.as_str(), read.state.as_str()),
            ("scene", "[flow]\n")
        );
        // Equal to the whole checkpoint of the same spheres, bit for bit.
        let path = dir.path().join("whole.bin");
        write_checkpoint(&path, &p, "scene", "[flow]\n").unwrap();
        assert_eq!(read, read_checkpoint(&path).unwrap());
        assert_eq!(read.particles, p);
        for i in 0..p.len() {
            assert_eq!(read.particles.history.loads_of(i), p.history.loads_of(i));
        }
        // Without materials, loads or contacts alike.
        for q in [
            Particles {
                materials: Vec::new(),
                ..whole()
            },
            Particles {
                history: ContactHistory::default(),
                ..whole()
            },
        ] {
            let dir = tempfile::tempdir().unwrap();
            let index = write_in_pieces(&q, &[0, 1, 0, 1, 0, 1, 0], 2, dir.path());
            assert_eq!(read_checkpoint(&index).unwrap().particles, q);
        }
    }

    #[test]
    fn a_new_checkpoint_in_pieces_takes_a_folder_of_its_own_and_removes_the_others() {
        let dir = tempfile::tempdir().unwrap();
        let p = whole();
        let first = write_in_pieces(&p, &[0, 1, 0, 1, 0, 1, 0], 2, dir.path());
        let folder = dir.path().join("checkpoint_00004321");
        assert!(checkpoint_piece_path(&folder, p.step, 1).exists());
        // The same step again: another folder, while the first stays whole.
        let again = piece_folder_for(&first, p.step);
        assert_eq!(again, dir.path().join("checkpoint_00004321-2"));
        write_in_pieces(&p, &[1, 1, 0, 0, 0, 1, 0], 2, dir.path());
        assert!(again.exists());
        std::fs::write(dir.path().join("checkpoint_00000001.txt"), "not ours").unwrap();
        remove_other_piece_folders(&first, Some(&again)).unwrap();
        assert!(!folder.exists() && again.exists());
        assert!(dir.path().join("checkpoint_00000001.txt").exists());
        assert_eq!(read_checkpoint(&first).unwrap().particles, p);
        remove_other_piece_folders(&first, None).unwrap();
        assert!(!again.exists());
    }

    #[test]
    fn a_checkpoint_whose_pieces_are_missing_damaged_or_of_another_write_is_an_error() {
        let p = whole();
        let deal = [0, 1, 0, 1, 0, 1, 0];
        let error = |damage: &dyn Fn(&Path, &Path)| {
            let dir = tempfile::tempdir().unwrap();
            let index = write_in_pieces(&p, &deal, 2, dir.path());
            let folder = dir.path().join("checkpoint_00004321");
            damage(&index, &folder);
            read_checkpoint(&index).unwrap_err().to_string()
        };
        let piece = |folder: &Path, k| checkpoint_piece_path(folder, 4321, k);
        let e = error(&|_, folder| std::fs::remove_file(piece(folder, 1)).unwrap());
        assert!(e.contains("checkpoint_00004321_1.bin"), "{e}");
        let e = error(&|_, folder| {
            let mut bytes = std::fs::read(piece(folder, 0)).unwrap();
            bytes[60] ^= 1;
            std::fs::write(piece(folder, 0), bytes).unwrap();
        });
        assert!(e.contains("checksum mismatch"), "{e}");
        // A piece of another write of the same step, whole in itself.
        let e = error(&|_, folder| {
            let other = tempfile::tempdir().unwrap();
            let moved = Particles {
                velocities: vec![[9.0; 3]; 7],
                ..whole()
            };
            write_in_pieces(&moved, &deal, 2, other.path());
            let theirs = piece(&other.path().join("checkpoint_00004321"), 1);
            std::fs::copy(theirs, piece(folder, 1)).unwrap();
        });
        assert!(e.contains("not the one its index names"), "{e}");
        let e = error(&|index, _| {
            let mut bytes = std::fs::read(index).unwrap();
            let last = bytes.len() - 1;
            bytes[last] ^= 1;
            std::fs::write(index, bytes).unwrap();
        });
        assert!(e.contains("checksum mismatch"), "{e}");
        // A sphere in two pieces.
        let dir = tempfile::tempdir().unwrap();
        let index = dir.path().join("checkpoint.bin");
        let folder = piece_folder_for(&index, 7);
        let one = Particles {
            positions: vec![[0.0; 3]],
            velocities: vec![[0.0; 3]],
            angular_velocities: vec![[0.0; 3]],
            radii: vec![0.1],
            step: 7,
            ..Particles::default()
        };
        let share = |ids| PieceSpheres {
            ids,
            spheres: &one,
            contacts: &[],
            loads: &[],
        };
        let written: Vec<CheckpointPiece> = (0..2)
            .map(|k| write_checkpoint_piece(&folder, k, &share(&[0])).unwrap())
            .collect();
        write_checkpoint_index(&index, (&folder, 7), ("", ""), &written).unwrap();
        let e = read_checkpoint(&index).unwrap_err().to_string();
        assert!(e.contains("sphere 0 is in two pieces"), "{e}");
    }
}
