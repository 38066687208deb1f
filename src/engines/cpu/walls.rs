//! The cpu step's mesh-wall pass: each sphere's contacts with the mesh walls (`dem::walls`),
//! their force and torque on the sphere, the history they keep, and their reaction on each wall.
//! Runs over the spheres in input order before the sphere contacts; the sphere pass adds each
//! sphere's sum and keeps its entries. Per-wall loads are summed per fixed chunk of spheres and
//! the chunks in order, so they depend on the state alone, not on the threads.

use crate::dem::model::StepParams;
use crate::dem::model::contact::{
    Body, Contact, Kept, LoadedSprings, Springs, surface_contact, surface_holds,
};
use crate::dem::walls::{Pose, Touches, WallLoad, WallSet, mesh_partner, touches};
use crate::error::{Error, Result, try_resize};
use crate::particles::{HistoryEntry, LoadEntry, LoadedEntry, Particles};
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
    /// `slots` entries per sphere, input order (where contacts keep Mindlin's springs).
    entries: Vec<HistoryEntry>,
    /// `slots` entries with their load histories per sphere, input order (where contacts keep
    /// those of the Mindlin–Deresiewicz model).
    loaded: Vec<LoadedEntry>,
    /// Per wall, of the last step.
    loads: Vec<WallLoad>,
    /// The spheres whose reactions [`loads`](Self::loads) sums (`None`: every sphere).
    counted: Option<Vec<bool>>,
}

impl MeshPass {
    pub fn new(walls: WallSet) -> Self {
        Self {
            loads: vec![WallLoad::default(); walls.meshes.len()],
            walls,
            slots: FIRST_SLOTS,
            sums: Vec::new(),
            entries: Vec::new(),
            loaded: Vec::new(),
            counted: None,
        }
    }

    /// Sums into [`loads`](Self::loads) the reactions of the spheres `counted` marks only
    /// (`None`: of every sphere), from the next step on.
    pub fn count_loads_of(&mut self, counted: Option<Vec<bool>>) {
        self.counted = counted;
    }

    pub fn walls(&self) -> &WallSet {
        &self.walls
    }

    /// The loads on each wall in the last step.
    pub fn loads(&self) -> &[WallLoad] {
        &self.loads
    }

    /// Sphere `i`'s sum and the history entries it keeps: those of Mindlin's springs, or
    /// those with load histories (the other slice is empty).
    #[inline(always)]
    pub fn of(&self, i: usize) -> (MeshSum, &[HistoryEntry], &[LoadedEntry]) {
        let s = self.sums[i];
        let at = i * self.slots;
        let held = at..at + s.held as usize;
        match self.loaded.is_empty() {
            true => (s, &self.entries[held], &[]),
            false => (s, &[], &self.loaded[held]),
        }
    }

    /// Calls `seen(w, contact, overlap)` for each contact of sphere `i` of `parts` (as `body`)
    /// with mesh wall `w` at `poses`, keeping `S`, as [`resolve`](Self::resolve) resolves it;
    /// `scratch` is the caller's, reused from sphere to sphere.
    pub fn visit<S: Kept>(
        &self,
        (p, parts): (&StepParams, &Particles),
        (i, body): (usize, &Body),
        poses: &[Pose],
        scratch: &mut (Touches, Vec<WallLoad>),
        seen: impl FnMut(usize, &Contact<S>, f32),
    ) {
        let kept = match p.friction.has_history() {
            true => (parts.history.of(i), parts.history.loads_of(i)),
            false => (&[][..], &[][..]),
        };
        let (touched, loads) = scratch;
        loads.resize(self.walls.meshes.len(), WallLoad::default());
        let walls = (&self.walls, poses);
        sphere::<S>(p, walls, body, kept, &mut [], loads, touched, seen);
    }

    /// Resolves every sphere's mesh contacts in the state of `parts` (before the step).
    pub fn resolve(&mut self, p: &StepParams, parts: &Particles, masses: &[f32]) -> Result<()> {
        match p.friction.keeps_load() {
            true => {
                self.entries = Vec::new();
                self.resolve_kept::<LoadedSprings>(p, parts, masses, |pass| &mut pass.loaded)
            }
            false => {
                self.loaded = Vec::new();
                self.resolve_kept::<Springs>(p, parts, masses, |pass| &mut pass.entries)
            }
        }
    }

    /// [`resolve`](Self::resolve) with contacts keeping `S`, in the entries `side` picks.
    fn resolve_kept<S: Kept>(
        &mut self,
        p: &StepParams,
        parts: &Particles,
        masses: &[f32],
        side: impl Fn(&mut Self) -> &mut Vec<S::Slot>,
    ) -> Result<()> {
        let n = parts.len();
        let t = parts.step as f64 * p.dt as f64;
        let poses = self.walls.poses_at(t);
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
            // Taken out while the pass writes it, beside the walls and sums it reads.
            let mut held_entries = std::mem::take(side(self));
            held_entries.clear();
            try_resize(&mut held_entries, entries, S::Slot::default(), of_n)?;
            let (walls, counted) = (&self.walls, &self.counted);
            let chunks: Vec<Vec<WallLoad>> = self
                .sums
                .par_chunks_mut(CHUNK)
                .zip(held_entries.par_chunks_mut(CHUNK * slots))
                .enumerate()
                .map(|(k, (sums, entries))| {
                    let mut loads = vec![WallLoad::default(); walls.meshes.len()];
                    let mut uncounted = loads.clone();
                    let mut scratch = Touches::default();
                    for (j, sum) in sums.iter_mut().enumerate() {
                        let i = k * CHUNK + j;
                        let held = &mut entries[j * slots..(j + 1) * slots];
                        let body = Body {
                            c: Vec3::from_array(parts.positions[i]),
                            v: Vec3::from_array(parts.velocities[i]),
                            w: Vec3::from_array(parts.angular_velocities[i]),
                            r: parts.radii[i],
                            m: masses[i],
                            material: parts.material(i),
                        };
                        let kept = match keeps {
                            true => (parts.history.of(i), parts.history.loads_of(i)),
                            false => (&[][..], &[][..]),
                        };
                        let into = match counted.as_ref().is_none_or(|c| c[i]) {
                            true => &mut loads,
                            false => &mut uncounted,
                        };
                        *sum = sphere::<S>(
                            p,
                            (walls, &poses),
                            &body,
                            kept,
                            held,
                            into,
                            &mut scratch,
                            |_, _, _| {},
                        );
                    }
                    loads
                })
                .collect();
            *side(self) = held_entries;
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
/// many as fit; `held` counts them all) and the reactions added to `loads`. `kept`: the entries
/// of the step before and their load histories (none where contacts keep none).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn sphere<S: Kept>(
    p: &StepParams,
    (walls, poses): (&WallSet, &[Pose]),
    b: &Body,
    kept: (&[HistoryEntry], &[LoadEntry]),
    held: &mut [S::Slot],
    loads: &mut [WallLoad],
    scratch: &mut Touches,
    mut seen: impl FnMut(usize, &Contact<S>, f32),
) -> MeshSum {
    let (kept, kept_loads) = kept;
    let keeps = p.friction.has_history();
    let turns = p.friction.turns();
    let mut sum = MeshSum::default();
    // How far past touching a cohesive contact may hold.
    let reach = match p.friction.cohesive {
        true => p.reach_margin(b.r),
        false => 0.0,
    };
    for (w, (wall, pose)) in walls.meshes.iter().zip(poses).enumerate() {
        touches(&wall.triangles, pose, b.c, (b.r, reach), scratch);
        if scratch.found.is_empty() {
            continue;
        }
        let partner = mesh_partner(w);
        let column = wall.column(&p.materials);
        // The k-th contact with this wall takes the k-th entry kept of it.
        let mut olds = (0..kept.len())
            .filter(|&k| kept[k].partner == partner)
            .peekable();
        let (mut force, mut torque) = (Vec3::ZERO, Vec3::ZERO);
        for t in &scratch.found {
            // Past touching, only a contact of the last step that still holds.
            let bonded = olds.peek().is_some();
            if t.overlap <= 0.0 && !(bonded && surface_holds(p, b, column, t.overlap)) {
                continue;
            }
            let old = match olds.next() {
                Some(k) => S::of_entry(&kept[k], kept_loads.get(k)),
                None => S::default(),
            };
            let v = pose.velocity_at(t.point);
            let c = surface_contact(p, b, t.normal, t.overlap, v, column, wall.friction, old);
            seen(w, &c, t.overlap);
            force += c.force;
            if turns {
                torque += c.torque;
            }
            if keeps {
                if let Some(slot) = held.get_mut(sum.held as usize) {
                    *slot = c.springs.slot(partner);
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
