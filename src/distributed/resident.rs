//! A GPU rank's step kept on its device from round to round, where its backend can
//! ([`ResidentStep`]: wgpu-compute). The step holds the rank's own spheres and its ghosts. After
//! each round the step writes, on the device, the records of its own spheres near the faces of
//! the rank's box for each neighbouring box within the halo of them; the rank sends these bytes
//! as they are, and the step places the records sent here (a ghost's state into its row, a
//! sphere that entered the box made the rank's own), lists the spheres that leave (ghosts no
//! owner sent, own spheres beyond the box grown by the halo) and marks those that left the box
//! as ghosts; the rank then takes out the leaving and appends the spheres it did not hold. So a
//! round moves the layer near the faces, and the host handles only the spheres that come and
//! go. A contact's springs stay where the step keeps them (a pair of a sphere and a ghost is
//! stepped on both ranks, each keeping its own springs for it), so no history crosses ranks and
//! a sphere that moves into a neighbour's box becomes that neighbour's own with the springs the
//! neighbour kept for it as a ghost. Where a centre lies the devices decide in `f32`, alike on
//! both sides of a face ([`LayerBounds`]).

use super::comm::Comm;
use super::grid::Grid;
use super::pieces::OwnPiece;
use super::record::{Held, SphereRecord, own_pair_ends, partners_by_id};
use crate::dem::flow::NewSphere;
use crate::engines::common::flow::{
    Arriving, DeviceFlow, DeviceRows, Layer, LayerBounds, LayerRecord, Named, ResidentStep,
    direction,
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
    /// The spheres the step holds.
    held: usize,
    /// The rank's own spheres among them (the step marks which).
    owned: usize,
    /// How far inside the box the next round gathers the spheres near its faces \[m\].
    depth: f64,
    /// The buffers of a round's records, kept from round to round: as the step gathers them
    /// (by direction), as sent and as received (by rank).
    layer: Layer,
    outgoing: Vec<Vec<u8>>,
    received: Vec<Vec<u8>>,
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
    /// The time counting the contacts and writing and reading back the records near the faces
    /// took \[ms\] (not waiting for the other ranks).
    pub read_ms: f64,
}

impl Resident {
    /// `step`, opened over the spheres of the whole run's ids `ids` (in its input order, its
    /// stable ids `0..`), of which those at the places `own_at` (ascending) are the rank's.
    pub fn new(step: Box<dyn DeviceFlow>, ids: &[u32], own_at: &[usize]) -> Result<Self> {
        let mut names: Vec<Named> = (0..ids.len() as u32)
            .map(|k| Named {
                stable: k,
                whole: ids[k as usize],
                own: false,
            })
            .collect();
        own_at.iter().for_each(|&at| names[at].own = true);
        let mut resident = Resident {
            step,
            global: ids.to_vec(),
            held: ids.len(),
            owned: own_at.len(),
            depth: 0.0,
            layer: Layer::default(),
            outgoing: Vec::new(),
            received: Vec::new(),
        };
        resident.resident()?.name(&names)?;
        Ok(resident)
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
        self.held - self.owned
    }

    /// The whole run's ids of the rank's own spheres, less those of the stable ids `not`.
    fn own_ids(&mut self, not: &FxHashSet<u32>) -> Result<Vec<u32>> {
        let marks = self.resident()?.own_marks()?;
        Ok((marks.iter().zip(0u32..))
            .filter(|&(&own, k)| own == 1 && !not.contains(&k))
            .map(|(_, k)| self.global[k as usize])
            .filter(|&g| g != GONE)
            .collect())
    }

    /// The halo of the last round's exchange (0 before the first) \[m\].
    pub fn halo(&self) -> f64 {
        self.depth / GATHER_MARGIN
    }

    /// Where the rank's own spheres' centres are, in no order (every row read back).
    pub fn own_centres(&mut self) -> Result<Vec<[f64; 3]>> {
        let rows = self.resident()?.rows()?;
        let marks = self.resident()?.own_marks()?;
        Ok((0..rows.ids.len())
            .into_par_iter()
            .filter(|&r| marks.get(rows.ids[r] as usize) == Some(&1))
            .map(|r| std::array::from_fn(|a| join(rows.pos[r][a], rows.lo[r][a])))
            .collect())
    }

    /// The rank's own spheres with their contacts (partners by the whole run's id), by
    /// ascending id.
    pub fn held(&mut self) -> Result<Vec<Held>> {
        let own = self.own_ids(&FxHashSet::default())?;
        self.held_of(own, &FxHashMap::default())
    }

    /// The rank's own spheres as records, in no order, each with the contacts it holds counted
    /// in [`SphereRecord::contacts`] (no springs read back).
    pub fn seen(&mut self) -> Result<Vec<SphereRecord>> {
        let own = self.own_places()?;
        let now = self.step.snapshot()?;
        Ok((own.into_par_iter())
            .map(|(at, g)| SphereRecord {
                contacts: now.contacts[at],
                ..super::record::record_of(&now.particles, at, g)
            })
            .collect())
    }

    /// Each own sphere's place in the step's input order and its whole-run id.
    fn own_places(&mut self) -> Result<Vec<(usize, u32)>> {
        let marks = self.resident()?.own_marks()?;
        // The step's input order is ascending stable id: the place of a held sphere is its
        // stable id's among those held.
        let held = (self.global.iter().zip(0..)).filter(|&(&g, _)| g != GONE);
        Ok((held.enumerate())
            .filter(|&(_, (_, k))| marks.get(k) == Some(&1))
            .map(|(at, (&g, _))| (at, g))
            .collect())
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
        let place = place_by_id(&ids, &own);
        (own.into_par_iter())
            .map(|g| {
                let mut h = match (place[g as usize], given.get(&g)) {
                    (GONE, Some(&sphere)) => Held {
                        sphere,
                        contacts: Vec::new(),
                        loads: Vec::new(),
                    },
                    (GONE, None) => {
                        return Err(Error::Usage(format!(
                            "rank's own sphere {g} is neither in its step nor given"
                        )));
                    }
                    (at, _) => Held::of(&whole, at as usize, g, rename),
                };
                if let Some(record) = given.get(&g) {
                    h.sphere = *record;
                }
                Ok(h)
            })
            .collect()
    }

    /// The rank's own spheres as its piece of a checkpoint holds them (their contacts'
    /// partners by the whole run's id).
    pub fn own_piece(&mut self) -> Result<OwnPiece> {
        let mut own = self.own_ids(&FxHashSet::default())?;
        own.par_sort_unstable();
        let whole = self.step.particles()?;
        let ids = self.ids();
        let place = place_by_id(&ids, &own);
        let places = (own.par_iter())
            .map(|&g| match place[g as usize] {
                GONE => Err(Error::Usage(format!(
                    "rank's own sphere {g} is not in its step"
                ))),
                at => Ok(at as usize),
            })
            .collect::<Result<Vec<usize>>>()?;
        Ok(OwnPiece::of_places(
            &whole,
            (own, &places),
            partners_by_id(&ids),
        ))
    }

    /// After a round: writes the records of the own spheres near the faces of the rank's box
    /// of `grid` for the neighbouring boxes, sends them, places those sent here and leaves in
    /// the step this rank's spheres (those in its box) and its ghosts (within the halo of it),
    /// each in the state its owner of the round gave it; `halo` gives the halo from the fastest
    /// own sphere's speed (every rank together); where `count` gives the proxy mode, the own
    /// spheres' contacts are counted too ([`own_pair_ends`](Self::own_pair_ends)). Every rank
    /// exchanges together.
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
        let first = bounds(grid, me, self.depth);
        let mut layer = std::mem::take(&mut self.layer);
        self.resident()?.gather_layer(&first, &mut layer)?;
        let mut read_ms = started.elapsed().as_secs_f64() * 1e3;
        // Every rank's speed: the wait for the others is not this rank's work.
        let halo = halo(layer.fastest as f64)?;
        if halo > self.depth {
            let again = std::time::Instant::now();
            self.resident()?
                .gather_layer(&bounds(grid, me, halo), &mut layer)?;
            read_ms += again.elapsed().as_secs_f64() * 1e3;
        }
        self.depth = halo * GATHER_MARGIN;

        // Each direction's records go to the box that lies that way, as they are: the first
        // list for a rank swapped into its message (the list keeps the buffer sent last round,
        // whose bytes the next gathering overwrites), any other appended.
        self.outgoing.resize_with(comm.size(), Vec::new);
        let mut filled = vec![false; comm.size()];
        for (d, list) in layer.lists.iter_mut().enumerate() {
            if list.is_empty() {
                continue;
            }
            let rank = (grid.neighbour(me, way(d)))
                .filter(|&r| r != me && d != direction([0; 3]))
                .ok_or_else(|| {
                    Error::Usage("a rank's step wrote records for a box that is not there".into())
                })?;
            match filled[rank] {
                false => std::mem::swap(&mut self.outgoing[rank], list),
                true => self.outgoing[rank].extend_from_slice(list),
            }
            filled[rank] = true;
        }
        self.layer = layer;
        (self.outgoing.iter_mut().zip(&filled))
            .filter(|(_, filled)| !**filled)
            .for_each(|(message, _)| message.clear());
        let mut received = std::mem::take(&mut self.received);
        comm.exchange_into(&mut self.outgoing, &mut received)?;
        if received
            .iter()
            .any(|m| !m.len().is_multiple_of(size_of::<LayerRecord>()))
        {
            return Err(Error::Usage("a rank's message ends inside a sphere".into()));
        }
        let placing = bounds(grid, me, halo);
        let placed = self.resident()?.place_layer(&placing, &received)?;

        // The records of spheres the step does not hold, by whole-run id.
        let record = |at: u32| -> Result<LayerRecord> {
            let mut at = at as usize * size_of::<LayerRecord>();
            for message in &received {
                if at < message.len() {
                    let bytes = &message[at..at + size_of::<LayerRecord>()];
                    return Ok(bytemuck::pod_read_unaligned(bytes));
                }
                at -= message.len();
            }
            Err(Error::Usage(
                "a rank's step listed a record it was not sent".into(),
            ))
        };
        let mut coming: Vec<LayerRecord> = placed
            .coming
            .iter()
            .map(|&at| record(at))
            .collect::<Result<_>>()?;
        coming.sort_unstable_by_key(|r| r.whole);
        self.received = received;
        let arriving: Vec<Arriving> = coming.iter().map(arriving_of).collect();
        let mut leaving: Vec<u32> = placed.leaving.iter().map(|&[row, _, _]| row).collect();
        leaving.sort_unstable();

        // Where some rank's step has no room, every rank opens its step again (they exchange
        // alike), from its own spheres as the next round has them.
        let fits = self.resident()?.fits(leaving.len(), &arriving);
        let everywhere = comm.exchange(vec![vec![fits as u8]; comm.size()])?;
        if !(fits && everywhere.iter().all(|m| m.iter().all(|&b| b == 1))) {
            let gone: FxHashSet<u32> = placed.leaving.iter().map(|&[_, k, _]| k).collect();
            let mut own = self.own_ids(&gone)?;
            let given: FxHashMap<u32, SphereRecord> = (coming.iter())
                .filter(|r| placing.owns(head(r.pos), r.lo))
                .map(|r| (r.whole, record_of(r)))
                .collect();
            own.extend(given.keys());
            let settled = Some(self.held_of(own, &given)?);
            return Ok(Exchanged {
                touching,
                settled,
                read_ms,
            });
        }
        let first = self.resident()?.update(&leaving, &arriving)?;

        let mut forget = Vec::with_capacity(placed.leaving.len());
        for &[_, k, was_own] in &placed.leaving {
            let k = k as usize;
            forget.push(self.global[k]);
            self.global[k] = GONE;
            self.owned -= was_own as usize;
        }
        self.held -= placed.leaving.len();
        self.owned = self.owned + placed.made_own as usize - placed.made_ghosts as usize;
        // The step numbers the spheres it appends after every one it was given.
        if first as usize != self.global.len() {
            return Err(Error::Usage(
                "a rank's step numbered the spheres it took other than the rank did".into(),
            ));
        }
        let names: Vec<Named> = (first..)
            .zip(&coming)
            .map(|(k, r)| Named {
                stable: k,
                whole: r.whole,
                own: placing.owns(head(r.pos), r.lo),
            })
            .collect();
        for n in &names {
            self.global.push(n.whole);
            self.owned += n.own as usize;
        }
        self.held += names.len();
        let step = self.resident()?;
        step.forget(&forget)?;
        step.name(&names)?;
        Ok(Exchanged {
            touching,
            settled: None,
            read_ms,
        })
    }

    /// The own spheres' contacts with any sphere, summed (each contact of two own spheres
    /// counted by both): as the step's history holds them where it keeps one, else found on
    /// the host from every row read back.
    fn own_pair_ends(&mut self, mode: ProxyMode) -> Result<u64> {
        if let Some(counts) = self.resident()?.sphere_contacts()? {
            let own = self.own_places()?;
            return Ok(own.iter().map(|&(at, _)| counts[at] as u64).sum());
        }
        let rows = self.resident()?.rows()?;
        let marks = self.resident()?.own_marks()?;
        let own_rows: Vec<usize> = (0..rows.ids.len())
            .into_par_iter()
            .filter(|&r| marks.get(rows.ids[r] as usize) == Some(&1))
            .collect();
        own_pair_ends(&spheres_of(&rows), &own_rows, mode)
    }
}

/// Where rank `me`'s box of `grid` and its halo `halo` lie, in `f32` ([`LayerBounds`]): the
/// faces rounded to `f32` (alike on both sides of a face), the halo widened a little so that the
/// `f32` centres miss no sphere within it.
fn bounds(grid: &Grid, me: usize, halo: f64) -> LayerBounds {
    let (lo, hi) = grid.bounds_of(me);
    let wide = |x: f64| halo + 1e-5 * (x.abs() + halo);
    let moved = |x: f64, by: f64| match x.is_finite() {
        true => (x + by * wide(x)) as f32,
        false => x as f32,
    };
    LayerBounds {
        near: (lo.map(|x| moved(x, 1.0)), hi.map(|x| moved(x, -1.0))),
        own: (lo.map(|x| x as f32), hi.map(|x| x as f32)),
        keep: (lo.map(|x| moved(x, -1.0)), hi.map(|x| moved(x, 1.0))),
        ways: std::array::from_fn(|d| {
            d != direction([0; 3]) && grid.neighbour(me, way(d)).is_some()
        }),
    }
}

/// The direction of index `d` ([`direction`]).
fn way(d: usize) -> [i32; 3] {
    [d % 3, d / 3 % 3, d / 9].map(|i| i as i32 - 1)
}

/// The first three of four.
fn head(v: [f32; 4]) -> [f32; 3] {
    [v[0], v[1], v[2]]
}

/// The sphere of the record `r`.
fn record_of(r: &LayerRecord) -> SphereRecord {
    SphereRecord {
        id: r.whole,
        material: r.omega[3] as u32,
        radius: r.pos[3],
        position: head(r.pos),
        residual: r.lo,
        velocity: r.vel,
        spin: head(r.omega),
        contacts: 0,
        loads: 0,
    }
}

/// The sphere of the record `r` as a step appends it.
fn arriving_of(r: &LayerRecord) -> Arriving {
    Arriving {
        sphere: NewSphere {
            centre: head(r.pos),
            velocity: r.vel,
            radius: r.pos[3],
            material: r.omega[3] as u8,
        },
        residual: r.lo,
        spin: head(r.omega),
    }
}

/// The place in the step (the step's input order, `ids` its whole-run ids) of each whole-run
/// id up to the largest of `ids` and `also` ([`GONE`]: none).
fn place_by_id(ids: &[u32], also: &[u32]) -> Vec<u32> {
    let top = ids.iter().chain(also).max().map_or(0, |&g| g as usize + 1);
    let mut place = vec![GONE; top];
    ids.iter()
        .zip(0..)
        .for_each(|(&g, at)| place[g as usize] = at);
    place
}

/// The rows' spheres (centres and radii), for finding their contacts.
fn spheres_of(rows: &DeviceRows) -> Particles {
    Particles {
        positions: rows.pos.iter().map(|p| [p[0], p[1], p[2]]).collect(),
        radii: rows.pos.iter().map(|p| p[3]).collect(),
        ..Particles::default()
    }
}
