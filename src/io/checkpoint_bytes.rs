//! The bytes checkpoints share, whole and in pieces: the spheres and their history as both hold them after their
//! heads (positions to materials), made on every core and written as they lie, the
//! little-endian words they are made of, and a reader of their fields.

use super::write_atomically;
use crate::error::{Error, Result};
use crate::particles::{ContactHistory, HistoryEntry, LoadEntry, Particles};
use rayon::prelude::*;
use std::borrow::Cow;
use std::path::Path;

/// The spheres of a checkpoint and their history as its file holds them after its head: n·3
/// f32 positions, velocities and angular velocities, n f32 radii, n·3 f32 position residuals,
/// the history entries' count u64 and each as owner u32, partner u32, 3 f32 tangential and 3
/// f32 rolling spring, the load histories' count u64 (0 or the entries') and each as 3 f32
/// reversal force and f32 normal force, the materials' count u64 (0 or n) and each a u8.
pub(super) struct SphereBytes<'a> {
    spheres: &'a Particles,
    residuals: Vec<[f32; 3]>,
    entries: Vec<[u32; 8]>,
    loads: Vec<[f32; 4]>,
    counts: [[u8; 8]; 3],
}

impl<'a> SphereBytes<'a> {
    /// `spheres` with their own contact history.
    pub fn of_particles(spheres: &'a Particles) -> Self {
        let history = &spheres.history;
        let owners = 0..spheres.len();
        let entries = (owners.clone().into_par_iter())
            .flat_map_iter(|i| history.of(i).iter().map(move |e| entry_words(i as u32, e)))
            .collect();
        let loads = match history.has_loads() {
            true => (owners.into_par_iter())
                .flat_map_iter(|i| history.loads_of(i).iter().map(load_words))
                .collect(),
            false => Vec::new(),
        };
        Self::with(spheres, entries, loads)
    }

    /// `spheres` (whose own history is not read) with `contacts` (owners, places in `spheres`)
    /// and their `loads` (none, or one a contact).
    pub fn with_contacts(
        spheres: &'a Particles,
        contacts: &[(u32, HistoryEntry)],
        loads: &[LoadEntry],
    ) -> Self {
        let entries = (contacts.par_iter())
            .map(|(o, e)| entry_words(*o, e))
            .collect();
        Self::with(spheres, entries, loads.par_iter().map(load_words).collect())
    }

    fn with(spheres: &'a Particles, entries: Vec<[u32; 8]>, loads: Vec<[f32; 4]>) -> Self {
        let residuals = (0..spheres.len())
            .into_par_iter()
            .map(|i| spheres.residual(i))
            .collect();
        let counts =
            [entries.len(), loads.len(), spheres.materials.len()].map(|c| (c as u64).to_le_bytes());
        Self {
            spheres,
            residuals,
            entries,
            loads,
            counts,
        }
    }

    /// The sections in the file's order.
    pub fn sections(&self) -> [Cow<'_, [u8]>; 11] {
        let p = self.spheres;
        [
            le_words(&p.positions),
            le_words(&p.velocities),
            le_words(&p.angular_velocities),
            le_words(&p.radii),
            le_words(&self.residuals),
            Cow::Borrowed(&self.counts[0]),
            le_words(&self.entries),
            Cow::Borrowed(&self.counts[1]),
            le_words(&self.loads),
            Cow::Borrowed(&self.counts[2]),
            Cow::Borrowed(&p.materials),
        ]
    }
}

/// A history entry as a checkpoint holds it: owner, partner, then the springs' bits.
fn entry_words(owner: u32, e: &HistoryEntry) -> [u32; 8] {
    let [t, r] = [e.tangential, e.rolling].map(|s| s.map(f32::to_bits));
    [owner, e.partner, t[0], t[1], t[2], r[0], r[1], r[2]]
}

/// The history entry of `words` ([`entry_words`]) and its owner.
pub(super) fn entry_of(w: &[u32; 8]) -> (u32, HistoryEntry) {
    let f = w.map(f32::from_bits);
    let entry = HistoryEntry {
        partner: w[1],
        tangential: [f[2], f[3], f[4]],
        rolling: [f[5], f[6], f[7]],
    };
    (w[0], entry)
}

fn load_words(l: &LoadEntry) -> [f32; 4] {
    [l.reversal[0], l.reversal[1], l.reversal[2], l.normal]
}

/// The load history of `words` ([`load_words`]).
pub(super) fn load_of(l: &[f32; 4]) -> LoadEntry {
    LoadEntry {
        reversal: [l[0], l[1], l[2]],
        normal: l[3],
    }
}

/// Contacts (each with its owner's place) and their load histories (none, or one each).
pub(super) type Decoded = (Vec<(u32, HistoryEntry)>, Vec<LoadEntry>);

/// Which spheres' contact history a read keeps ([`super::read_checkpoint_keeping_history`]): from the
/// checkpoint's scene (TOML) and its spheres read without their history, a flag a sphere (by
/// place).
pub type HistoryFilter<'a> = &'a (dyn Fn(&str, &Particles) -> Result<Vec<bool>> + Sync);

/// The contact history of the spheres a read kept ([`super::read_checkpoint_keeping_history`]), as
/// [`ContactHistory::from_contacts_with_loads`] takes it, checked as it checks it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct KeptHistory {
    /// Which spheres' history was kept, by place.
    pub kept: Vec<bool>,
    /// Their contacts, each with its owner's place, in the checkpoint's order.
    pub contacts: Vec<(u32, HistoryEntry)>,
    /// The load history of each contact (none: the run keeps none).
    pub loads: Vec<LoadEntry>,
}

impl KeptHistory {
    /// The history `keep` asks of the contacts and load histories of `n` spheres read (owners
    /// `keep` does not name are kept, so that the check refuses them).
    pub(super) fn checked(n: usize, kept: Vec<bool>, (contacts, loads): Decoded) -> Result<Self> {
        if kept.len() != n {
            return Err(Error::Usage(format!(
                "a history filter named {} spheres of {n}",
                kept.len()
            )));
        }
        ContactHistory::check_contacts(n, &contacts, &loads)?;
        Ok(Self {
            kept,
            contacts,
            loads,
        })
    }
}

/// Whether the history of the sphere at `at` is read where `kept` flags the spheres whose is
/// (`None`: every sphere's; a place beyond the flags is read, for the checks to refuse).
pub(super) fn is_kept(kept: Option<&[bool]>, at: u32) -> bool {
    kept.is_none_or(|k| k.get(at as usize).copied().unwrap_or(true))
}

/// Entries a task of [`decode_history`] decodes.
const DECODED_A_TASK: usize = 1 << 16;

/// The contacts (the owner's place, the entry) of the `count` history entries `entry(k)` gives
/// ([`entry_words`]) whose owners `wanted` keeps, with the load history `load(k)` of each where
/// given, decoded on every core in their order; `place` maps an entry's owner word to its
/// sphere's place. The kept entries are counted first and written into vectors of their
/// length: no task leaves a vector of its own behind.
pub(super) fn decode_history(
    count: usize,
    entry: impl Fn(usize) -> [u32; 8] + Sync,
    load: Option<&(dyn Fn(usize) -> [f32; 4] + Sync)>,
    place: impl Fn(u32) -> Result<u32> + Sync,
    wanted: impl Fn(u32) -> bool + Sync,
) -> Result<Decoded> {
    let tasks = count.div_ceil(DECODED_A_TASK);
    let span = |t: usize| t * DECODED_A_TASK..count.min((t + 1) * DECODED_A_TASK);
    let kept_by_task = ((0..tasks).into_par_iter())
        .map(|t| {
            span(t).try_fold(0, |kept, k| {
                let at = place(entry(k)[0])?;
                Ok(kept + usize::from(wanted(at)))
            })
        })
        .collect::<Result<Vec<usize>>>()?;
    let total = kept_by_task.iter().sum();
    let mut contacts = vec![(0, HistoryEntry::default()); total];
    let mut loads = vec![LoadEntry::default(); if load.is_some() { total } else { 0 }];
    let mut contacts_rest = &mut contacts[..];
    let mut loads_rest = &mut loads[..];
    let mut slices = Vec::with_capacity(tasks);
    for &kept in &kept_by_task {
        let (c, more) = contacts_rest.split_at_mut(kept);
        let (l, more_loads) = loads_rest.split_at_mut(kept.min(loads_rest.len()));
        slices.push((c, l));
        (contacts_rest, loads_rest) = (more, more_loads);
    }
    (slices.into_par_iter().enumerate()).for_each(|(t, (c, l))| {
        let mut j = 0;
        for k in span(t) {
            let (owner, e) = entry_of(&entry(k));
            // Every place was found in the count above.
            let Ok(at) = place(owner) else { continue };
            if !wanted(at) {
                continue;
            }
            c[j] = (at, e);
            if let (Some(load), Some(slot)) = (load, l.get_mut(j)) {
                *slot = load_of(&load(k));
            }
            j += 1;
        }
    });
    Ok((contacts, loads))
}

/// The `N` little-endian words of four bytes at the start of `bytes`.
pub(super) fn le_word_array<const N: usize>(bytes: &[u8]) -> [u32; N] {
    std::array::from_fn(|k| u32::from_le_bytes(bytes[4 * k..4 * k + 4].try_into().expect("4")))
}

/// The little-endian bytes of `values`, words of four bytes each: as they lie on a
/// little-endian machine, each word turned on a big-endian one.
pub(super) fn le_words<T: bytemuck::Pod>(values: &[T]) -> Cow<'_, [u8]> {
    let bytes: &[u8] = bytemuck::cast_slice(values);
    match cfg!(target_endian = "little") {
        true => bytes.into(),
        false => turned(bytes).into(),
    }
}

/// The values of the little-endian words `bytes` ([`le_words`]'s inverse).
pub(super) fn from_le_words<T: bytemuck::Pod>(bytes: &[u8]) -> Vec<T> {
    match cfg!(target_endian = "little") {
        true => bytemuck::pod_collect_to_vec(bytes),
        false => bytemuck::pod_collect_to_vec(&turned(bytes)),
    }
}

/// `bytes` with each word of four turned end for end.
fn turned(bytes: &[u8]) -> Vec<u8> {
    (bytes.chunks_exact(4))
        .flat_map(|w| [w[3], w[2], w[1], w[0]])
        .collect()
}

/// Checks the spheres a checkpoint was read into: their columns one a sphere, their values
/// finite, their radii positive.
pub(super) fn check_read(p: &Particles) -> Result<()> {
    p.validate()?;
    match p.radii.iter().position(|&r| !(r > 0.0 && r.is_finite())) {
        Some(i) => Err(Error::Usage(format!(
            "sphere {i} has radius {}",
            p.radii[i]
        ))),
        None => Ok(()),
    }
}

/// Writes `sections` and then the CRC-32 of their bytes to `path`, atomically; returns the
/// CRC-32.
pub(super) fn write_with_checksum(path: &Path, sections: &[&[u8]]) -> Result<u32> {
    let mut crc = crc32fast::Hasher::new();
    for section in sections {
        crc.update(section);
    }
    let checksum = crc.finalize();
    write_atomically(path, |out| {
        for section in sections {
            out.write_all(section)?;
        }
        out.write_all(&checksum.to_le_bytes())
    })?;
    Ok(checksum)
}

/// Reads a little-endian file field by field, each error naming the file.
pub(super) struct Fields<'a> {
    bytes: &'a [u8],
    at: usize,
    path: &'a Path,
}

impl<'a> Fields<'a> {
    /// The fields of `bytes`, the file at `path`, from its first.
    pub fn new(path: &'a Path, bytes: &'a [u8]) -> Self {
        Self { bytes, at: 0, path }
    }

    /// An error of this file saying `msg`.
    pub fn bad(&self, msg: String) -> Error {
        Error::Parse {
            path: self.path.to_owned(),
            line: None,
            msg,
        }
    }

    /// The next `len` bytes, `what` the file holds there.
    pub fn take(&mut self, len: usize, what: &str) -> Result<&'a [u8]> {
        let end = (self.at.checked_add(len))
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| self.bad(format!("truncated checkpoint: {what} missing")))?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }

    /// The next u64.
    pub fn u64(&mut self, what: &str) -> Result<u64> {
        Ok(u64::from_le_bytes(
            self.take(8, what)?.try_into().expect("8 bytes"),
        ))
    }

    /// The bytes of `m` things of `each` bytes.
    pub fn each(&mut self, m: usize, each: usize, what: &str) -> Result<&'a [u8]> {
        let len = (m.checked_mul(each))
            .ok_or_else(|| self.bad(format!("{m} {what} cannot fit in memory")))?;
        self.take(len, what)
    }

    /// A count of things of `each` bytes, and their bytes.
    pub fn counted(&mut self, each: usize, what: &str) -> Result<(usize, &'a [u8])> {
        let n = self.u64(what)?;
        let len = (n.checked_mul(each as u64))
            .and_then(|b| usize::try_from(b).ok())
            .ok_or_else(|| self.bad(format!("{n} {what} cannot fit in memory")))?;
        Ok((n as usize, self.take(len, what)?))
    }

    /// A length u64 and the UTF-8 text of that many bytes.
    pub fn text(&mut self, what: &str) -> Result<String> {
        let (_, bytes) = self.counted(1, what)?;
        String::from_utf8(bytes.to_vec()).map_err(|_| self.bad(format!("the {what} is not UTF-8")))
    }

    /// Checks the CRC-32 that ends the file; returns it.
    pub fn checksum(&mut self) -> Result<u32> {
        let stored = u32::from_le_bytes(self.take(4, "checksum")?.try_into().expect("4 bytes"));
        if self.at != self.bytes.len() {
            let extra = self.bytes.len() - self.at;
            return Err(self.bad(format!("{extra} unexpected bytes at the end")));
        }
        if crc32fast::hash(&self.bytes[..self.at - 4]) != stored {
            return Err(self.bad(
                "checksum mismatch: the checkpoint is damaged (resume from an intact copy)".into(),
            ));
        }
        Ok(stored)
    }
}
