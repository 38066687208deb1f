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
use super::record::{Held, SphereRecord, own_pair_ends, partners_by_id, put, read};
use crate::dem::flow::NewSphere;
use crate::engines::common::flow::{Arriving, DeviceFlow, DeviceRows, ResidentStep};
use crate::error::{Error, Result};
use crate::particles::Particles;
use crate::particles::position::join;
use crate::proxy::ProxyMode;
use rayon::prelude::*;
use rustc_hash::FxHashMap;

/// Marks a stable id whose sphere the step no longer holds.
const GONE: u32 = u32::MAX;

/// A rank's step on its device between rounds, and whose its spheres are.
pub(super) struct Resident {
    pub step: Box<dyn DeviceFlow>,
    /// The whole run's id of the sphere of each stable id of the step ([`GONE`]: none now).
    global: Vec<u32>,
    /// Whether the sphere of each stable id is this rank's own (else a ghost).
    own: Vec<bool>,
    /// The stable id of each sphere of the step, by its whole-run id.
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
    /// The time reading the step's rows back took \[ms\].
    pub read_ms: f64,
}

impl Resident {
    /// `step`, opened over the spheres of the whole run's ids `ids` (in its input order, its
    /// stable ids `0..`), of which those at the places `own_at` (ascending) are the rank's.
    pub fn new(step: Box<dyn DeviceFlow>, ids: &[u32], own_at: &[usize]) -> Self {
        let mut own = vec![false; ids.len()];
        own_at.iter().for_each(|&at| own[at] = true);
        Resident {
            step,
            stable_of: ids.iter().copied().zip(0..).collect(),
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

    /// The whole run's ids of the step's spheres, in its input order (ascending stable id).
    pub fn ids(&self) -> Vec<u32> {
        self.global.iter().copied().filter(|&g| g != GONE).collect()
    }

    /// The rank's own spheres.
    pub fn own_spheres(&self) -> usize {
        self.own.iter().filter(|&&own| own).count()
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
        let started = std::time::Instant::now();
        let mut rows = self.resident()?.rows()?;
        let read_ms = started.elapsed().as_secs_f64() * 1e3;
        let n = rows.ids.len();
        if n != self.stable_of.len() {
            return Err(Error::Usage(
                "a rank's step does not hold the spheres the rank gave it".into(),
            ));
        }
        let own = &self.own;
        let own_rows: Vec<usize> = (0..n)
            .into_par_iter()
            .filter(|&r| own[rows.ids[r] as usize])
            .collect();
        let touching = count
            .map(|mode| own_pair_ends(&spheres_of(&rows), &own_rows, mode))
            .transpose()?;
        let speed = |r: usize| glam::Vec4::from(rows.vel[r]).truncate().length() as f64;
        let fastest = own_rows
            .par_iter()
            .map(|&r| speed(r))
            .reduce(|| 0.0, f64::max);
        let halo = halo(fastest)?;

        // Each own sphere near a face goes to every other rank whose box is within the halo
        // of it; those deep in the box stay as they are.
        let near: Vec<(usize, Vec<usize>)> = own_rows
            .par_iter()
            .filter_map(|&r| {
                let x = exact(&rows, r);
                let alone = grid.alone_within(x, halo) == Some(me);
                (!alone).then(|| (r, grid.ranks_within(x, halo)))
            })
            .collect();
        let mut outgoing = vec![Vec::new(); comm.size()];
        let mut keep = vec![false; n];
        let mut own_next = vec![false; n];
        own_rows
            .iter()
            .for_each(|&r| (keep[r], own_next[r]) = (true, true));
        for (r, ranks) in near {
            let record = record_of_row(&rows, r, self.global[rows.ids[r] as usize]);
            keep[r] = ranks.contains(&me);
            own_next[r] = grid.owner(record.exact_position()) == me;
            for rank in ranks.into_iter().filter(|&rank| rank != me) {
                put(&mut outgoing[rank], &record, (&[], &[]));
            }
        }
        // Those sent here: states of spheres held (ghosts, or spheres moving in), written
        // into their rows, or new ones.
        let mut row_of = vec![GONE; self.global.len()];
        for (r, &k) in rows.ids.iter().enumerate() {
            row_of[k as usize] = r as u32;
        }
        let mut updated = Vec::new();
        let mut coming = Vec::new();
        for message in comm.exchange(outgoing)? {
            for h in read(&message)? {
                let s = h.sphere;
                match self.stable_of.get(&s.id) {
                    Some(&k) => {
                        let r = row_of[k as usize] as usize;
                        place_in_row(&mut rows, r, &s);
                        (keep[r], own_next[r]) = (true, grid.owner(s.exact_position()) == me);
                        updated.push(s);
                    }
                    None => coming.push(s),
                }
            }
        }
        coming.sort_unstable_by_key(|s| s.id);

        let mut leaving: Vec<u32> = (0..n).filter(|&r| !keep[r]).map(|r| rows.ids[r]).collect();
        leaving.sort_unstable();
        let arriving: Vec<Arriving> = coming
            .iter()
            .map(|s| Arriving {
                sphere: NewSphere {
                    centre: s.position,
                    velocity: s.velocity,
                    radius: s.radius,
                    material: s.material as u8,
                },
                residual: s.residual,
                spin: s.spin,
            })
            .collect();
        // Where some rank's step has no room, every rank opens its step again (they exchange
        // alike), from its own spheres as the next round has them.
        let fits = self.resident()?.fits(leaving.len(), &arriving);
        let everywhere = comm.exchange(vec![vec![fits as u8]; comm.size()])?;
        if !(fits && everywhere.iter().all(|m| m.iter().all(|&b| b == 1))) {
            let given: FxHashMap<u32, SphereRecord> = (updated.iter().chain(&coming))
                .map(|s| (s.id, *s))
                .collect();
            let own = (0..n)
                .filter(|&r| keep[r] && own_next[r])
                .map(|r| self.global[rows.ids[r] as usize])
                .chain(
                    coming
                        .iter()
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
        let first = self.resident()?.rewrite(&rows, &leaving, &arriving)?;

        for r in 0..n {
            let k = rows.ids[r] as usize;
            match keep[r] {
                true => self.own[k] = own_next[r],
                false => {
                    self.stable_of.remove(&self.global[k]);
                    (self.global[k], self.own[k]) = (GONE, false);
                }
            }
        }
        // The step numbers the spheres it appends after every one it was given.
        if first as usize != self.global.len() {
            return Err(Error::Usage(
                "a rank's step numbered the spheres it took other than the rank did".into(),
            ));
        }
        for (k, s) in (first..).zip(&coming) {
            self.global.push(s.id);
            self.own.push(grid.owner(s.exact_position()) == me);
            self.stable_of.insert(s.id, k);
        }
        Ok(Exchanged {
            touching,
            settled: None,
            read_ms,
        })
    }
}

/// Where the centre of row `r` is, in `f64`.
fn exact(rows: &DeviceRows, r: usize) -> [f64; 3] {
    std::array::from_fn(|a| join(rows.pos[r][a], rows.lo[r][a]))
}

/// Row `r` of `rows` as a record of the whole run's id `id`.
fn record_of_row(rows: &DeviceRows, r: usize, id: u32) -> SphereRecord {
    let triple = |v: &[f32; 4]| [v[0], v[1], v[2]];
    SphereRecord {
        id,
        material: rows.omega[r][3] as u32,
        radius: rows.pos[r][3],
        position: triple(&rows.pos[r]),
        residual: triple(&rows.lo[r]),
        velocity: triple(&rows.vel[r]),
        spin: triple(&rows.omega[r]),
        contacts: 0,
        loads: 0,
    }
}

/// Writes the state of `s` into row `r` (its radius, mass and material as they are).
fn place_in_row(rows: &mut DeviceRows, r: usize, s: &SphereRecord) {
    let put = |row: &mut [f32; 4], v: [f32; 3]| row[..3].copy_from_slice(&v);
    put(&mut rows.pos[r], s.position);
    put(&mut rows.lo[r], s.residual);
    put(&mut rows.vel[r], s.velocity);
    put(&mut rows.omega[r], s.spin);
}

/// The rows' spheres (centres and radii), for finding their contacts.
fn spheres_of(rows: &DeviceRows) -> Particles {
    Particles {
        positions: rows.pos.iter().map(|p| [p[0], p[1], p[2]]).collect(),
        radii: rows.pos.iter().map(|p| p[3]).collect(),
        ..Particles::default()
    }
}
