//! A GPU rank's step kept on its device from round to round, where its backend can
//! ([`ResidentStep`]: wgpu-compute). The step holds the rank's own spheres and its ghosts. After
//! each round the rank reads their states back (not their contact history) and sends each other
//! rank the states of its own spheres within the halo of that rank's box; then its step keeps
//! exactly the spheres of its box and those within the halo of it, each with the state its
//! owner of the round gave it, and takes out the others and appends the new ones. A contact's
//! springs stay where the step keeps them (a pair of a sphere and a ghost is stepped on both
//! ranks, each keeping its own springs for it), so no history crosses ranks and a sphere that
//! moves into a neighbour's box becomes that neighbour's own with the springs the neighbour
//! kept for it as a ghost.

use super::comm::Comm;
use super::grid::Grid;
use super::record::{Held, SphereRecord, own_pair_ends, put, read, record_of};
use crate::dem::flow::NewSphere;
use crate::dem::stepper::Motion;
use crate::engines::common::flow::{DeviceFlow, ResidentStep};
use crate::error::{Error, Result};
use crate::particles::HistoryEntry;
use crate::proxy::ProxyMode;
use rustc_hash::FxHashMap;

/// A rank's step on its device between rounds, and whose its spheres are.
pub(super) struct Resident {
    pub step: Box<dyn DeviceFlow>,
    /// The step's stable ids of its spheres, ascending (its input order).
    stable: Vec<u32>,
    /// The whole run's id of each, in that order.
    global: Vec<u32>,
    /// Whether each is this rank's own (else a ghost), in that order.
    own: Vec<bool>,
    /// The stable id of each sphere of the step, by its id in the whole run.
    stable_of: FxHashMap<u32, u32>,
}

/// What a round's exchange found and left.
pub(super) struct Exchanged {
    /// The round's own spheres' contacts with any sphere, summed, where asked (each contact of
    /// two own spheres counted by both).
    pub touching: Option<u64>,
    /// Where the step had no room for the next round's spheres, the rank's own spheres with
    /// their contacts, by ascending id (the rank opens a step again); `None`: the step holds
    /// the next round's spheres.
    pub settled: Option<Vec<Held>>,
}

impl Resident {
    /// `step`, opened over the spheres of the whole run's ids `ids` (in its input order, its
    /// stable ids `0..`), of which those at the places `own_at` (ascending) are the rank's.
    pub fn new(step: Box<dyn DeviceFlow>, ids: &[u32], own_at: &[usize]) -> Self {
        let mut own = vec![false; ids.len()];
        own_at.iter().for_each(|&at| own[at] = true);
        let stable: Vec<u32> = (0..ids.len() as u32).collect();
        Resident {
            step,
            stable_of: ids.iter().copied().zip(stable.iter().copied()).collect(),
            stable,
            global: ids.to_vec(),
            own,
        }
    }

    /// The step as a resident one (every step a `Resident` holds is one).
    fn resident(&mut self) -> Result<&mut dyn ResidentStep> {
        self.step
            .resident()
            .ok_or_else(|| Error::Usage("a rank's step is not kept on its device".into()))
    }

    /// The whole run's ids of the step's spheres, in its input order.
    pub fn ids(&self) -> &[u32] {
        &self.global
    }

    /// The rank's own spheres.
    pub fn own_spheres(&self) -> usize {
        self.own.iter().filter(|&&own| own).count()
    }

    /// The step's ghosts.
    pub fn ghosts(&self) -> usize {
        self.own.len() - self.own_spheres()
    }

    /// The rank's own spheres with their contacts (partners by the whole run's id), by
    /// ascending id.
    pub fn held(&mut self) -> Result<Vec<Held>> {
        let own: Vec<u32> = (0..self.own.len())
            .filter(|&at| self.own[at])
            .map(|at| self.global[at])
            .collect();
        self.held_of(own, &FxHashMap::default())
    }

    /// The spheres of the whole run's ids `own` with their contacts as the step keeps them,
    /// by ascending id, each in the state of `given` where it has one (one the step does not
    /// hold must have one).
    fn held_of(
        &mut self,
        mut own: Vec<u32>,
        given: &FxHashMap<u32, SphereRecord>,
    ) -> Result<Vec<Held>> {
        own.sort_unstable();
        let whole = self.step.particles()?;
        let ids = &self.global;
        let n = ids.len() as u32;
        // Partners by place to partners by id (a wall keeps its own).
        let rename = |e: &HistoryEntry| HistoryEntry {
            partner: match e.partner < n {
                true => ids[e.partner as usize],
                false => e.partner,
            },
            ..*e
        };
        let place = |g: u32| {
            let k = self.stable_of.get(&g)?;
            self.stable.binary_search(k).ok()
        };
        let mut held = Vec::with_capacity(own.len());
        for g in own {
            let mut h = match (place(g), given.get(&g)) {
                (Some(at), _) => Held::of(&whole, at, g, rename),
                (None, Some(&sphere)) => Held {
                    sphere,
                    contacts: Vec::new(),
                    loads: Vec::new(),
                },
                (None, None) => {
                    return Err(Error::Usage(format!(
                        "rank's own sphere {g} is neither in its step nor given"
                    )));
                }
            };
            if let Some(record) = given.get(&g) {
                h.sphere = *record;
            }
            held.push(h);
        }
        Ok(held)
    }

    /// After a round: reads the spheres back, sends each other rank the own spheres within
    /// the halo of its box (or in it), takes those sent here, and leaves in the step this
    /// rank's spheres (those in its box of `grid`) and its ghosts (within the halo of it), each
    /// in the state its owner of the round gave it; `halo` gives the halo from the fastest own
    /// sphere's speed; where `count` gives the proxy mode, the own spheres' contacts are
    /// found too. Every rank exchanges together.
    pub fn exchange<C: Comm>(
        &mut self,
        comm: &C,
        grid: &Grid,
        halo: impl FnOnce(f64) -> Result<f64>,
        count: Option<ProxyMode>,
    ) -> Result<Exchanged> {
        let me = comm.rank();
        let (now, stable) = self.resident()?.states()?;
        if stable != self.stable {
            return Err(Error::Usage(
                "a rank's step does not hold the spheres the rank gave it".into(),
            ));
        }
        let n = stable.len();
        let own_at: Vec<usize> = (0..n).filter(|&at| self.own[at]).collect();
        let touching = count
            .map(|mode| own_pair_ends(&now, &own_at, mode))
            .transpose()?;
        let speed = |at: usize| glam::Vec3::from(now.velocities[at]).length() as f64;
        let halo = halo(own_at.iter().map(|&at| speed(at)).fold(0.0, f64::max))?;

        // Each own sphere near a face goes to every other rank whose box is within the halo
        // of it; those deep in the box stay as they are.
        let mut outgoing = vec![Vec::new(); comm.size()];
        let mut keep = vec![false; n];
        let mut own_next = vec![false; n];
        for &at in &own_at {
            let x = now.exact_position(at);
            if grid.alone_within(x, halo) == Some(me) {
                (keep[at], own_next[at]) = (true, true);
                continue;
            }
            let record = record_of(&now, at, self.global[at]);
            for r in grid.ranks_within(x, halo) {
                match r == me {
                    true => keep[at] = true,
                    false => put(&mut outgoing[r], &record, (&[], &[])),
                }
            }
            own_next[at] = grid.owner(x) == me;
        }
        // Those sent here: states of spheres held (ghosts, or spheres moving in), or new ones.
        let mut updated = Vec::new();
        let mut coming = Vec::new();
        for message in comm.exchange(outgoing)? {
            for h in read(&message)? {
                let s = h.sphere;
                let at = self
                    .stable_of
                    .get(&s.id)
                    .map(|k| self.stable.binary_search(k));
                match at {
                    Some(Ok(at)) => {
                        (keep[at], own_next[at]) = (true, grid.owner(s.exact_position()) == me);
                        updated.push((at, s));
                    }
                    _ => coming.push(s),
                }
            }
        }
        coming.sort_unstable_by_key(|s| s.id);

        let leaving: Vec<u32> = (0..n)
            .filter(|&at| !keep[at])
            .map(|at| stable[at])
            .collect();
        let new: Vec<NewSphere> = coming
            .iter()
            .map(|s| NewSphere {
                centre: s.position,
                velocity: s.velocity,
                radius: s.radius,
                material: s.material as u8,
            })
            .collect();
        let Some(first) = self.resident()?.replace(&leaving, &new)? else {
            // Opened again by the rank: its own spheres as the next round has them.
            let given: FxHashMap<u32, SphereRecord> = (updated.iter().map(|(_, s)| *s))
                .chain(coming.iter().copied())
                .map(|s| (s.id, s))
                .collect();
            let own = (0..n)
                .filter(|&at| keep[at] && own_next[at])
                .map(|at| self.global[at])
                .chain(
                    coming
                        .iter()
                        .filter(|s| grid.owner(s.exact_position()) == me)
                        .map(|s| s.id),
                )
                .collect();
            let settled = Some(self.held_of(own, &given)?);
            return Ok(Exchanged { touching, settled });
        };

        // Every sphere's state as given, in the step's new input order: the kept, then the
        // appended.
        let mut positions = now.exact_positions()?;
        let (mut velocities, mut spins) = (now.velocities, now.angular_velocities);
        for (at, s) in &updated {
            positions[*at] = s.exact_position();
            (velocities[*at], spins[*at]) = (s.velocity, s.spin);
        }
        let mut order: Vec<usize> = Vec::with_capacity(n);
        for (at, &kept) in keep.iter().enumerate() {
            match kept {
                true => order.push(at),
                false => _ = self.stable_of.remove(&self.global[at]),
            }
        }
        self.stable = order.iter().map(|&at| stable[at]).collect();
        self.global = order.iter().map(|&at| self.global[at]).collect();
        self.own = order.iter().map(|&at| own_next[at]).collect();
        let positions: Vec<[f64; 3]> = order
            .iter()
            .map(|&at| positions[at])
            .chain(coming.iter().map(|s| s.exact_position()))
            .collect();
        let velocities: Vec<[f32; 3]> = order
            .iter()
            .map(|&at| velocities[at])
            .chain(coming.iter().map(|s| s.velocity))
            .collect();
        let spins: Vec<[f32; 3]> = order
            .drain(..)
            .map(|at| spins[at])
            .chain(coming.iter().map(|s| s.spin))
            .collect();
        for (k, s) in (first..).zip(&coming) {
            self.stable.push(k);
            self.global.push(s.id);
            self.own.push(grid.owner(s.exact_position()) == me);
            self.stable_of.insert(s.id, k);
        }
        self.step.set_motion(&Motion {
            positions: Some(&positions),
            velocities: Some(&velocities),
            angular_velocities: Some(&spins),
        })?;
        Ok(Exchanged {
            touching,
            settled: None,
        })
    }
}
