//! Clumps in a run over ranks. A clump and its component spheres are one rank's: the rank whose
//! box holds the clump's centre, wherever its components lie, so that one rank sums each
//! clump's forces (in its template's order, as the whole run does). A clump goes whole wherever
//! it goes: as a ghost to every rank within whose halo any of its components lies, and on
//! migration with every component, so that every clump a rank steps has all its components.

use super::grid::Grid;
use crate::clump::{Clump, ClumpKind, ClumpSet, RigidBody};
use crate::error::{Error, Result};
use crate::particles::Particles;
use glam::{DQuat, DVec3};

/// A clump as the ranks send and hold it: its index in the whole run, its kind and its body.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct ClumpRecord {
    pub index: u32,
    pub kind: u32,
    pub position: [f64; 3],
    pub orientation: [f64; 4],
    pub velocity: [f64; 3],
    pub angular_momentum: [f64; 3],
}

impl ClumpRecord {
    /// `clump` as clump `index` of the whole run.
    pub fn of(clump: &Clump, index: u32) -> Self {
        let b = &clump.body;
        Self {
            index,
            kind: clump.kind as u32,
            position: b.position.to_array(),
            orientation: b.orientation.to_array(),
            velocity: b.velocity.to_array(),
            angular_momentum: b.angular_momentum.to_array(),
        }
    }

    /// The clump it records.
    pub fn clump(&self) -> Clump {
        Clump {
            kind: self.kind as usize,
            body: RigidBody {
                position: DVec3::from_array(self.position),
                orientation: DQuat::from_array(self.orientation),
                velocity: DVec3::from_array(self.velocity),
                angular_momentum: DVec3::from_array(self.angular_momentum),
            },
        }
    }
}

/// The clumps of a run over ranks: what every rank knows of them (their kinds, where each
/// clump's components lie among the run's ids) and the clumps this rank owns.
#[derive(Debug, Clone)]
pub(super) struct RankClumps {
    kinds: Vec<ClumpKind>,
    /// The id of each clump's first component, then the number of components.
    first: Vec<u32>,
    /// The farthest any component's centre lies from its clump's centre \[m\].
    pub span: f64,
    /// This rank's clumps, by ascending index.
    pub own: Vec<ClumpRecord>,
}

impl RankClumps {
    /// The clumps of `whole` (`None` where it has none, nor kinds of clumps: a run whose
    /// clumps have all left keeps their kinds), those whose centres lie in box `rank` of `grid`
    /// this rank's.
    pub fn of(whole: &Particles, grid: &Grid, rank: usize) -> Option<Self> {
        let set = &whole.clumps;
        if set.clumps.is_empty() && set.kinds.is_empty() {
            return None;
        }
        let mut first = Vec::with_capacity(set.clumps.len() + 1);
        let mut next = 0u32;
        for c in &set.clumps {
            first.push(next);
            next += set.kinds[c.kind].template.components.len() as u32;
        }
        first.push(next);
        let span = (set.kinds.iter())
            .flat_map(|k| k.template.components.iter().map(|c| c.centre.length()))
            .fold(0.0, f64::max);
        let own = (set.clumps.iter().enumerate())
            .filter(|(_, c)| grid.owner(c.body.position.to_array()) == rank)
            .map(|(k, c)| ClumpRecord::of(c, k as u32))
            .collect();
        Some(Self {
            kinds: set.kinds.clone(),
            first,
            span,
            own,
        })
    }

    /// The clumps of the run.
    pub fn count(&self) -> usize {
        self.first.len() - 1
    }

    /// The spheres that are components (the run's first ids).
    pub fn components(&self) -> u32 {
        self.first[self.first.len() - 1]
    }

    /// The component spheres of clump `index`: their ids.
    pub fn ids_of(&self, index: u32) -> std::ops::Range<u32> {
        self.first[index as usize]..self.first[index as usize + 1]
    }

    /// The clump of the run whose component sphere `id` is (`None`: a free sphere).
    pub fn clump_of(&self, id: u32) -> Option<u32> {
        let components = self.components();
        (id < components).then(|| (self.first.partition_point(|&f| f <= id) - 1) as u32)
    }

    /// The clumps of `records` (by ascending index) as a set of every kind of the run.
    pub fn set_of<'a>(&self, records: impl Iterator<Item = &'a ClumpRecord>) -> ClumpSet {
        ClumpSet {
            kinds: self.kinds.clone(),
            clumps: records.map(ClumpRecord::clump).collect(),
        }
    }

    /// The clumps whose components are the first spheres of a rank's local set of spheres of
    /// the run's ids `ids`: this rank's and `ghosts` (both by ascending index) merged by
    /// index, with each one's index and the places of this rank's among them. Every
    /// component of each must be among the spheres, in the run's order, before any other.
    pub fn local(&self, ghosts: &[ClumpRecord], ids: &[u32]) -> Result<LocalClumps> {
        let mut records = Vec::with_capacity(self.own.len() + ghosts.len());
        let mut own_at = Vec::with_capacity(self.own.len());
        let (mut a, mut b) = (0, 0);
        while a < self.own.len() || b < ghosts.len() {
            let take_own =
                b == ghosts.len() || (a < self.own.len() && self.own[a].index < ghosts[b].index);
            match take_own {
                true => {
                    own_at.push(records.len());
                    records.push(self.own[a]);
                    a += 1;
                }
                false => {
                    records.push(ghosts[b]);
                    b += 1;
                }
            }
        }
        let expected = records.iter().flat_map(|c| self.ids_of(c.index));
        let mut count = 0;
        for (k, id) in expected.enumerate() {
            if ids.get(k) != Some(&id) {
                return Err(Error::Usage(
                    "a clump's spheres are not all on the rank that steps it".into(),
                ));
            }
            count += 1;
        }
        if ids.get(count).is_some_and(|&id| id < self.components()) {
            return Err(Error::Usage(
                "a clump's sphere is on a rank without its clump".into(),
            ));
        }
        Ok(LocalClumps {
            set: self.set_of(records.iter()),
            indices: records.iter().map(|c| c.index).collect(),
            own_at,
        })
    }

    /// This rank's clumps again from `set`, the clumps of [`local`](Self::local) stepped.
    pub fn take_own(&mut self, set: &ClumpSet, local: &LocalClumps) {
        self.own = (local.own_at.iter())
            .map(|&at| ClumpRecord::of(&set.clumps[at], local.indices[at]))
            .collect();
    }
}

/// A rank's clumps for a round: its own and its ghosts'.
pub(super) struct LocalClumps {
    /// The clumps, by ascending index.
    pub set: ClumpSet,
    /// Each one's index in the whole run.
    pub indices: Vec<u32>,
    /// The places of this rank's own among them.
    pub own_at: Vec<usize>,
}

/// The clumps of messages of clump records, by ascending index.
pub(super) fn read_clumps(messages: &[Vec<u8>]) -> Result<Vec<ClumpRecord>> {
    let size = std::mem::size_of::<ClumpRecord>();
    if messages.iter().any(|m| m.len() % size != 0) {
        return Err(Error::Usage("a rank's message ends inside a clump".into()));
    }
    let mut all: Vec<ClumpRecord> = (messages.iter())
        .flat_map(|m| m.chunks_exact(size).map(bytemuck::pod_read_unaligned))
        .collect();
    all.sort_unstable_by_key(|c| c.index);
    Ok(all)
}
