//! The cpu step's mesh-wall pass: each sphere's contacts with the mesh walls (`dem::walls`),
//! their force and torque on the sphere, the history they keep, and their reaction on each wall.
//! Runs over the spheres in input order before the sphere contacts; the sphere pass adds each
//! sphere's sum and keeps its entries. Per-wall loads are summed per fixed chunk of spheres and
//! the chunks in order, so they depend on the state alone, not on the threads.

use super::dem::springs_of;
use super::query::chunks_or_none;
use crate::dem::model::StepParams;
use crate::dem::model::contact::{Body, Springs, surface_contact};
use crate::dem::walls::{Pose, Touches, WallLoad, WallSet, mesh_partner, touches};
use crate::error::{Error, Result, try_resize};
use crate::particles::{HistoryEntry, LoadEntry, Particles};
use glam::Vec3;
use rayon::prelude::*;

/// Spheres per chunk of the load sums.
const CHUNK: usize = 1024;

/// History slots per sphere for mesh contacts a run starts with (a sphere in a corner touches
/// three faces); more are added when a sphere needs them.
const FIRST_SLOTS: usize = 4;

/// What one sphere's mesh contacts sum to.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct MeshSum {
    /// Force on the sphere \[N\].
    pub force: Vec3,
    /// Torque on the sphere about its centre \[N·m\].
    pub torque: Vec3,
    /// Contacts with history (the first of its slots in use).
    pub held: u32,
}

/// The mesh walls and what the pass wrote in the last step.
pub(super) struct MeshPass {
    walls: WallSet,
    /// History slots per sphere.
    slots: usize,
    /// Per sphere, input order.
    sums: Vec<MeshSum>,
    /// `slots` entries per sphere, input order.
    entries: Vec<HistoryEntry>,
    /// Their load histories, beside them (Mindlin–Deresiewicz; empty otherwise).
    entry_loads: Vec<LoadEntry>,
    /// Per wall, of the last step.
    loads: Vec<WallLoad>,
}

impl MeshPass {
    pub fn new(walls: WallSet) -> Self {
        Self {
            loads: vec![WallLoad::default(); walls.meshes.len()],
            walls,
            slots: FIRST_SLOTS,
            sums: Vec::new(),
            entries: Vec::new(),
            entry_loads: Vec::new(),
        }
    }

    pub fn walls(&self) -> &WallSet {
        &self.walls
    }

    /// The loads on each wall in the last step.
    pub fn loads(&self) -> &[WallLoad] {
        &self.loads
    }

    /// Sphere `i`'s sum, the history entries it keeps and their load histories (none where
    /// contacts keep none).
    #[inline(always)]
    pub fn of(&self, i: usize) -> (MeshSum, &[HistoryEntry], &[LoadEntry]) {
        let s = self.sums[i];
        let at = i * self.slots;
        let kept = at..at + s.held as usize;
        let loads = match self.entry_loads.is_empty() {
            true => &[][..],
            false => &self.entry_loads[kept.clone()],
        };
        (s, &self.entries[kept], loads)
    }

    /// Resolves every sphere's mesh contacts in the state of `parts` (before the step).
    pub fn resolve(&mut self, p: &StepParams, parts: &Particles, masses: &[f32]) -> Result<()> {
        let n = parts.len();
        let t = parts.step as f64 * p.dt as f64;
        let poses = self.walls.poses_at(t);
        let walls = &self.walls;
        let keeps = p.friction.has_history();
        let of_n = || format!("the mesh wall contacts of {n} spheres");
        try_resize(&mut self.sums, n, MeshSum::default(), of_n)?;
        loop {
            let slots = self.slots;
            let entries = n.checked_mul(slots).ok_or_else(|| Error::TooLarge {
                what: format!("mesh contact history slots of {n} spheres"),
                got: slots as u64,
                limit: (usize::MAX / n.max(1)) as u64,
            })?;
            self.entries.clear();
            try_resize(&mut self.entries, entries, HistoryEntry::default(), of_n)?;
            self.entry_loads.clear();
            if p.friction.keeps_load() {
                try_resize(&mut self.entry_loads, entries, LoadEntry::default(), of_n)?;
            }
            let chunks: Vec<Vec<WallLoad>> = self
                .sums
                .par_chunks_mut(CHUNK)
                .zip(self.entries.par_chunks_mut(CHUNK * slots))
                .zip(chunks_or_none(
                    &mut self.entry_loads,
                    CHUNK * slots,
                    n.div_ceil(CHUNK),
                ))
                .enumerate()
                .map(|(k, ((sums, entries), entry_loads))| {
                    let mut loads = vec![WallLoad::default(); walls.meshes.len()];
                    let mut scratch = Touches::default();
                    for (j, sum) in sums.iter_mut().enumerate() {
                        let i = k * CHUNK + j;
                        let held = &mut entries[j * slots..(j + 1) * slots];
                        let held_loads = match entry_loads.is_empty() {
                            true => &mut [][..],
                            false => &mut entry_loads[j * slots..(j + 1) * slots],
                        };
                        let body = Body {
                            c: Vec3::from_array(parts.positions[i]),
                            v: Vec3::from_array(parts.velocities[i]),
                            w: Vec3::from_array(parts.angular_velocities[i]),
                            r: parts.radii[i],
                            m: masses[i],
                        };
                        let kept = match keeps {
                            true => (parts.history.of(i), parts.history.loads_of(i)),
                            false => (&[][..], &[][..]),
                        };
                        *sum = sphere(
                            p,
                            walls,
                            &poses,
                            &body,
                            kept,
                            (held, held_loads),
                            &mut loads,
                            &mut scratch,
                        );
                    }
                    loads
                })
                .collect();
            let most = self.sums.iter().map(|s| s.held).max().unwrap_or(0) as usize;
            if most <= slots {
                for load in &mut self.loads {
                    *load = WallLoad::default();
                }
                for chunk in &chunks {
                    for (load, part) in self.loads.iter_mut().zip(chunk) {
                        load.add(part);
                    }
                }
                return Ok(());
            }
            self.slots = most + most / 2;
        }
    }
}

/// One sphere's contacts with every mesh wall: the sum on it, its history entries in `held` (as
/// many as fit, with their load histories where that slice is not empty; the sum counts them
/// all) and the reactions added to `loads`. `kept`: the entries of the step before and their
/// load histories.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn sphere(
    p: &StepParams,
    walls: &WallSet,
    poses: &[Pose],
    b: &Body,
    kept: (&[HistoryEntry], &[LoadEntry]),
    held: (&mut [HistoryEntry], &mut [LoadEntry]),
    loads: &mut [WallLoad],
    scratch: &mut Touches,
) -> MeshSum {
    let (kept, kept_loads) = kept;
    let (held, held_loads) = held;
    let keeps = p.friction.has_history();
    let turns = p.friction.turns();
    let mut sum = MeshSum::default();
    for (w, (wall, pose)) in walls.meshes.iter().zip(poses).enumerate() {
        touches(&wall.triangles, pose, b.c, b.r, scratch);
        if scratch.found.is_empty() {
            continue;
        }
        let partner = mesh_partner(w);
        // The k-th contact with this wall takes the k-th entry kept of it.
        let mut olds = (0..kept.len()).filter(|&k| kept[k].partner == partner);
        let (mut force, mut torque) = (Vec3::ZERO, Vec3::ZERO);
        for t in &scratch.found {
            let old = match olds.next() {
                Some(k) => springs_of(&kept[k], kept_loads.get(k)),
                None => Springs::default(),
            };
            let v = pose.velocity_at(t.point);
            let c = surface_contact(p, b, t.normal, t.overlap, v, wall.friction, old);
            force += c.force;
            if turns {
                torque += c.torque;
            }
            if keeps {
                if let Some(slot) = held.get_mut(sum.held as usize) {
                    *slot = HistoryEntry {
                        partner,
                        tangential: c.springs.tangential.to_array(),
                        rolling: c.springs.rolling.to_array(),
                    };
                }
                if let Some(load) = held_loads.get_mut(sum.held as usize) {
                    *load = LoadEntry {
                        reversal: c.springs.reversal.to_array(),
                        normal: c.springs.normal,
                    };
                }
                sum.held += 1;
            }
        }
        sum.force += force;
        sum.torque += torque;
        // The wall takes the opposite force and the opposite angular impulse about its centre.
        let on_wall = -force;
        let about = -((b.c - pose.centre).cross(force) + torque);
        let load = &mut loads[w];
        for a in 0..3 {
            load.force[a] += on_wall[a] as f64;
            load.torque[a] += about[a] as f64;
        }
    }
    sum
}
