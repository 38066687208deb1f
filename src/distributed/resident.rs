//! A GPU rank's step kept on its device from round to round, where its backend can
//! ([`ResidentStep`]: wgpu-compute). The step holds the rank's own spheres and its ghosts. After
//! each round the step lists, on the device, the own spheres near the faces of the rank's box
//! (outside it shrunk by the halo) and its ghosts' rows; the rank reads back these alone, sends
//! each other rank the states of its own spheres within the halo of that rank's box, and the
//! step writes the states sent here into their ghosts' rows, takes out the spheres that left
//! the rank's box and halo and appends the new ones: a round moves the layer near the faces,
//! not the rank. A contact's springs stay where the step keeps them (a pair of a sphere and a
//! ghost is stepped on both ranks, each keeping its own springs for it), so no history crosses
//! ranks and a sphere that moves into a neighbour's box becomes that neighbour's own with the
//! springs the neighbour kept for it as a ghost.

use super::comm::Comm;
use super::grid::Grid;
use super::record::{Held, SphereRecord, own_pair_ends, partners_by_id};
use crate::dem::flow::NewSphere;
use crate::engines::common::flow::{
    Arriving, DeviceFlow, DeviceRows, NearFaces, NearRow, ResidentStep, RowState,
};
use crate::error::{Error, Result};
use crate::particles::Particles;
use crate::particles::position::join;
use crate::proxy::ProxyMode;
use rayon::prelude::*;
use rustc_hash::{FxHashMap, FxHashSet};

/// Marks a stable id whose sphere the step no longer holds.
const GONE: u32 = u32::MAX;

/// How much deeper than the last round's halo a round gathers the spheres near the faces
/// (the round's own halo is known only once every rank has its speeds; a deeper one gathers
/// again).
const GATHER_MARGIN: f64 = 1.1;

/// A rank's step on its device between rounds, and whose its spheres are.
pub(super) struct Resident {
    pub step: Box<dyn DeviceFlow>,
    /// The whole run's id of the sphere of each stable id of the step ([`GONE`]: none now).
    global: Vec<u32>,
    /// Whether the sphere of each stable id is this rank's own (else a ghost); the step holds
    /// the same marks.
    own: Vec<bool>,
    /// The stable id of each sphere of the step, by its whole-run id.
    stable_of: FxHashMap<u32, u32>,
    /// The rank's own spheres.
    owned: usize,
    /// How far inside the box the next round gathers the spheres near its faces \[m\].
    depth: f64,
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
    /// The time reading the step's rows back took \[ms\].
    pub read_ms: f64,
}

impl Resident {
    /// `step`, opened over the spheres of the whole run's ids `ids` (in its input order, its
    /// stable ids `0..`), of which those at the places `own_at` (ascending) are the rank's.
    pub fn new(mut step: Box<dyn DeviceFlow>, ids: &[u32], own_at: &[usize]) -> Result<Self> {
        let mut own = vec![false; ids.len()];
        own_at.iter().for_each(|&at| own[at] = true);
        let marks: Vec<(u32, bool)> = own_at.iter().map(|&at| (at as u32, true)).collect();
        let resident = step
            .resident()
            .ok_or_else(|| Error::Usage("a rank's step is not kept on its device".into()))?;
        resident.mark_own(&marks)?;
        Ok(Resident {
            step,
            stable_of: ids.iter().copied().zip(0..).collect(),
            global: ids.to_vec(),
            own,
            owned: own_at.len(),
            depth: 0.0,
        })
    }

    /// The step as a resident one (every step a `Resident` holds is one).
    fn resident(&mut self) -> Result<&mut dyn ResidentStep> {
        self.step
            .resident()
            .ok_or_else(|| Error::Usage("a rank's step is not kept on its device".into()))
    }

    /// The whole run's ids of the step's spheres, in its input order (ascending stable id).
    pub fn ids(&self) -> Vec<u32> {
        self.global.iter().copied().filter(|&g| g != GONE).collect()
    }

    /// The rank's own spheres.
    pub fn own_spheres(&self) -> usize {
        self.owned
    }

    /// The step's ghosts.
    pub fn ghosts(&self) -> usize {
        self.stable_of.len() - self.own_spheres()
    }

    /// The rank's own spheres with their contacts (partners by the whole run's id), by
    /// ascending id.
    pub fn held(&mut self) -> Result<Vec<Held>> {
        let own = (self.global.iter().zip(&self.own))
            .filter(|(_, own)| **own)
            .map(|(&g, _)| g)
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
        // The step's input order: ascending stable id.
        let ids = self.ids();
        let rename = partners_by_id(&ids);
        let place: FxHashMap<u32, usize> = ids.iter().enumerate().map(|(at, &g)| (g, at)).collect();
        let mut held = Vec::with_capacity(own.len());
        for g in own {
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

    /// After a round: lists the own spheres near the faces of the rank's box of `grid`, sends
    /// each other rank those within the halo of its box (or in it), takes those sent here, and
    /// leaves in the step this rank's spheres (those in its box) and its ghosts (within the halo
    /// of it), each in the state its owner of the round gave it; `halo` gives the halo from the
    /// fastest own sphere's speed (every rank together); where `count` gives the proxy mode,
    /// the own spheres' contacts are found too (every row read back). Every rank exchanges
    /// together.
    pub fn exchange<C: Comm>(
        &mut self,
        comm: &C,
        grid: &Grid,
        halo: impl FnOnce(f64) -> Result<f64>,
        count: Option<ProxyMode>,
    ) -> Result<Exchanged> {
        let me = comm.rank();
        let started = std::time::Instant::now();
        let touching = count.map(|mode| self.own_pair_ends(mode)).transpose()?;
        let bounds = grid.bounds_of(me);
        let mut faces = self.near_faces(bounds, self.depth)?;
        let halo = halo(faces.fastest as f64)?;
        if halo > self.depth {
            faces = self.near_faces(bounds, halo)?;
        }
        self.depth = halo * GATHER_MARGIN;
        let read_ms = started.elapsed().as_secs_f64() * 1e3;
        if faces.rows as usize != self.stable_of.len()
            || faces.ghosts.len() != self.stable_of.len() - self.owned
        {
            return Err(Error::Usage(
                "a rank's step does not hold the spheres the rank gave it".into(),
            ));
        }

        // Each own sphere near a face goes to every other rank whose box is within the halo
        // of it; those deep in the box stay as they are. The messages are bare records.
        let own = &self.own;
        if (faces.near.iter()).any(|near| !own.get(near.stable as usize).is_some_and(|&o| o)) {
            return Err(Error::Usage(
                "a rank's step listed as its own a sphere the rank does not own".into(),
            ));
        }
        let global = &self.global;
        let placed: Vec<Placed> = (faces.near.par_iter())
            .map(|near| {
                let x = exact(near);
                let ranks = grid.ranks_within(x, halo);
                let record = record_of_near(near, global[near.stable as usize]);
                (near.row, near.stable, ranks, grid.owner(x) == me, record)
            })
            .collect();
        let mut outgoing = vec![Vec::new(); comm.size()];
        let (mut leaving, mut gone) = (Vec::new(), Vec::new());
        let mut to_ghost = Vec::new();
        for (row, k, ranks, owned, record) in &placed {
            if ranks[..] == [me] {
                continue;
            }
            for &rank in ranks.iter().filter(|&&rank| rank != me) {
                outgoing[rank].extend_from_slice(bytemuck::bytes_of(record));
            }
            if !ranks.contains(&me) {
                leaving.push(*row);
                gone.push(*k);
            } else if !owned {
                to_ghost.push(*k);
            }
        }
        // Those sent here: states of the ghosts (written into their rows; a ghost no owner
        // sent has left the halo), or new spheres.
        let mut ghost_row = vec![GONE; self.global.len()];
        for &[row, k] in &faces.ghosts {
            ghost_row[k as usize] = row;
        }
        let mut received = Vec::new();
        for message in comm.exchange(outgoing)? {
            received.extend(records(&message)?);
        }
        let stable_of = &self.stable_of;
        let taken: Vec<Taken> = (received.par_iter())
            .map(|s| match stable_of.get(&s.id) {
                None => Ok(Taken::Coming(*s)),
                Some(&k) => match ghost_row[k as usize] {
                    GONE => Err(Error::Usage(format!(
                        "rank {me} was sent the state of sphere {} that is not its ghost",
                        s.id
                    ))),
                    row => Ok(Taken::Ghost(k, row, grid.owner(s.exact_position()) == me)),
                },
            })
            .collect::<Result<_>>()?;
        let mut states = Vec::with_capacity(received.len());
        let (mut to_own, mut updated, mut coming) = (Vec::new(), Vec::new(), Vec::new());
        for (taken, s) in taken.into_iter().zip(&received) {
            match taken {
                Taken::Coming(s) => coming.push(s),
                Taken::Ghost(k, row, owned) => {
                    if ghost_row[k as usize] == GONE {
                        return Err(Error::Usage(format!(
                            "rank {me} was sent sphere {} twice",
                            s.id
                        )));
                    }
                    ghost_row[k as usize] = GONE;
                    states.push(RowState {
                        row,
                        position: s.position,
                        residual: s.residual,
                        velocity: s.velocity,
                        spin: s.spin,
                    });
                    if owned {
                        to_own.push(k);
                    }
                    updated.push(*s);
                }
            }
        }
        for &[row, k] in &faces.ghosts {
            if ghost_row[k as usize] != GONE {
                leaving.push(row);
                gone.push(k);
            }
        }
        coming.sort_unstable_by_key(|s| s.id);
        let arriving: Vec<Arriving> = coming.iter().map(arriving_of).collect();

        // Where some rank's step has no room, every rank opens its step again (they exchange
        // alike), from its own spheres as the next round has them.
        let fits = self.resident()?.fits(leaving.len(), &arriving);
        let everywhere = comm.exchange(vec![vec![fits as u8]; comm.size()])?;
        if !(fits && everywhere.iter().all(|m| m.iter().all(|&b| b == 1))) {
            let given: FxHashMap<u32, SphereRecord> = (updated.iter().chain(&coming))
                .map(|s| (s.id, *s))
                .collect();
            let not_own: FxHashSet<u32> = gone.iter().chain(&to_ghost).copied().collect();
            let own = (0..self.global.len() as u32)
                .filter(|k| self.own[*k as usize] && !not_own.contains(k))
                .chain(to_own.iter().copied())
                .map(|k| self.global[k as usize])
                .chain(
                    (coming.iter())
                        .filter(|s| grid.owner(s.exact_position()) == me)
                        .map(|s| s.id),
                )
                .collect();
            let settled = Some(self.held_of(own, &given)?);
            return Ok(Exchanged {
                touching,
                settled,
                read_ms,
            });
        }
        let first = self.resident()?.update(&states, &leaving, &arriving)?;

        let mut marks = Vec::with_capacity(to_ghost.len() + to_own.len() + coming.len());
        for k in gone {
            let k = k as usize;
            self.stable_of.remove(&self.global[k]);
            self.owned -= self.own[k] as usize;
            (self.global[k], self.own[k]) = (GONE, false);
        }
        for (k, own) in
            (to_ghost.iter().map(|&k| (k, false))).chain(to_own.iter().map(|&k| (k, true)))
        {
            self.own[k as usize] = own;
            marks.push((k, own));
        }
        self.owned = self.owned + to_own.len() - to_ghost.len();
        // The step numbers the spheres it appends after every one it was given.
        if first as usize != self.global.len() {
            return Err(Error::Usage(
                "a rank's step numbered the spheres it took other than the rank did".into(),
            ));
        }
        for (k, s) in (first..).zip(&coming) {
            let own = grid.owner(s.exact_position()) == me;
            self.global.push(s.id);
            self.own.push(own);
            self.stable_of.insert(s.id, k);
            self.owned += own as usize;
            marks.push((k, own));
        }
        self.resident()?.mark_own(&marks)?;
        Ok(Exchanged {
            touching,
            settled: None,
            read_ms,
        })
    }

    /// The step's own spheres outside its rank's box `bounds` shrunk by `depth`, its ghosts'
    /// rows and its own spheres' largest speed.
    fn near_faces(&mut self, bounds: ([f64; 3], [f64; 3]), depth: f64) -> Result<NearFaces> {
        let (lo, hi) = bounds;
        // Shrunk a little more, so that the `f32` centres miss no sphere near a face.
        let slack = |x: f64| 1e-5 * (x.abs() + depth);
        let side = |x: f64, inward: f64| match x.is_finite() {
            true => (x + inward * (depth + slack(x))) as f32,
            false => x as f32,
        };
        let inner = (lo.map(|x| side(x, 1.0)), hi.map(|x| side(x, -1.0)));
        self.resident()?.near_faces(inner)
    }

    /// The own spheres' contacts with any sphere, summed (each contact of two own spheres
    /// counted by both), found on the host from every row read back.
    fn own_pair_ends(&mut self, mode: ProxyMode) -> Result<u64> {
        let rows = self.resident()?.rows()?;
        let own = &self.own;
        let own_rows: Vec<usize> = (0..rows.ids.len())
            .into_par_iter()
            .filter(|&r| own.get(rows.ids[r] as usize).is_some_and(|&own| own))
            .collect();
        own_pair_ends(&spheres_of(&rows), &own_rows, mode)
    }
}

/// An own sphere near a face: its row, stable id, the ranks whose boxes lie within the halo of
/// it, whether it stays this rank's own, and its record.
type Placed = (u32, u32, Vec<usize>, bool, SphereRecord);

/// A sphere sent here: a ghost's new state (its stable id, row, and whether it is this rank's
/// own now), or a sphere the step does not hold.
enum Taken {
    Ghost(u32, u32, bool),
    Coming(SphereRecord),
}

/// The bare records of a message (no history follows any).
fn records(message: &[u8]) -> Result<Vec<SphereRecord>> {
    let size = std::mem::size_of::<SphereRecord>();
    if !message.len().is_multiple_of(size) {
        return Err(Error::Usage("a rank's message ends inside a sphere".into()));
    }
    let records: Vec<SphereRecord> = bytemuck::pod_collect_to_vec(message);
    if records.iter().any(|s| s.contacts != 0 || s.loads != 0) {
        return Err(Error::Usage(
            "a rank's states of its spheres near a face carry contacts".into(),
        ));
    }
    Ok(records)
}

/// Where the centre of `near` is, in `f64`.
fn exact(near: &NearRow) -> [f64; 3] {
    std::array::from_fn(|a| join(near.pos[a], near.lo[a]))
}

/// The sphere of `near` as a record of the whole run's id `id`.
fn record_of_near(near: &NearRow, id: u32) -> SphereRecord {
    SphereRecord {
        id,
        material: near.omega[3] as u32,
        radius: near.pos[3],
        position: [near.pos[0], near.pos[1], near.pos[2]],
        residual: near.lo,
        velocity: near.vel,
        spin: [near.omega[0], near.omega[1], near.omega[2]],
        contacts: 0,
        loads: 0,
    }
}

/// The sphere of `s` as a step appends it.
fn arriving_of(s: &SphereRecord) -> Arriving {
    Arriving {
        sphere: NewSphere {
            centre: s.position,
            velocity: s.velocity,
            radius: s.radius,
            material: s.material as u8,
        },
        residual: s.residual,
        spin: s.spin,
    }
}

/// The rows' spheres (centres and radii), for finding their contacts.
fn spheres_of(rows: &DeviceRows) -> Particles {
    Particles {
        positions: rows.pos.iter().map(|p| [p[0], p[1], p[2]]).collect(),
        radii: rows.pos.iter().map(|p| p[3]).collect(),
        ..Particles::default()
    }
}
