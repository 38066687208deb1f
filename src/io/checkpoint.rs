//! Checkpoints: the particles, their contact history, the step count, the scene (as TOML) and
//! the run's state besides the particles (as TOML: what its flows did, digests of the files it
//! reads) in one little-endian binary file, written atomically so the file on disk is always a
//! whole checkpoint.
//!
//! Layout (version 8): `MOCHICKP`, version u32, step u64, n u64, scene length u64, scene TOML
//! (UTF-8), state length u64, state TOML (UTF-8), then n·3 f32 positions (the `f32` centres),
//! n·3 f32 velocities, n·3 f32 angular velocities, n f32 radii, n·3 f32 position residuals
//! (each centre plus its residual is the sphere's position, as [`Particles`] holds it: saved as
//! the pair, a resumed run goes on bit for bit), the number of history entries u64 and each
//! entry as owner u32, partner u32, 3 f32 tangential spring, 3 f32 rolling spring (owners in
//! order), the number of load histories u64 (0, or that of the entries: the
//! Mindlin–Deresiewicz model's) and each as 3 f32 reversal force, f32 normal force (in the
//! entries' order), the number of materials u64 (0: every sphere of the first material, or n)
//! and each sphere's material as a u8 (as [`Particles::materials`] holds them), the clumps
//! ([`Particles::clumps`]: the number of kinds u64 and each kind as its name's length u64, its
//! name (UTF-8), its component count u64, each component as 4 f64 (centre, radius), its mass
//! f64 and 3 f64 principal moments; the number of clumps u64 and each as its kind u64, 3 f64
//! centre, 4 f64 orientation (x, y, z, w), 3 f64 velocity, 3 f64 angular momentum), and last
//! the CRC-32 (u32) of every byte before it: a damaged file is refused rather than resumed.
//! Version 7 (no clumps) is still read without them, version 6 (no materials) is still read without them (every sphere of the first material),
//! version 5 (no load histories either) without those, version 4 (no residuals either) with
//! residuals of 0, version 3 (no state either) with an empty state, and version 2 (no angular
//! velocities, no history) as spheres at rest in rotation without history.

use super::checkpoint_bytes::{
    Fields, HistoryFilter, KeptHistory, SphereBytes, check_read, decode_history, from_le_words,
    is_kept, le_word_array, write_with_checksum,
};
use super::io_error;
use crate::clump::{
    Clump, ClumpKind, ClumpSet, ClumpTemplate, Component, PrincipalInertia, RigidBody,
};
use crate::error::{Error, Result};
use crate::particles::{ContactHistory, Particles};
use glam::{DQuat, DVec3};
use std::path::Path;

const MAGIC: &[u8; 8] = b"MOCHICKP";
const VERSION: u32 = 8;
/// The oldest version this mochi reads.
const OLDEST: u32 = 2;
/// Bytes of one history entry: owner, partner and six f32.
const ENTRY_BYTES: usize = 32;
/// Bytes of one load history: four f32.
const LOAD_BYTES: usize = 16;

/// What a checkpoint holds.
#[derive(Debug, Clone, PartialEq)]
pub struct Checkpoint {
    /// The particles (their step included).
    pub particles: Particles,
    /// The scene, as TOML.
    pub scene: String,
    /// The run's state besides the particles, as TOML (empty in checkpoints of version 3 and
    /// older).
    pub state: String,
}

/// Writes `particles`, `scene` (TOML) and the run's `state` (TOML) to `path`, atomically.
pub fn write_checkpoint(
    path: &Path,
    particles: &Particles,
    scene: &str,
    state: &str,
) -> Result<()> {
    let mut head = Vec::with_capacity(44 + scene.len() + state.len());
    head.extend_from_slice(MAGIC);
    head.extend_from_slice(&VERSION.to_le_bytes());
    head.extend_from_slice(&particles.step.to_le_bytes());
    head.extend_from_slice(&(particles.len() as u64).to_le_bytes());
    head.extend_from_slice(&(scene.len() as u64).to_le_bytes());
    head.extend_from_slice(scene.as_bytes());
    head.extend_from_slice(&(state.len() as u64).to_le_bytes());
    head.extend_from_slice(state.as_bytes());
    let spheres = SphereBytes::of_particles(particles);
    let mut clumps = Vec::new();
    write_clumps(&mut clumps, &particles.clumps);
    let body = spheres.sections();
    let sections: Vec<&[u8]> = [&head[..]]
        .into_iter()
        .chain(body.iter().map(|s| &s[..]))
        .chain([&clumps[..]])
        .collect();
    write_with_checksum(path, &sections).map(|_| ())
}

/// Appends `set` as the checkpoint holds it.
fn write_clumps(bytes: &mut Vec<u8>, set: &ClumpSet) {
    let f64s = |bytes: &mut Vec<u8>, xs: &[f64]| {
        for x in xs {
            bytes.extend_from_slice(&x.to_le_bytes());
        }
    };
    bytes.extend_from_slice(&(set.kinds.len() as u64).to_le_bytes());
    for kind in &set.kinds {
        let t = &kind.template;
        bytes.extend_from_slice(&(t.name.len() as u64).to_le_bytes());
        bytes.extend_from_slice(t.name.as_bytes());
        bytes.extend_from_slice(&(t.components.len() as u64).to_le_bytes());
        for c in &t.components {
            f64s(bytes, &[c.centre.x, c.centre.y, c.centre.z, c.radius]);
        }
        f64s(bytes, &[kind.inertia.mass]);
        f64s(bytes, &kind.inertia.moments.to_array());
    }
    bytes.extend_from_slice(&(set.clumps.len() as u64).to_le_bytes());
    for c in &set.clumps {
        let b = &c.body;
        bytes.extend_from_slice(&(c.kind as u64).to_le_bytes());
        f64s(bytes, &b.position.to_array());
        f64s(bytes, &b.orientation.to_array());
        f64s(bytes, &b.velocity.to_array());
        f64s(bytes, &b.angular_momentum.to_array());
    }
}

/// Reads the clumps `write_clumps` wrote, taking their bytes with `take`.
fn read_clumps(f: &mut Fields) -> Result<ClumpSet> {
    // A count of things of `bytes_each` bytes (refused where they cannot be held).
    fn count(f: &mut Fields, what: &str, bytes_each: usize) -> Result<usize> {
        let n = f.u64(what)?;
        usize::try_from(n)
            .ok()
            .filter(|&n| n.checked_mul(bytes_each).is_some())
            .ok_or_else(|| Error::Usage(format!("{n} {what} cannot fit in memory")))
    }
    let kinds_len = count(f, "clump kinds", 1)?;
    let mut kinds = Vec::new();
    for _ in 0..kinds_len {
        let name_len = count(f, "clump name bytes", 1)?;
        let name = String::from_utf8(f.take(name_len, "clump name")?.to_vec())
            .map_err(|_| Error::Usage("a clump's name is not UTF-8".into()))?;
        let components = count(f, "clump components", 32)?;
        let values = f64s_from(f.take(32 * components, "clump components")?);
        let components = values
            .chunks_exact(4)
            .map(|c| Component {
                centre: DVec3::new(c[0], c[1], c[2]),
                radius: c[3],
            })
            .collect();
        let inertia = f64s_from(f.take(32, "clump inertia")?);
        kinds.push(ClumpKind {
            template: ClumpTemplate::new(&name, components)?,
            inertia: PrincipalInertia {
                mass: inertia[0],
                moments: DVec3::new(inertia[1], inertia[2], inertia[3]),
            },
        });
    }
    let clumps_len = count(f, "clumps", 112)?;
    let mut clumps = Vec::new();
    for _ in 0..clumps_len {
        let kind = count(f, "clump kind", 1)?;
        let x = f64s_from(f.take(104, "clump state")?);
        clumps.push(Clump {
            kind,
            body: RigidBody {
                position: DVec3::new(x[0], x[1], x[2]),
                orientation: DQuat::from_xyzw(x[3], x[4], x[5], x[6]),
                velocity: DVec3::new(x[7], x[8], x[9]),
                angular_momentum: DVec3::new(x[10], x[11], x[12]),
            },
        });
    }
    Ok(ClumpSet { kinds, clumps })
}

/// Little-endian `f64`s of `bytes`.
fn f64s_from(bytes: &[u8]) -> Vec<f64> {
    bytes
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
        .collect()
}

/// Reads a checkpoint: a whole one, or the index of one in pieces (read with its pieces as
/// the whole, see [`super::write_checkpoint_index`]).
pub fn read_checkpoint(path: &Path) -> Result<Checkpoint> {
    read_checkpoint_with(path, None).map(|(checkpoint, _)| checkpoint)
}

/// Reads a checkpoint as [`read_checkpoint`] does, but the contact history only of the spheres
/// `keep` flags, beside the particles (whose own history is left empty): a process that steps
/// some of a large run's spheres never holds the whole run's history. The same checks, the
/// same errors.
pub fn read_checkpoint_keeping_history(
    path: &Path,
    keep: HistoryFilter,
) -> Result<(Checkpoint, KeptHistory)> {
    let (checkpoint, kept) = read_checkpoint_with(path, Some(keep))?;
    Ok((checkpoint, kept.unwrap_or_default()))
}

/// Reads a checkpoint, every sphere's history into its particles (`keep`: `None`), or the
/// history of the spheres `keep` flags beside them.
fn read_checkpoint_with(
    path: &Path,
    keep: Option<HistoryFilter>,
) -> Result<(Checkpoint, Option<KeptHistory>)> {
    let bytes = std::fs::read(path).map_err(io_error(path))?;
    if bytes.starts_with(super::checkpoint_pieces::INDEX_MAGIC) {
        return super::checkpoint_pieces::read_checkpoint_pieces(path, &bytes, keep);
    }
    let mut f = Fields::new(path, &bytes);
    if f.take(8, "header")? != MAGIC {
        return Err(f.bad("not a mochi checkpoint".into()));
    }
    let u64_at = |s: &[u8]| u64::from_le_bytes(s.try_into().expect("8 bytes"));
    let version = u32::from_le_bytes(f.take(4, "version")?.try_into().expect("4 bytes"));
    if !(OLDEST..=VERSION).contains(&version) {
        let age = if version < VERSION {
            "an older"
        } else {
            "a newer"
        };
        return Err(f.bad(format!(
            "checkpoint version {version} is from {age} mochi; this one reads versions \
             {OLDEST} to {VERSION} (restart from the run's last frame with --input)"
        )));
    }
    let spins = version >= 3;
    let residuals = version >= 5;
    let step = u64_at(f.take(8, "step")?);
    let n = u64_at(f.take(8, "sphere count")?);
    let scene_len = u64_at(f.take(8, "scene length")?);
    let scene = f.take(scene_len.try_into().unwrap_or(usize::MAX), "scene")?;
    let state = match version >= 4 {
        true => {
            let len = u64_at(f.take(8, "state length")?);
            f.take(len.try_into().unwrap_or(usize::MAX), "state")?
        }
        false => &[][..],
    };
    let per_sphere = match (spins, residuals) {
        (_, true) => 13,
        (true, false) => 10,
        (false, false) => 7,
    };
    let floats = n
        .checked_mul(per_sphere * 4)
        .and_then(|b| usize::try_from(b).ok())
        .ok_or_else(|| f.bad(format!("{n} spheres cannot fit in memory")))?;
    let data = f.take(floats, "sphere data")?;
    let (history_len, history) = if spins {
        let len = u64_at(f.take(8, "history length")?);
        let size = len
            .checked_mul(ENTRY_BYTES as u64)
            .and_then(|b| usize::try_from(b).ok())
            .ok_or_else(|| f.bad(format!("{len} history entries cannot fit in memory")))?;
        (len as usize, f.take(size, "contact history")?)
    } else {
        (0, &[][..])
    };
    let loads = if version >= 6 {
        let len = u64_at(f.take(8, "load history length")?);
        if len != 0 && len != history_len as u64 {
            return Err(f.bad(format!(
                "{len} load histories for {history_len} history entries"
            )));
        }
        f.take(len as usize * LOAD_BYTES, "load history")?
    } else {
        &[][..]
    };
    let materials = if version >= 7 {
        let len = u64_at(f.take(8, "material count")?);
        if len != 0 && len != n {
            return Err(f.bad(format!("{len} materials for {n} spheres")));
        }
        f.take(len as usize, "materials")?
    } else {
        &[][..]
    };
    let clumps = match version >= 8 {
        true => read_clumps(&mut f)?,
        false => ClumpSet::default(),
    };
    f.checksum()?;
    let scene = std::str::from_utf8(scene)
        .map_err(|_| f.bad("the scene is not UTF-8".into()))?
        .to_owned();
    let state = std::str::from_utf8(state)
        .map_err(|_| f.bad("the run's state is not UTF-8".into()))?
        .to_owned();
    let values: Vec<f32> = from_le_words(data);
    let n = n as usize;
    let triples = |s: &[f32]| s.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    let (angular_velocities, radii) = if spins {
        (
            triples(&values[6 * n..9 * n]),
            values[9 * n..10 * n].to_vec(),
        )
    } else {
        (vec![[0.0; 3]; n], values[6 * n..].to_vec())
    };
    let position_residuals = match residuals {
        true => triples(&values[10 * n..]),
        false => Vec::new(),
    };
    let mut particles = Particles {
        positions: triples(&values[..3 * n]),
        position_residuals,
        velocities: triples(&values[3 * n..6 * n]),
        angular_velocities,
        radii,
        materials: materials.to_vec(),
        history: ContactHistory::default(),
        clumps,
        step,
    };
    drop(values);
    let bad = |e: Error| f.bad(e.to_string());
    check_read(&particles).map_err(bad)?;
    let kept = match keep {
        Some(keep) => Some(keep(&scene, &particles)?),
        None => None,
    };
    let entry = |k: usize| le_word_array::<8>(&history[ENTRY_BYTES * k..]);
    let load = |k: usize| le_word_array::<4>(&loads[LOAD_BYTES * k..]).map(f32::from_bits);
    let decoded = decode_history(
        history_len,
        entry,
        (!loads.is_empty()).then_some(&load),
        Ok,
        |at| is_kept(kept.as_deref(), at),
    )?;
    let kept = match kept {
        Some(kept) => Some(KeptHistory::checked(n, kept, decoded).map_err(bad)?),
        None => {
            let (contacts, loads) = decoded;
            particles.history =
                ContactHistory::from_contacts_with_loads(n, &contacts, &loads).map_err(bad)?;
            None
        }
    };
    let checkpoint = Checkpoint {
        particles,
        scene,
        state,
    };
    Ok((checkpoint, kept))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::{FIRST_WALL, HistoryEntry, LoadEntry};

    fn contact(partner: u32, x: f32) -> HistoryEntry {
        HistoryEntry {
            partner,
            tangential: [x, -x, 0.5 * x],
            rolling: [0.0, x, 0.0],
        }
    }

    fn sample() -> Particles {
        Particles {
            positions: vec![[0.1, 0.2, 0.3], [1.0, -2.0, 3.5]],
            position_residuals: vec![[1e-9, -3e-9, 0.0], [0.0, 5e-8, -1e-7]],
            velocities: vec![[0.0, -1.5, 2.0], [1e-9, 0.0, -0.0]],
            angular_velocities: vec![[3.0, 0.0, -1.0], [0.0, 2e-7, 0.0]],
            radii: vec![0.01, 0.002],
            materials: vec![2, 0],
            history: ContactHistory::from_contacts(
                2,
                &[
                    (0, contact(1, 1e-6)),
                    (1, contact(0, -1e-6)),
                    (1, contact(FIRST_WALL + 4, 2e-5)),
                ],
            )
            .unwrap(),
            clumps: ClumpSet::default(),
            step: 1234,
        }
    }

    #[test]
    fn a_checkpoint_round_trips_bit_for_bit() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.bin");
        write_checkpoint(&path, &sample(), "scene = \"slab\"\n", "[flow]\n").unwrap();
        let c = read_checkpoint(&path).unwrap();
        assert_eq!(c.particles, sample());
        assert_eq!(c.particles.materials, [2, 0]);
        assert_eq!(c.scene, "scene = \"slab\"\n");
        assert_eq!(c.state, "[flow]\n");
        // A run of one material keeps none, and reads back with none.
        write_checkpoint(&path, &without_materials(), "x", "").unwrap();
        let c = read_checkpoint(&path).unwrap();
        assert!(c.particles.materials.is_empty());
        assert_eq!(c.particles, without_materials());
        assert_ne!(c.particles, sample());
    }

    /// [`sample`] of one material, as a run of one material holds it (no materials).
    fn without_materials() -> Particles {
        Particles {
            materials: Vec::new(),
            ..sample()
        }
    }

    #[test]
    fn damaged_checkpoints_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.bin");
        write_checkpoint(&path, &sample(), "x", "").unwrap();
        let whole = std::fs::read(&path).unwrap();
        for cut in [0, 5, 20, whole.len() - 1] {
            std::fs::write(&path, &whole[..cut]).unwrap();
            let e = read_checkpoint(&path).unwrap_err().to_string();
            assert!(
                e.contains("truncated") || e.contains("not a mochi"),
                "{cut}: {e}"
            );
        }
        let mut extra = whole.clone();
        extra.push(0);
        std::fs::write(&path, &extra).unwrap();
        assert!(
            read_checkpoint(&path)
                .unwrap_err()
                .to_string()
                .contains("unexpected")
        );
        // A NaN with a valid checksum: refused by the value checks. After the sphere data: the
        // history, the load histories' count, the materials' count and the materials.
        let mut nan = whole[..whole.len() - 4].to_vec();
        let tail = 8 + 3 * ENTRY_BYTES + 8 + 8 + sample().len();
        let first_position = nan.len() - tail - 4 * 26;
        nan[first_position..first_position + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        let crc = crc32fast::hash(&nan);
        nan.extend_from_slice(&crc.to_le_bytes());
        std::fs::write(&path, &nan).unwrap();
        let e = read_checkpoint(&path).unwrap_err().to_string();
        assert!(e.contains("non-finite"), "{e}");
        // Materials for some spheres only.
        let partial = Particles {
            materials: vec![1],
            ..sample()
        };
        write_checkpoint(&path, &partial, "x", "").unwrap();
        let e = read_checkpoint(&path).unwrap_err().to_string();
        assert!(e.contains("1 materials for 2 spheres"), "{e}");
    }

    #[test]
    fn a_flipped_bit_anywhere_is_caught_by_the_checksum() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.bin");
        let (scene, state) = ("scene = \"slab\"\n", "[flow]\ninserted = 3\n");
        write_checkpoint(&path, &sample(), scene, state).unwrap();
        let whole = std::fs::read(&path).unwrap();
        // The step, the scene, the state, the sphere data, the history, the materials and the
        // checksum (damage to the magic, version or a length or count reads as a foreign,
        // older or truncated file; the sample has no clumps, two counts of 0 before the
        // checksum).
        let state_length = 36 + scene.len();
        let history_length = state_length + 8 + state.len() + 52 * sample().len();
        let clumps = whole.len() - 4 - 16;
        let materials = clumps - sample().len();
        let data = (36..state_length)
            .chain(state_length + 8..history_length)
            .chain(history_length + 8..materials - 16)
            .chain(materials..clumps)
            .chain(whole.len() - 4..whole.len());
        for at in (12..20).chain(data) {
            let mut flipped = whole.clone();
            flipped[at] ^= 0x10;
            std::fs::write(&path, &flipped).unwrap();
            let e = read_checkpoint(&path).unwrap_err().to_string();
            assert!(e.contains("checksum mismatch"), "byte {at}: {e}");
        }
    }

    #[test]
    fn a_version_2_checkpoint_reads_as_spheres_without_spin_or_history() {
        let p = sample();
        let mut bytes = MAGIC.to_vec();
        bytes.extend_from_slice(&2u32.to_le_bytes());
        bytes.extend_from_slice(&p.step.to_le_bytes());
        bytes.extend_from_slice(&2u64.to_le_bytes());
        bytes.extend_from_slice(&1u64.to_le_bytes());
        bytes.push(b'x');
        let floats = p
            .positions
            .iter()
            .flatten()
            .chain(p.velocities.iter().flatten());
        for x in floats.chain(&p.radii) {
            bytes.extend_from_slice(&x.to_le_bytes());
        }
        let crc = crc32fast::hash(&bytes);
        bytes.extend_from_slice(&crc.to_le_bytes());
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.bin");
        std::fs::write(&path, &bytes).unwrap();
        let read = read_checkpoint(&path).unwrap();
        assert_eq!((read.scene.as_str(), read.state.as_str()), ("x", ""));
        let expected = Particles {
            position_residuals: Vec::new(),
            angular_velocities: vec![[0.0; 3]; 2],
            materials: Vec::new(),
            history: ContactHistory::default(),
            ..p
        };
        assert_eq!(read.particles, expected);
    }

    /// The checkpoint of [`sample`] of one material (scene `x`, empty state) as version 7
    /// wrote it: no clumps' counts before the checksum.
    fn version_7() -> Vec<u8> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.bin");
        write_checkpoint(&path, &without_materials(), "x", "").unwrap();
        let v8 = std::fs::read(&path).unwrap();
        let mut v7 = v8[..v8.len() - 20].to_vec();
        v7[8..12].copy_from_slice(&7u32.to_le_bytes());
        let crc = crc32fast::hash(&v7);
        v7.extend_from_slice(&crc.to_le_bytes());
        v7
    }

    /// The checkpoint of [`sample`] (scene `x`, empty state) as version 6 wrote it: no
    /// materials' count before the checksum (the materials lost).
    fn version_6() -> Vec<u8> {
        let v7 = version_7();
        let mut v6 = v7[..v7.len() - 12].to_vec();
        v6[8..12].copy_from_slice(&6u32.to_le_bytes());
        let crc = crc32fast::hash(&v6);
        v6.extend_from_slice(&crc.to_le_bytes());
        v6
    }

    /// The checkpoint of [`sample`] (scene `x`, empty state) as version 5 wrote it: no load
    /// histories' count before the checksum either.
    fn version_5() -> Vec<u8> {
        let v6 = version_6();
        let mut v5 = v6[..v6.len() - 12].to_vec();
        v5[8..12].copy_from_slice(&5u32.to_le_bytes());
        let crc = crc32fast::hash(&v5);
        v5.extend_from_slice(&crc.to_le_bytes());
        v5
    }

    /// The checkpoint of [`sample`] (scene `x`, empty state) as version 4 wrote it: no
    /// residuals after the radii.
    fn version_4() -> Vec<u8> {
        let v5 = version_5();
        // Header (45 bytes with scene "x" and an empty state), then 40 bytes a sphere of
        // positions, velocities, spins and radii, then the residuals.
        let spheres = 45 + 40 * sample().len();
        let mut v4 = v5[..spheres].to_vec();
        v4[8..12].copy_from_slice(&4u32.to_le_bytes());
        v4.extend_from_slice(&v5[spheres + 12 * sample().len()..v5.len() - 4]);
        let crc = crc32fast::hash(&v4);
        v4.extend_from_slice(&crc.to_le_bytes());
        v4
    }

    /// The checkpoint at `path` reads as [`sample`] (scene `x`, empty state) without
    /// materials: one written before spheres had them.
    fn assert_reads_as_sample_without_materials(path: &std::path::Path) {
        let read = read_checkpoint(path).unwrap();
        assert!(read.particles.materials.is_empty());
        assert_eq!(
            (read.particles, read.scene.as_str(), read.state.as_str()),
            (without_materials(), "x", "")
        );
    }

    /// The checkpoint at `path` reads as [`sample`] (scene `x`, empty state) with residuals of
    /// zero and without materials: one written before positions had residuals.
    fn assert_reads_as_sample_without_residuals(path: &std::path::Path) {
        let read = read_checkpoint(path).unwrap();
        assert!(read.particles.materials.is_empty());
        let expected = Particles {
            position_residuals: Vec::new(),
            ..without_materials()
        };
        assert_eq!(
            (read.particles, read.scene.as_str(), read.state.as_str()),
            (expected, "x", "")
        );
    }

    #[test]
    fn a_version_4_checkpoint_reads_with_residuals_of_zero() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.bin");
        std::fs::write(&path, version_4()).unwrap();
        assert_reads_as_sample_without_residuals(&path);
    }

    #[test]
    fn a_version_3_checkpoint_reads_with_an_empty_state() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.bin");
        // Version 4 with an empty state is version 3 with a zero length after the scene.
        let v4 = version_4();
        let mut v3 = v4[..37].to_vec();
        v3[8..12].copy_from_slice(&3u32.to_le_bytes());
        v3.extend_from_slice(&v4[45..v4.len() - 4]);
        let crc = crc32fast::hash(&v3);
        v3.extend_from_slice(&crc.to_le_bytes());
        std::fs::write(&path, &v3).unwrap();
        assert_reads_as_sample_without_residuals(&path);
    }

    #[test]
    fn residuals_that_are_not_below_half_a_spacing_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.bin");
        let mut off = sample();
        // Half of 1.0's spacing above: the pair's sum rounds to 1.0's neighbour.
        off.position_residuals[1][0] = 1e-7;
        write_checkpoint(&path, &off, "x", "").unwrap();
        let e = read_checkpoint(&path).unwrap_err().to_string();
        assert!(
            e.contains("sphere 1") && e.contains("half an f32 spacing"),
            "{e}"
        );
    }

    /// [`sample`] with the load histories of the Mindlin–Deresiewicz model.
    fn loaded() -> Particles {
        let load = |x: f32| LoadEntry {
            reversal: [x, 0.0, -x],
            normal: 3.0 * x.abs(),
        };
        let p = sample();
        let contacts: Vec<(u32, HistoryEntry)> =
            p.history.contacts().map(|(o, e)| (o, *e)).collect();
        let loads = [load(1e-3), load(-1e-3), load(0.25)];
        Particles {
            history: ContactHistory::from_contacts_with_loads(2, &contacts, &loads).unwrap(),
            ..p
        }
    }

    #[test]
    fn load_histories_round_trip_bit_for_bit() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.bin");
        write_checkpoint(&path, &loaded(), "x", "").unwrap();
        let c = read_checkpoint(&path).unwrap();
        assert!(c.particles.history.has_loads());
        assert_eq!(c.particles, loaded());
        assert_ne!(c.particles, sample());
        write_checkpoint(&path, &sample(), "x", "").unwrap();
        assert!(
            !read_checkpoint(&path)
                .unwrap()
                .particles
                .history
                .has_loads()
        );
    }

    #[test]
    fn a_version_7_checkpoint_reads_without_clumps() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.bin");
        std::fs::write(&path, version_7()).unwrap();
        assert_reads_as_sample_without_materials(&path);
    }

    /// [`sample`] whose first sphere is a clump's component: a dimer's (the second sphere,
    /// free, is of another radius; the clump's state need not match the spheres' to be saved).
    fn with_a_clump() -> Particles {
        let kind = ClumpKind::new(&ClumpTemplate::dimer(0.01).unwrap(), 2500.0);
        let mut p = sample();
        // Two components: the dimer's, then the free sphere.
        p.positions.insert(0, [0.3, 0.2, 0.1]);
        p.position_residuals.insert(0, [0.0; 3]);
        p.velocities.insert(0, [0.0; 3]);
        p.angular_velocities.insert(0, [0.0; 3]);
        p.radii.insert(0, 0.01);
        p.radii[1] = 0.01;
        p.materials.insert(0, 0);
        p.history = ContactHistory::default();
        p.clumps = ClumpSet {
            clumps: vec![Clump {
                kind: 0,
                body: RigidBody {
                    position: DVec3::new(0.1, 0.2, 0.3 + 1e-12),
                    orientation: DQuat::from_rotation_z(0.3),
                    velocity: DVec3::new(1e-9, 0.0, -2.0),
                    angular_momentum: DVec3::new(0.0, 3e-11, 1e-13),
                },
            }],
            kinds: vec![kind],
        };
        p
    }

    #[test]
    fn clumps_round_trip_bit_for_bit() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.bin");
        let p = with_a_clump();
        p.validate().unwrap();
        write_checkpoint(&path, &p, "x", "").unwrap();
        let read = read_checkpoint(&path).unwrap().particles;
        assert_eq!(read.clumps, p.clumps);
        assert_eq!(read, p);
        assert_ne!(read, sample());
        // Cut inside the clumps: refused.
        let whole = std::fs::read(&path).unwrap();
        std::fs::write(&path, &whole[..whole.len() - 40]).unwrap();
        let e = read_checkpoint(&path).unwrap_err().to_string();
        assert!(e.contains("truncated"), "{e}");
    }

    #[test]
    fn a_version_6_checkpoint_reads_without_materials() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.bin");
        std::fs::write(&path, version_6()).unwrap();
        assert_reads_as_sample_without_materials(&path);
    }

    #[test]
    fn a_version_5_checkpoint_reads_without_load_histories() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.bin");
        std::fs::write(&path, version_5()).unwrap();
        assert_reads_as_sample_without_materials(&path);
    }

    #[test]
    fn an_older_checkpoint_version_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.bin");
        write_checkpoint(&path, &sample(), "x", "").unwrap();
        let mut old = std::fs::read(&path).unwrap();
        old[8..12].copy_from_slice(&1u32.to_le_bytes());
        std::fs::write(&path, &old).unwrap();
        let e = read_checkpoint(&path).unwrap_err().to_string();
        assert!(e.contains("version 1 is from an older mochi"), "{e}");
    }
}
