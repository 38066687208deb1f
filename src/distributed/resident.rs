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
use std::collections::{BTreeMap, HashMap};

/// A rank's step on its device between rounds, and whose its spheres are.
pub(super) struct Resident {
    pub step: Box<dyn DeviceFlow>,
    /// The whole run's id of each sphere of the step, by its stable id there (in the step's
    /// input order).
    global: BTreeMap<u32, u32>,
    /// The whole run's ids of this rank's own spheres, ascending.
    pub own: Vec<u32>,
    /// The step's spheres that are ghosts.
    pub ghosts: usize,
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
    /// stable ids `0..`), of which those of `own` (ascending) are the rank's.
    pub fn new(step: Box<dyn DeviceFlow>, ids: &[u32], own: Vec<u32>) -> Self {
        Resident {
            step,
            global: (0..).zip(ids.iter().copied()).collect(),
            ghosts: ids.len() - own.len(),
            own,
        }
    }

    /// The step as a resident one (every step a `Resident` holds is one).
    fn resident(&mut self) -> Result<&mut dyn ResidentStep> {
        self.step
            .resident()
            .ok_or_else(|| Error::Usage("a rank's step is not kept on its device".into()))
    }

    /// The whole run's ids of the step's spheres of stable ids `stable`.
    fn globals(&self, stable: &[u32]) -> Result<Vec<u32>> {
        let unknown = || Error::Usage("a rank's step holds a sphere the rank does not know".into());
        stable
            .iter()
            .map(|k| self.global.get(k).copied().ok_or_else(unknown))
            .collect()
    }

    /// The whole run's ids of the step's spheres, in its input order.
    pub fn ids(&self) -> Vec<u32> {
        self.global.values().copied().collect()
    }

    /// The rank's own spheres with their contacts (partners by the whole run's id), by
    /// ascending id, with the states of `given` in place of the step's where it has them.
    pub fn held(&mut self, given: &HashMap<u32, SphereRecord>) -> Result<Vec<Held>> {
        let (_, stable) = self.resident()?.states()?;
        let ids = self.globals(&stable)?;
        let whole = self.step.particles()?;
        let n = ids.len() as u32;
        // Partners by place to partners by id (a wall keeps its own).
        let rename = |e: &HistoryEntry| HistoryEntry {
            partner: match e.partner < n {
                true => ids[e.partner as usize],
                false => e.partner,
            },
            ..*e
        };
        let place: HashMap<u32, usize> = ids.iter().enumerate().map(|(at, &g)| (g, at)).collect();
        let mut held = Vec::with_capacity(self.own.len());
        for &g in &self.own {
            let mut h = match (place.get(&g), given.get(&g)) {
                (Some(&at), _) => Held::of(&whole, at, g, rename),
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
        let ids = self.globals(&stable)?;
        if ids.len() != self.global.len() {
            return Err(Error::Usage(
                "a rank's step does not hold the spheres the rank gave it".into(),
            ));
        }
        // The own spheres' places, and their contacts where asked.
        let own_at: Vec<usize> = (0..ids.len())
            .filter(|&at| self.own.binary_search(&ids[at]).is_ok())
            .collect();
        let touching = count
            .map(|mode| own_pair_ends(&now, &own_at, mode))
            .transpose()?;
        let fastest = own_at
            .iter()
            .map(|&at| record_of(&now, at, ids[at]).speed())
            .fold(0.0, f64::max);
        let halo = halo(fastest)?;

        // Each own sphere's state goes to every rank whose box is within the halo of it.
        let mut outgoing = vec![Vec::new(); comm.size()];
        let mut given: HashMap<u32, SphereRecord> = HashMap::with_capacity(ids.len());
        for &at in &own_at {
            let record = record_of(&now, at, ids[at]);
            let x = now.exact_position(at);
            for r in grid.ranks_within(x, halo) {
                match r == me {
                    true => {
                        given.insert(record.id, record);
                    }
                    false => put(&mut outgoing[r], &record, (&[], &[])),
                }
            }
        }
        for message in comm.exchange(outgoing)? {
            for h in read(&message)? {
                given.insert(h.sphere.id, h.sphere);
            }
        }

        // Out: the spheres given none; in: those given and not held.
        let held: HashMap<u32, u32> = stable.iter().zip(&ids).map(|(&k, &g)| (g, k)).collect();
        let leaving: Vec<u32> = stable
            .iter()
            .zip(&ids)
            .filter(|(_, g)| !given.contains_key(g))
            .map(|(&k, _)| k)
            .collect();
        let mut coming: Vec<&SphereRecord> = given
            .values()
            .filter(|s| !held.contains_key(&s.id))
            .collect();
        coming.sort_unstable_by_key(|s| s.id);
        let new: Vec<NewSphere> = coming
            .iter()
            .map(|s| NewSphere {
                centre: s.position,
                velocity: s.velocity,
                radius: s.radius,
                material: s.material as u8,
            })
            .collect();
        let mut own: Vec<u32> = given
            .values()
            .filter(|s| grid.owner(s.exact_position()) == me)
            .map(|s| s.id)
            .collect();
        own.sort_unstable();
        let Some(first) = self.resident()?.replace(&leaving, &new)? else {
            self.own = own;
            let settled = Some(self.held(&given)?);
            return Ok(Exchanged { touching, settled });
        };
        for k in &leaving {
            self.global.remove(k);
        }
        self.global
            .extend((first..).zip(coming.iter().map(|s| s.id)));

        // Every sphere's state as given, in the step's input order (ascending stable id).
        let states: Vec<&SphereRecord> = self.global.values().map(|g| &given[g]).collect();
        let positions: Vec<[f64; 3]> = states.iter().map(|s| s.exact_position()).collect();
        let velocities: Vec<[f32; 3]> = states.iter().map(|s| s.velocity).collect();
        let spins: Vec<[f32; 3]> = states.iter().map(|s| s.spin).collect();
        self.step.set_motion(&Motion {
            positions: Some(&positions),
            velocities: Some(&velocities),
            angular_velocities: Some(&spins),
        })?;
        self.ghosts = states.len() - own.len();
        self.own = own;
        Ok(Exchanged {
            touching,
            settled: None,
        })
    }
}
