//! Contact history: what each sphere keeps of its contacts from one step to the next (the
//! tangential spring and the rolling spring), keyed by the partner's stable id, its index in
//! input order, so that no re-sort of the spheres can mix contacts up.
//!
//! Layout (docs/method.md, "Contact history"): K slots per sphere, sphere i's contacts in
//! `entries[i·K .. i·K + counts[i]]`. Both spheres of a pair keep the contact, each in its own
//! slots (the partner's springs are the exact negatives), so a step that computes every sphere's
//! contacts from its own side reads and writes only its own slots. K grows when a sphere has
//! more contacts than slots (the step counts them, grows K and redoes the step): no contact is
//! ever dropped. Under the Mindlin–Deresiewicz tangential model each entry has a
//! [`LoadEntry`] beside it (its load history), in a parallel array that other runs do not
//! allocate.

use crate::error::{Error, Result, try_vec};
use rayon::prelude::*;

/// Partner ids from here on name the six walls of the box: `FIRST_WALL + 2·axis + side`
/// (side 0 the low wall). Sphere ids stay below it.
pub const FIRST_WALL: u32 = u32::MAX - 5;

/// How many mesh walls a run may have: their partner ids lie just below the box's.
pub const MESH_WALLS: u32 = 1 << 16;

/// Partner ids from here to [`FIRST_WALL`] name mesh walls (`FIRST_MESH_WALL + w`, the
/// scene's wall `w`). A run with mesh walls keeps its sphere ids below it.
pub const FIRST_MESH_WALL: u32 = FIRST_WALL - MESH_WALLS;

/// The partner of a GPU history slot that holds no contact: the wgpu steps give every candidate
/// of a sphere's walk a slot, also one that does not touch (or hold), and name no partner there
/// (`NO_PARTNER` in `wgsl/dem/dem_granular.wgsl`). Reading the history back drops such slots;
/// sphere ids of a run with history stay below it.
pub const NO_PARTNER: u32 = FIRST_MESH_WALL - 1;

/// One contact as one of its spheres keeps it.
#[derive(Debug, Clone, Copy, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct HistoryEntry {
    /// The other sphere's index in input order, or a wall (a mesh wall from
    /// [`FIRST_MESH_WALL`] on, a box wall from [`FIRST_WALL`] on).
    pub partner: u32,
    /// Tangential spring ξ \[m\].
    pub tangential: [f32; 3],
    /// Rolling spring torque \[N·m\] (EPSD rolling resistance).
    pub rolling: [f32; 3],
}

/// What the Mindlin–Deresiewicz tangential model keeps of a contact besides its
/// [`HistoryEntry`] (whose `tangential` then holds the elastic tangential force \[N\] on the
/// sphere, not a spring): its load history. The partner keeps the negated reversal and the
/// same normal force.
#[derive(Debug, Clone, Copy, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct LoadEntry {
    /// The elastic tangential force on the sphere at the last reversal of the loading \[N\]
    /// (zero: no reversal since the contact began or last slid).
    pub reversal: [f32; 3],
    /// The elastic normal force of the last step \[N\].
    pub normal: f32,
}

impl HistoryEntry {
    /// The contact as its partner keeps it, `owner` holding this entry: `owner` the partner,
    /// the springs negated.
    pub fn seen_by_partner(&self, owner: u32) -> HistoryEntry {
        HistoryEntry {
            partner: owner,
            tangential: self.tangential.map(|x| -x),
            rolling: self.rolling.map(|x| -x),
        }
    }
}

impl LoadEntry {
    /// The load history as the contact's partner keeps it: the reversal negated, the same
    /// normal force.
    pub fn seen_by_partner(&self) -> LoadEntry {
        LoadEntry {
            reversal: self.reversal.map(|x| -x),
            normal: self.normal,
        }
    }
}

/// An entry with its load history, as a step under the Mindlin–Deresiewicz model writes it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LoadedEntry {
    /// The entry.
    pub entry: HistoryEntry,
    /// Its load history.
    pub load: LoadEntry,
}

/// A slot as a step writes it: a [`HistoryEntry`] alone, or a [`LoadedEntry`] (the
/// Mindlin–Deresiewicz model), so that a step of the other models keeps its entries as they
/// are.
pub trait Slot: Copy + Default + Send + Sync {
    /// Whether it carries a load history.
    const LOADED: bool;
    /// The entry.
    fn entry(&self) -> &HistoryEntry;
    /// Its load history (zero where it carries none).
    fn load(&self) -> LoadEntry;
}

impl Slot for HistoryEntry {
    const LOADED: bool = false;
    #[inline(always)]
    fn entry(&self) -> &HistoryEntry {
        self
    }
    #[inline(always)]
    fn load(&self) -> LoadEntry {
        LoadEntry::default()
    }
}

impl Slot for LoadedEntry {
    const LOADED: bool = true;
    #[inline(always)]
    fn entry(&self) -> &HistoryEntry {
        &self.entry
    }
    #[inline(always)]
    fn load(&self) -> LoadEntry {
        self.load
    }
}

/// Every sphere's contacts with history, in per-sphere slots.
#[derive(Debug, Clone, Default)]
pub struct ContactHistory {
    /// Slots per sphere (K).
    slots: usize,
    /// Contacts held per sphere (none at all: no sphere has any).
    counts: Vec<u32>,
    /// `slots` entries per sphere, the first `counts[i]` in use.
    entries: Vec<HistoryEntry>,
    /// The load history of each entry (Mindlin–Deresiewicz), beside `entries`; empty where
    /// contacts keep none.
    loads: Vec<LoadEntry>,
}

impl ContactHistory {
    /// No contacts for `n` spheres, with `slots` slots each.
    pub fn with_slots(n: usize, slots: usize) -> Result<Self> {
        let what = || format!("the contact history of {n} spheres ({slots} contacts each)");
        let total = n.checked_mul(slots).ok_or_else(|| Error::TooLarge {
            what: what(),
            got: u64::MAX,
            limit: usize::MAX as u64,
        })?;
        let mut counts = try_vec(n, what)?;
        counts.resize(n, 0);
        let mut entries = try_vec(total, what)?;
        entries.resize(total, HistoryEntry::default());
        Ok(Self {
            slots,
            counts,
            entries,
            loads: Vec::new(),
        })
    }

    /// A copy, or [`Error::OutOfMemory`] where it does not fit.
    pub fn try_clone(&self) -> Result<Self> {
        let n = self.counts.len();
        let what = || format!("a copy of the contact history of {n} spheres");
        let mut counts = try_vec(n, what)?;
        counts.extend_from_slice(&self.counts);
        let mut entries = try_vec(self.entries.len(), what)?;
        entries.extend_from_slice(&self.entries);
        let mut loads = try_vec(self.loads.len(), what)?;
        loads.extend_from_slice(&self.loads);
        Ok(Self {
            slots: self.slots,
            counts,
            entries,
            loads,
        })
    }

    /// The history of `n` spheres holding `contacts` (owner, entry), in any order of owners;
    /// each owner's entries keep their order. Refuses owners or partners out of range.
    pub fn from_contacts(n: usize, contacts: &[(u32, HistoryEntry)]) -> Result<Self> {
        Self::from_contacts_with_loads(n, contacts, &[])
    }

    /// Refuses `contacts` (each with its owner) of `n` spheres that
    /// [`Self::from_contacts_with_loads`] would refuse: owners or partners out of range, a
    /// sphere its own partner, values that are not finite, load histories that are not one a
    /// contact or not valid.
    pub fn check_contacts(
        n: usize,
        contacts: &[(u32, HistoryEntry)],
        loads: &[LoadEntry],
    ) -> Result<()> {
        if !loads.is_empty() && loads.len() != contacts.len() {
            return Err(Error::Usage(format!(
                "{} load histories for {} contacts",
                loads.len(),
                contacts.len()
            )));
        }
        for (k, &(owner, entry)) in contacts.iter().enumerate() {
            check_entry(n, owner as usize, &entry)?;
            if let Some(load) = loads.get(k) {
                check_load(owner as usize, load)?;
            }
        }
        Ok(())
    }

    /// [`from_contacts`](Self::from_contacts) with the load history of each contact, `loads`
    /// beside `contacts` (empty: none kept).
    pub fn from_contacts_with_loads(
        n: usize,
        contacts: &[(u32, HistoryEntry)],
        loads: &[LoadEntry],
    ) -> Result<Self> {
        Self::check_contacts(n, contacts, loads)?;
        let mut per = vec![0usize; n];
        for &(owner, _) in contacts {
            per[owner as usize] += 1;
        }
        let slots = per.iter().copied().max().unwrap_or(0);
        let mut out = Self::with_slots(n, slots)?;
        if !loads.is_empty() {
            out.keep_loads()?;
        }
        for (c, &(owner, entry)) in contacts.iter().enumerate() {
            let i = owner as usize;
            let k = out.counts[i] as usize;
            out.entries[i * slots + k] = entry;
            if let Some(&load) = loads.get(c) {
                out.loads[i * slots + k] = load;
            }
            out.counts[i] += 1;
        }
        Ok(out)
    }

    /// The history of `n` spheres from rows that hold each sphere pair's contact once, by
    /// either sphere (as the GPU steps keep it), or by both (an uploaded history read back
    /// before a step): `row(i)` gives sphere i's entries with their load histories. A contact
    /// that a sphere holds of a partner sphere that does not hold it back is given to the
    /// partner too, as the partner sees it, right after the owner's entry: each sphere's
    /// contacts come in the order of their owners. Contacts with walls stay with their
    /// sphere; the load histories are kept where `loaded`. Refuses partners out of range.
    pub fn from_owner_rows<R>(n: usize, loaded: bool, row: impl Fn(usize) -> R) -> Result<Self>
    where
        R: Iterator<Item = (HistoryEntry, LoadEntry)>,
    {
        let (mut contacts, mut loads) = (Vec::new(), Vec::new());
        for i in 0..n {
            let owner = i as u32;
            for (e, load) in row(i) {
                contacts.push((owner, e));
                loads.push(load);
                // Partners from n on are walls (or out of range: refused below).
                let j = e.partner as usize;
                if j < n && !row(j).any(|(back, _)| back.partner == owner) {
                    contacts.push((e.partner, e.seen_by_partner(owner)));
                    loads.push(load.seen_by_partner());
                }
            }
        }
        if !loaded {
            loads.clear();
        }
        Self::from_contacts_with_loads(n, &contacts, &loads)
    }

    /// Keeps a load history beside every entry from now on (zero for those held: the virgin
    /// curve, from no normal force), as the Mindlin–Deresiewicz model needs.
    pub fn keep_loads(&mut self) -> Result<()> {
        if self.loads.len() != self.entries.len() {
            let n = self.entries.len();
            self.loads.clear();
            crate::error::try_resize(&mut self.loads, n, LoadEntry::default(), || {
                format!("the load history of {n} contact slots")
            })?;
        }
        Ok(())
    }

    /// Whether the entries have a load history beside them.
    pub fn has_loads(&self) -> bool {
        !self.loads.is_empty()
    }

    /// The load histories of the contacts sphere `i` holds, beside [`of`](Self::of) (none
    /// without load history).
    #[inline]
    pub fn loads_of(&self, i: usize) -> &[LoadEntry] {
        match (self.loads.is_empty(), self.counts.get(i)) {
            (false, Some(&c)) => &self.loads[i * self.slots..i * self.slots + c as usize],
            _ => &[],
        }
    }

    /// The load history of every contact, in the order of [`contacts`](Self::contacts)
    /// (nothing without load history).
    pub fn contact_loads(&self) -> impl Iterator<Item = &LoadEntry> {
        (0..self.counts.len()).flat_map(move |i| self.loads_of(i).iter())
    }

    /// Slots per sphere.
    pub fn slots(&self) -> usize {
        self.slots
    }

    /// Contacts held, over all spheres (each pair twice, once per sphere).
    pub fn len(&self) -> usize {
        self.counts.iter().map(|&c| c as usize).sum()
    }

    /// Whether no sphere holds a contact.
    pub fn is_empty(&self) -> bool {
        self.counts.iter().all(|&c| c == 0)
    }

    /// The contacts sphere `i` holds (none when the history is empty).
    #[inline]
    pub fn of(&self, i: usize) -> &[HistoryEntry] {
        match self.counts.get(i) {
            Some(&c) => &self.entries[i * self.slots..i * self.slots + c as usize],
            None => &[],
        }
    }

    /// Every contact as (owner, entry), owners in order.
    pub fn contacts(&self) -> impl Iterator<Item = (u32, &HistoryEntry)> {
        (0..self.counts.len()).flat_map(move |i| self.of(i).iter().map(move |e| (i as u32, e)))
    }

    /// The contacts each of `n` spheres holds (zero for those beyond the history's).
    pub fn counts(&self, n: usize) -> Vec<u32> {
        (0..n).map(|i| self.of(i).len() as u32).collect()
    }

    /// The contacts each of `n` spheres holds in the history [`from_owner_rows`](Self::from_owner_rows)
    /// builds from the same rows (`row(i)`: the partners sphere i holds), without building it:
    /// its own row's, and those of the rows that name it where its own does not name them back.
    pub fn counts_of_owner_rows<R>(n: usize, row: impl Fn(usize) -> R + Sync) -> Vec<u32>
    where
        R: Iterator<Item = u32>,
    {
        use std::sync::atomic::{AtomicU32, Ordering::Relaxed};
        let counts: Vec<AtomicU32> = (0..n).map(|_| AtomicU32::new(0)).collect();
        (0..n).into_par_iter().for_each(|i| {
            let owner = i as u32;
            for partner in row(i) {
                counts[i].fetch_add(1, Relaxed);
                let j = partner as usize;
                if j < n && !row(j).any(|back| back == owner) {
                    counts[j].fetch_add(1, Relaxed);
                }
            }
        });
        counts.into_iter().map(AtomicU32::into_inner).collect()
    }

    /// The most contacts any sphere holds.
    pub fn most(&self) -> usize {
        self.counts.iter().copied().max().unwrap_or(0) as usize
    }

    /// Replaces the history of `counts.len()` spheres with one written in another order:
    /// sphere i holds `entries[p·slots .. p·slots + counts[p]]` for p = `sorted_at(i)` (a
    /// gather on the rayon pool), with their load histories where the slots carry them.
    pub fn gather_from<E: Slot>(
        &mut self,
        sorted_at: impl Fn(usize) -> usize + Sync,
        slots: usize,
        counts: &[u32],
        entries: &[E],
    ) -> Result<()> {
        let n = counts.len();
        if self.counts.len() != n || self.slots != slots {
            *self = Self::with_slots(n, slots)?;
        }
        if E::LOADED {
            self.keep_loads()?;
        } else {
            self.loads = Vec::new();
        }
        if slots == 0 {
            self.counts.fill(0);
            return Ok(());
        }
        let rows = self.entries.par_chunks_mut(slots);
        self.counts
            .par_iter_mut()
            .zip(rows)
            .enumerate()
            .for_each(|(i, (count, row))| {
                let p = sorted_at(i);
                let c = counts[p] as usize;
                let from = &entries[p * slots..p * slots + c];
                for (to, e) in row[..c].iter_mut().zip(from) {
                    *to = *e.entry();
                }
                *count = c as u32;
            });
        if E::LOADED {
            let counts = &self.counts;
            self.loads
                .par_chunks_mut(slots)
                .enumerate()
                .for_each(|(i, row)| {
                    let p = sorted_at(i);
                    let c = counts[i] as usize;
                    let from = &entries[p * slots..p * slots + c];
                    for (to, e) in row[..c].iter_mut().zip(from) {
                        *to = e.load();
                    }
                });
        }
        Ok(())
    }

    /// Adds spheres with no contacts until there are `n` (a history with no spheres at all
    /// stays empty: every sphere holds none).
    pub fn grow_to(&mut self, n: usize) -> Result<()> {
        if self.counts.is_empty() || self.counts.len() >= n {
            return Ok(());
        }
        let what = || format!("the contact history of {n} spheres");
        let total = n.checked_mul(self.slots).ok_or_else(|| Error::TooLarge {
            what: what(),
            got: u64::MAX,
            limit: usize::MAX as u64,
        })?;
        self.counts
            .try_reserve(n - self.counts.len())
            .map_err(|_| Error::OutOfMemory {
                what: what(),
                bytes: (4 * n) as u64,
            })?;
        self.counts.resize(n, 0);
        self.entries.resize(total, HistoryEntry::default());
        if !self.loads.is_empty() {
            self.loads.resize(total, LoadEntry::default());
        }
        Ok(())
    }

    /// Makes room for `m` spheres with no contacts at number `at`: the spheres from `at` on
    /// take numbers `m` higher, their partners renamed with them (walls stay as they are).
    pub fn insert_empty(&mut self, at: usize, m: usize) -> Result<()> {
        if self.counts.is_empty() || m == 0 {
            return Ok(());
        }
        let n = self.counts.len();
        for e in &mut self.entries {
            if !is_wall(e.partner, n) && e.partner as usize >= at {
                e.partner += m as u32;
            }
        }
        let slots = self.slots;
        let what = || format!("the contact history of {} spheres", n + m);
        let grow = |len: usize| (len + m * slots) as u64;
        self.counts.try_reserve(m).map_err(|_| Error::OutOfMemory {
            what: what(),
            bytes: 4 * (n + m) as u64,
        })?;
        self.counts.splice(at..at, std::iter::repeat_n(0, m));
        self.entries
            .try_reserve(m * slots)
            .map_err(|_| Error::OutOfMemory {
                what: what(),
                bytes: 32 * grow(self.entries.len()),
            })?;
        let empty = std::iter::repeat_n(HistoryEntry::default(), m * slots);
        self.entries.splice(at * slots..at * slots, empty);
        if !self.loads.is_empty() {
            let empty = std::iter::repeat_n(LoadEntry::default(), m * slots);
            self.loads.splice(at * slots..at * slots, empty);
        }
        Ok(())
    }

    /// Keeps the spheres `i` with `keep[i]` (one flag per sphere), renumbered in order: the
    /// partners are renamed to the new numbers and the contacts with removed spheres dropped;
    /// walls stay as they are.
    pub fn retain(&mut self, keep: &[bool]) {
        if self.counts.is_empty() {
            return;
        }
        let n = keep.len();
        let mut renamed = vec![u32::MAX; n];
        let mut next = 0u32;
        for (i, &k) in keep.iter().enumerate() {
            if k {
                renamed[i] = next;
                next += 1;
            }
        }
        let slots = self.slots;
        let with_loads = self.has_loads();
        let mut counts = Vec::with_capacity(next as usize);
        let mut entries = Vec::with_capacity(next as usize * slots);
        let mut loads = Vec::with_capacity(if with_loads { entries.capacity() } else { 0 });
        for i in (0..n).filter(|&i| keep[i]) {
            let mut held = 0;
            for (k, e) in self.of(i).iter().enumerate() {
                let p = e.partner as usize;
                let partner = match is_wall(e.partner, n) {
                    true => e.partner,
                    false if keep[p] => renamed[p],
                    false => continue,
                };
                entries.push(HistoryEntry { partner, ..*e });
                if with_loads {
                    loads.push(self.loads_of(i)[k]);
                }
                held += 1;
            }
            let free = slots - held as usize;
            entries.resize(entries.len() + free, HistoryEntry::default());
            if with_loads {
                loads.resize(loads.len() + free, LoadEntry::default());
            }
            counts.push(held);
        }
        self.counts = counts;
        self.entries = entries;
        self.loads = loads;
    }

    /// Checks the history against `n` spheres: owners and partners in range, no sphere its own
    /// partner, finite springs.
    pub fn validate(&self, n: usize) -> Result<()> {
        if !self.counts.is_empty() && self.counts.len() != n {
            return Err(Error::Usage(format!(
                "contact history of {} spheres for {n} spheres",
                self.counts.len()
            )));
        }
        for (owner, entry) in self.contacts() {
            check_entry(n, owner as usize, entry)?;
        }
        for i in 0..self.counts.len() {
            for load in self.loads_of(i) {
                check_load(i, load)?;
            }
        }
        Ok(())
    }
}

/// Checks the load history of a contact of sphere `owner`: finite, the normal force ≥ 0.
fn check_load(owner: usize, load: &LoadEntry) -> Result<()> {
    let finite = load.reversal.iter().all(|x| x.is_finite()) && load.normal.is_finite();
    if !finite || load.normal < 0.0 {
        return Err(Error::InvalidSphere {
            index: owner,
            reason: format!("bad load history {load:?}"),
        });
    }
    Ok(())
}

/// Whether `partner` names a wall in the history of `n` spheres.
#[inline]
fn is_wall(partner: u32, n: usize) -> bool {
    partner >= FIRST_WALL || (partner >= FIRST_MESH_WALL && partner as usize >= n)
}

/// Checks one entry of sphere `owner` among `n`.
fn check_entry(n: usize, owner: usize, e: &HistoryEntry) -> Result<()> {
    let bad = |reason: String| {
        Err(Error::InvalidSphere {
            index: owner,
            reason,
        })
    };
    if owner >= n {
        return bad(format!("contact history for sphere {owner} of {n}"));
    }
    let partner = e.partner as usize;
    if !is_wall(e.partner, n) && (partner >= n || partner == owner) {
        return bad(format!("contact history names partner {partner} of {n}"));
    }
    if e.tangential
        .iter()
        .chain(&e.rolling)
        .any(|x| !x.is_finite())
    {
        return bad(format!("non-finite contact history {e:?}"));
    }
    Ok(())
}

/// Equal when every sphere holds the same contacts in the same order, whatever the slots, with
/// the same load histories (a history without them counts as holding zero ones).
impl PartialEq for ContactHistory {
    fn eq(&self, other: &Self) -> bool {
        let n = self.counts.len().max(other.counts.len());
        let loads = |h: &Self, i: usize| -> Vec<LoadEntry> {
            match h.has_loads() {
                true => h.loads_of(i).to_vec(),
                false => vec![LoadEntry::default(); h.of(i).len()],
            }
        };
        (0..n).all(|i| {
            self.of(i) == other.of(i)
                && (!(self.has_loads() || other.has_loads()) || loads(self, i) == loads(other, i))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(partner: u32, x: f32) -> HistoryEntry {
        HistoryEntry {
            partner,
            tangential: [x, 0.0, 0.0],
            rolling: [0.0; 3],
        }
    }

    #[test]
    fn owner_rows_give_each_pair_to_both_spheres_in_the_order_of_their_owners() {
        let load = LoadEntry {
            reversal: [0.5, -0.25, 0.0],
            normal: 2.0,
        };
        // Sphere 0 owns its contacts with 2 and a wall; 1 and 2 both hold theirs.
        let rows = [
            vec![(entry(2, 1.0), load), (entry(FIRST_WALL + 4, 2.0), load)],
            vec![(entry(2, 3.0), LoadEntry::default())],
            vec![(entry(1, -3.0), LoadEntry::default())],
        ];
        let row = |i: usize| rows[i].iter().copied();
        let h = ContactHistory::from_owner_rows(3, true, row).unwrap();
        assert_eq!(h.of(0), &[entry(2, 1.0), entry(FIRST_WALL + 4, 2.0)]);
        assert_eq!(h.of(1), &[entry(2, 3.0)]);
        assert_eq!(h.of(2), &[entry(0, -1.0), entry(1, -3.0)]);
        let mirrored = LoadEntry {
            reversal: [-0.5, 0.25, -0.0],
            normal: 2.0,
        };
        assert_eq!(h.loads_of(2), &[mirrored, LoadEntry::default()]);
        // Without load histories, and both-sided rows as they are.
        let plain = ContactHistory::from_owner_rows(3, false, row).unwrap();
        assert!(!plain.has_loads());
        let both = |i: usize| h.of(i).iter().map(|&e| (e, LoadEntry::default()));
        assert_eq!(
            ContactHistory::from_owner_rows(3, false, both).unwrap(),
            plain
        );
        // The counts without the history: those of the history built.
        let partners = |i: usize| rows[i].iter().map(|(e, _)| e.partner);
        assert_eq!(
            ContactHistory::counts_of_owner_rows(3, partners),
            h.counts(3)
        );
        assert_eq!(h.counts(4), [2, 1, 2, 0]);
        // A partner that is neither a sphere nor a wall.
        let stray = [vec![(entry(7, 1.0), load)]];
        assert!(ContactHistory::from_owner_rows(1, true, |i| stray[i].iter().copied()).is_err());
    }

    #[test]
    fn contacts_round_trip_through_slots_of_any_size() {
        let contacts = [
            (2, entry(0, 1.0)),
            (0, entry(2, -1.0)),
            (2, entry(FIRST_WALL, 3.0)),
        ];
        let h = ContactHistory::from_contacts(3, &contacts).unwrap();
        assert_eq!(h.slots(), 2);
        assert_eq!(h.of(2), &[entry(0, 1.0), entry(FIRST_WALL, 3.0)]);
        assert_eq!(h.of(1), &[]);
        assert_eq!(h.len(), 3);
        // Written sorted (sphere 2 first, then 0, then 1) with 4 slots: the same history.
        let mut sorted = vec![HistoryEntry::default(); 12];
        sorted[0] = entry(0, 1.0);
        sorted[1] = entry(FIRST_WALL, 3.0);
        sorted[4] = entry(2, -1.0);
        let mut g = ContactHistory::default();
        g.gather_from(|i| [1, 2, 0][i], 4, &[2, 1, 0], &sorted)
            .unwrap();
        assert_eq!(g.slots(), 4);
        assert_eq!(g, h);
        assert_ne!(g, ContactHistory::default());
        assert_eq!(
            ContactHistory::with_slots(3, 5).unwrap(),
            ContactHistory::default()
        );
    }

    #[test]
    fn removed_spheres_take_their_contacts_along_and_the_rest_are_renumbered() {
        let contacts = [
            (0, entry(2, 1.0)),
            (0, entry(1, 2.0)),
            (1, entry(0, -2.0)),
            (2, entry(0, -1.0)),
            (2, entry(FIRST_MESH_WALL, 3.0)),
        ];
        let mut h = ContactHistory::from_contacts(3, &contacts).unwrap();
        h.retain(&[true, false, true]);
        let kept = [
            (0, entry(1, 1.0)),
            (1, entry(0, -1.0)),
            (1, entry(FIRST_MESH_WALL, 3.0)),
        ];
        assert_eq!(h, ContactHistory::from_contacts(2, &kept).unwrap());
        h.validate(2).unwrap();
        h.grow_to(4).unwrap();
        assert_eq!(h.of(3), &[]);
        h.validate(4).unwrap();
    }

    #[test]
    fn bad_partners_are_refused() {
        for e in [entry(3, 0.0), entry(1, 0.0), entry(0, f32::NAN)] {
            assert!(
                ContactHistory::from_contacts(3, &[(1, e)]).is_err(),
                "{e:?}"
            );
        }
        assert!(ContactHistory::from_contacts(3, &[(3, entry(0, 0.0))]).is_err());
    }
}
