//! The cpu backend's DEM step: the sorted proxy grid of [`crate::engines::cpu`], re-binned every
//! step, and a full-neighbourhood gather in which every sphere sums the forces of its own
//! contacts. Each pair is computed from both sides (twice the narrow phase of a one-sided
//! search) but no sphere is written by two threads: no atomics, no locks, and a force sum whose
//! order depends only on the state, so a run is bit-for-bit reproducible (and resumable) on any
//! number of threads.

use super::grid::SortedGrid;
use super::query::{gather, gather_with_side};
use super::walls::MeshPass;
use crate::dem::contacts::{ContactData, box_wall_id, mesh_wall_id};
use crate::dem::flow::{FlowCounts, FlowSet};
use crate::dem::model::contact::{
    Body, Kept, LoadedSprings, Springs, integrate_rotation, moment_of_inertia, pair_contact,
    wall_contacts,
};
use crate::dem::model::{StepParams, integrate};
use crate::dem::stepper::{Advance, Clock, ExternalLoads, Motion, StageTimes, Stepper};
use crate::dem::walls::{WallLoad, WallSet};
use crate::engines::common::rows;
use crate::engines::setup::DemSetup;
use crate::error::{Error, Result, try_resize, try_vec};
use crate::particles::{FIRST_MESH_WALL, FIRST_WALL, HistoryEntry, LoadedEntry, Particles, Slot};
use crate::proxy::ProxyMode;
use crate::spheres::center_bounds;
use glam::Vec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Instant;

/// History slots per sphere a frictional run starts with (a dense monodisperse packing has
/// 12 neighbours, plus up to 3 walls); more are added when a sphere needs them.
const FIRST_SLOTS: usize = 16;

/// What the contacts of one sphere sum to.
#[derive(Debug, Clone, Copy, Default)]
struct SphereSum {
    /// Force \[N\].
    force: Vec3,
    /// Torque about the centre \[N·m\].
    torque: Vec3,
    /// Touching spheres.
    touching: u32,
    /// Contacts with history (spheres and walls): how many slots the sphere needs.
    held: u32,
}

/// The cpu DEM step.
pub struct CpuStepper {
    particles: Particles,
    params: StepParams,
    /// Each sphere's mass as its contacts see it (a clump's component: its clump's).
    masses: Vec<f32>,
    /// The clump of each component (the first spheres; empty without clumps).
    owners: Vec<u32>,
    /// How far beyond touching a contact may act ([`StepParams::reach_margin`]): the cells
    /// grow by it.
    margin: f32,
    cell_size: f32,
    /// The box and a margin of one cell: the region the grid covers in a step where some
    /// centre is not finite or beyond the coordinate limit (centres outside it clamped into
    /// its border cells); else it covers the centres' bounds, so that its cells follow the
    /// spheres, not the box.
    region: ([f32; 3], [f32; 3]),
    grid: SortedGrid,
    /// Contact sums of each sorted sphere.
    sums: Vec<SphereSum>,
    /// History slots per sphere while resolving contacts (0 without history).
    slots: usize,
    /// The new contact history of each sorted sphere, `slots` entries each (where contacts
    /// keep Mindlin's springs).
    sorted_history: Vec<HistoryEntry>,
    /// The same with load histories (where contacts keep those of the Mindlin–Deresiewicz
    /// model).
    sorted_loaded: Vec<LoadedEntry>,
    /// The sorted position of each sphere (input order), for the gathers back into it.
    sorted_at: Vec<AtomicU32>,
    /// Force of each sphere, in input order.
    forces: Vec<[f32; 3]>,
    /// Torque of each sphere, in input order (empty when nothing turns).
    torques: Vec<[f32; 3]>,
    /// Whether the six walls of the box act.
    box_walls: bool,
    /// The mesh walls' pass (`None`: the box alone).
    mesh: Option<MeshPass>,
    /// Inflows and outflows (`None`: the spheres stay as they are).
    flow: Option<(FlowSet, FlowCounts)>,
    /// Loads added every step (`None`: none).
    external: Option<ExternalLoads>,
}

impl CpuStepper {
    /// The step of `setup` (its spheres validated by the caller).
    pub fn open(setup: DemSetup) -> Result<Self> {
        let DemSetup {
            particles,
            params,
            mode,
            walls,
        } = setup;
        Self::new(particles, params, mode)?.with_walls(walls)
    }

    /// A stepper over `particles` in the box (validated by the caller).
    fn new(mut particles: Particles, params: StepParams, mode: ProxyMode) -> Result<Self> {
        particles.place_clump_components()?;
        particles.separate_coincident()?;
        let (_, r_max) = particles.radius_range();
        let reach_margin = params.reach_margin(r_max);
        let cell_size = mode.cell_size(r_max) + reach_margin;
        let margin = cell_size;
        let region = (
            params.box_lo.map(|x| x - margin),
            params.box_hi.map(|x| x + margin),
        );
        let n = particles.len();
        if params.friction.has_history() && n > FIRST_WALL as usize {
            return Err(Error::TooLarge {
                what: "spheres of a run with contact history (ids above are the walls')".into(),
                got: n as u64,
                limit: FIRST_WALL as u64,
            });
        }
        let masses = rows::contact_masses(&particles, &params.materials)?;
        let owners = particles.clumps.owners();
        let slots = match params.friction.has_history() {
            true => FIRST_SLOTS.max(particles.history.most()),
            false => 0,
        };
        if params.friction.keeps_load() {
            particles.history.keep_loads()?;
        }
        Ok(Self {
            masses,
            owners,
            margin: reach_margin,
            cell_size,
            region,
            grid: SortedGrid::default(),
            sums: Vec::new(),
            slots,
            sorted_history: Vec::new(),
            sorted_loaded: Vec::new(),
            sorted_at: Vec::new(),
            forces: Vec::new(),
            torques: Vec::new(),
            box_walls: true,
            mesh: None,
            flow: None,
            external: None,
            params,
            particles,
        })
    }

    /// This stepper with spheres entering and leaving by `flow`; `mode` sizes the grid's
    /// cells for the largest sphere an inflow inserts.
    pub fn with_flow(mut self, flow: FlowSet, mode: ProxyMode) -> Self {
        if flow.is_empty() {
            return self;
        }
        let r_max = flow.largest_radius();
        let counted = flow.counted;
        self.flow = Some((flow, counted));
        self.sized_for(r_max, mode)
    }

    /// This stepper with its cells and its reach sized for spheres up to `r_max` as well as
    /// its own (`mode` sizes the cells): a part of a run stepped apart bins on the lattice of
    /// the whole, whose largest sphere it may not hold.
    pub(crate) fn sized_for(mut self, r_max: f32, mode: ProxyMode) -> Self {
        let (_, own) = self.particles.radius_range();
        let r_max = r_max.max(own);
        self.margin = self.params.reach_margin(r_max);
        let cell_size = mode.cell_size(r_max) + self.margin;
        if cell_size > self.cell_size {
            let margin = cell_size;
            self.cell_size = cell_size;
            self.region = (
                self.params.box_lo.map(|x| x - margin),
                self.params.box_hi.map(|x| x + margin),
            );
        }
        self
    }

    /// Removes and inserts spheres as the flows say, after a step.
    fn flow_after_step(&mut self) -> Result<()> {
        let Some((flow, counts)) = &mut self.flow else {
            return Ok(());
        };
        let (p, every) = (&self.params, flow.every(false));
        if !FlowSet::due_after(self.particles.step, every) {
            return Ok(());
        }
        let started = Instant::now();
        let changed = flow.apply(
            &mut self.particles,
            every,
            p.dt,
            &p.materials.densities,
            counts,
        )?;
        counts.events += 1;
        counts.event_ms += started.elapsed().as_secs_f64() * 1e3;
        if changed {
            self.masses = rows::contact_masses(&self.particles, &p.materials)?;
            self.owners = self.particles.clumps.owners();
        }
        Ok(())
    }

    /// This stepper with `walls` instead of the box alone.
    fn with_walls(mut self, walls: WallSet) -> Result<Self> {
        let n = self.particles.len();
        if !walls.meshes.is_empty()
            && self.params.friction.has_history()
            && n > FIRST_MESH_WALL as usize
        {
            return Err(Error::TooLarge {
                what: "spheres of a run with mesh walls and contact history (ids above are the \
                       walls')"
                    .into(),
                got: n as u64,
                limit: FIRST_MESH_WALL as u64,
            });
        }
        self.box_walls = walls.box_walls;
        self.mesh = (!walls.meshes.is_empty()).then(|| MeshPass::new(walls));
        Ok(self)
    }

    /// Sums into its [`wall_loads`](Stepper::wall_loads) the reactions of the spheres
    /// `counted` marks only (`None`: of every sphere), from the next step on: a decomposed
    /// run's own spheres, not their ghosts.
    pub(crate) fn count_wall_loads_of(&mut self, counted: Option<Vec<bool>>) {
        if let Some(mesh) = &mut self.mesh {
            mesh.count_loads_of(counted);
        }
    }

    /// Puts `particles` in place of its spheres, its cells, scratch and settings kept: as
    /// opening a stepper over them would (a decomposed run's own and ghost spheres of its
    /// next step), but that spheres sharing a centre are not moved apart (as a run's are only
    /// when it opens).
    pub(crate) fn replace_particles(&mut self, mut particles: Particles) -> Result<()> {
        self.masses = rows::contact_masses(&particles, &self.params.materials)?;
        self.owners = particles.clumps.owners();
        if self.params.friction.has_history() {
            self.slots = self.slots.max(FIRST_SLOTS.max(particles.history.most()));
        }
        if self.params.friction.keeps_load() {
            particles.history.keep_loads()?;
        }
        self.particles = particles;
        Ok(())
    }

    /// How many spheres each sphere touched in the last step, in input order (none before the
    /// first step).
    pub(crate) fn touching(&self) -> Vec<u32> {
        let mut out = vec![0; self.particles.len()];
        for (sum, &id) in self.sums.iter().zip(&self.grid.ids) {
            out[id as usize] = sum.touching;
        }
        out
    }

    /// Bins the spheres, on the lattice of cells anchored at the box's corner: a step's first
    /// phase. Each sphere meets its neighbours in an order that the spheres' places and
    /// their order in the input alone decide (not the bounds of the others), so a part of the
    /// spheres stepped apart, in the same order, sums each force as the whole does.
    fn bin(&mut self) -> Result<()> {
        let parts = &self.particles;
        let bounds = match center_bounds(&parts.positions) {
            Ok(Some(bounds)) => bounds,
            _ => self.region,
        };
        let anchor = self.params.box_lo.map(f64::from);
        self.grid.bin_within(
            &parts.positions,
            &parts.radii,
            bounds,
            anchor,
            self.cell_size,
        )
    }

    /// Resolves the spheres' mesh-wall contacts, before their other contacts.
    fn resolve_mesh(&mut self) -> Result<()> {
        match &mut self.mesh {
            Some(mesh) => mesh.resolve(&self.params, &self.particles, &self.masses),
            None => Ok(()),
        }
    }

    /// The contacts of the state now, as the next step resolves them (the state is left as it
    /// is, but for its contact history: this step's, as a step would leave it).
    pub fn contact_data(&mut self) -> Result<ContactData> {
        let n = self.particles.len();
        self.bin()?;
        self.resolve_mesh()?;
        let mut data = match (
            self.params.friction.has_history(),
            self.params.friction.keeps_load(),
        ) {
            (false, _) | (true, false) => self.contacts_keeping::<Springs>()?,
            (true, true) => self.contacts_keeping::<LoadedSprings>()?,
        };
        self.resolve_contacts()?;
        data.forces = self.forces.clone();
        data.torques = match self.torques.len() {
            0 => vec![[0.0; 3]; n],
            _ => self.torques.clone(),
        };
        Ok(data)
    }

    /// [`contact_data`](Self::contact_data)'s contacts, with the springs `S` (of the binned
    /// state, its mesh contacts resolved).
    fn contacts_keeping<S: Kept>(&self) -> Result<ContactData> {
        let n = self.grid.keys.len();
        let pass = ContactPass {
            grid: &self.grid,
            params: &self.params,
            particles: &self.particles,
            masses: &self.masses,
            owners: &self.owners,
            box_walls: self.box_walls,
            mesh: self.mesh.as_ref(),
            margin: self.margin,
        };
        let poses = self.mesh.as_ref().map(|m| {
            let t = self.particles.step as f64 * self.params.dt as f64;
            m.walls().poses_at(t)
        });
        let mut found: Vec<ContactData> = Vec::new();
        found.try_reserve_exact(n).map_err(|_| Error::OutOfMemory {
            what: format!("the contacts of {n} spheres"),
            bytes: (n * std::mem::size_of::<ContactData>()) as u64,
        })?;
        found.resize_with(n, ContactData::default);
        gather(&self.grid, &mut found, |at, runs| {
            let i = self.grid.ids[at] as usize;
            let mut data = ContactData::default();
            let mut record = |partner: i64, normal: Vec3, tangential: Vec3, overlap: f32| {
                // Each pair once, from its lower index's side.
                if partner < 0 || partner > i as i64 {
                    data.push(
                        [i as i64, partner],
                        normal.into(),
                        tangential.into(),
                        overlap,
                    );
                }
            };
            pass.sphere::<S>(at, runs, &mut [], &mut record);
            if let (Some(mesh), Some(poses)) = (&self.mesh, &poses) {
                let body = pass.body(at);
                let mut scratch = Default::default();
                let state = (pass.params, pass.particles);
                mesh.visit::<S>(state, (i, &body), poses, &mut scratch, |w, c, overlap| {
                    let partner = mesh_wall_id(w);
                    record(partner, c.normal, c.force - c.normal, overlap)
                });
            }
            data
        });
        // In input order of the first partner.
        let mut sorted_at = vec![0; n];
        for (at, &id) in self.grid.ids.iter().enumerate() {
            sorted_at[id as usize] = at;
        }
        let mut all = ContactData::default();
        for at in sorted_at {
            let data = std::mem::take(&mut found[at]);
            all.pairs.extend(data.pairs);
            all.normal_force.extend(data.normal_force);
            all.tangential_force.extend(data.tangential_force);
            all.overlap.extend(data.overlap);
        }
        Ok(all)
    }

    /// Sums every sorted sphere's contact forces and torques and writes the new contact
    /// history; returns the number of touching pairs. When a sphere has more contacts with
    /// history than there are slots, grows the slots and resolves the step again (the old
    /// history is only read, so the redo sees the same state).
    fn resolve_contacts(&mut self) -> Result<u64> {
        let n = self.grid.keys.len();
        let of_n = || format!("the contact sums of {n} spheres");
        try_resize(&mut self.sums, n, SphereSum::default(), of_n)?;
        let pass = ContactPass {
            grid: &self.grid,
            params: &self.params,
            particles: &self.particles,
            masses: &self.masses,
            owners: &self.owners,
            box_walls: self.box_walls,
            mesh: self.mesh.as_ref(),
            margin: self.margin,
        };
        let (grid, sums, slots) = (&self.grid, &mut self.sums, &mut self.slots);
        if !self.params.friction.has_history() {
            gather(grid, sums, |at, runs| {
                pass.sphere::<Springs>(at, runs, &mut [], |_, _, _, _| {})
            });
        } else if self.params.friction.keeps_load() {
            let side = &mut self.sorted_loaded;
            resolve_kept::<LoadedSprings>(&pass, grid, sums, side, slots)?;
        } else {
            let side = &mut self.sorted_history;
            resolve_kept::<Springs>(&pass, grid, sums, side, slots)?;
        }
        // Each sphere's sorted position, so that what the pass found is gathered back into
        // input order in parallel.
        if self.sorted_at.len() < n {
            let more = n - self.sorted_at.len();
            self.sorted_at
                .try_reserve_exact(more)
                .map_err(|_| Error::OutOfMemory {
                    what: of_n(),
                    bytes: (n * std::mem::size_of::<AtomicU32>()) as u64,
                })?;
        }
        self.sorted_at.resize_with(n, || AtomicU32::new(0));
        let sorted_at = &self.sorted_at;
        self.grid
            .ids
            .par_iter()
            .enumerate()
            .for_each(|(p, &id)| sorted_at[id as usize].store(p as u32, Ordering::Relaxed));
        let at = |i: usize| sorted_at[i].load(Ordering::Relaxed) as usize;
        let sums = &self.sums;
        if self.params.friction.has_history() {
            let mut counts = try_vec(n, of_n)?;
            counts.par_extend(sums.par_iter().map(|s| s.held));
            let history = &mut self.particles.history;
            match self.params.friction.keeps_load() {
                true => history.gather_from(at, self.slots, &counts, &self.sorted_loaded)?,
                false => history.gather_from(at, self.slots, &counts, &self.sorted_history)?,
            }
        }
        try_resize(&mut self.forces, n, [0.0; 3], of_n)?;
        self.forces
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, f)| *f = sums[at(i)].force.to_array());
        let turns = self.params.friction.turns();
        try_resize(&mut self.torques, if turns { n } else { 0 }, [0.0; 3], of_n)?;
        self.torques
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, t)| *t = sums[at(i)].torque.to_array());
        let pairs_twice: u64 = sums.par_iter().map(|s| s.touching as u64).sum();
        Ok(pairs_twice / 2)
    }

    /// Gravity and one semi-implicit Euler step for every sphere (positions, and angular
    /// velocities where contacts exert torques).
    fn integrate_all(&mut self) -> Result<()> {
        let p = &self.params;
        let g = p.gravity_at(self.particles.step);
        let parts = &mut self.particles;
        // Inserted spheres arrive with a residual of 0 (a run may start with none).
        parts.fill_residuals()?;
        let (forces, masses) = (&mut self.forces, &self.masses);
        let torques = &mut self.torques;
        if let Some(loads) = &self.external {
            // Contacts first, then the load: the sums of the GPU integrations.
            let add = |rows: &mut [[f32; 3]], of: &(dyn Fn(usize) -> [f32; 3] + Sync)| {
                rows.par_iter_mut().enumerate().for_each(|(i, f)| {
                    *f = (Vec3::from_array(*f) + Vec3::from_array(of(i))).to_array()
                })
            };
            add(forces, &|i| loads.force(i));
            add(torques, &|i| loads.torque(i));
        }
        parts
            .positions
            .par_iter_mut()
            .zip(parts.position_residuals.par_iter_mut())
            .zip(parts.velocities.par_iter_mut())
            .zip(forces.par_iter().zip(masses.par_iter()))
            .for_each(|((c, v), (&f, &m))| integrate(p.dt, c, v, f, m, g));
        if p.friction.turns() {
            parts
                .angular_velocities
                .par_iter_mut()
                .zip(&*torques)
                .zip(parts.radii.par_iter().zip(masses.par_iter()))
                .for_each(|((w, t), (&r, &m))| {
                    integrate_rotation(p.dt, w, Vec3::from_array(*t), moment_of_inertia(m, r))
                });
        }
        if !parts.clumps.clumps.is_empty() {
            // The components move with their clumps (over what the loops above did to them).
            let of = |rows: &[[f32; 3]], k: usize| {
                rows.get(k)
                    .map_or(glam::DVec3::ZERO, |f| Vec3::from_array(*f).as_dvec3())
            };
            let gravity = Vec3::from_array(g).as_dvec3();
            let (forces, torques) = (&*forces, &*torques);
            let (force, torque) = (|k| of(forces, k), |k| of(torques, k));
            parts.clumps.advance_by(force, torque, gravity, p.dt as f64);
            parts.place_clump_components()?;
        }
        parts.step += 1;
        Ok(())
    }
}

/// What one sphere's contacts read: the grid, the parameters, the state before the step.
struct ContactPass<'a> {
    grid: &'a SortedGrid,
    params: &'a StepParams,
    particles: &'a Particles,
    masses: &'a [f32],
    /// The clump of each component (the first spheres).
    owners: &'a [u32],
    /// Whether the six walls of the box act.
    box_walls: bool,
    /// Each sphere's mesh-wall contacts, resolved before this pass.
    mesh: Option<&'a MeshPass>,
    /// How far beyond touching a contact may act ([`StepParams::reach_margin`]).
    margin: f32,
}

impl ContactPass<'_> {
    /// Whether spheres `i` and `j` are components of one clump: never a pair.
    #[inline(always)]
    fn one_clump(&self, i: usize, j: usize) -> bool {
        let o = self.owners;
        i < o.len() && j < o.len() && o[i] == o[j]
    }

    /// The sphere at sorted position `q` as the law takes it.
    #[inline(always)]
    fn body(&self, q: usize) -> Body {
        let (grid, parts) = (self.grid, self.particles);
        let s = grid.spheres[q];
        let id = grid.ids[q] as usize;
        Body {
            c: Vec3::new(s[0], s[1], s[2]),
            v: Vec3::from_array(parts.velocities[id]),
            w: Vec3::from_array(parts.angular_velocities[id]),
            r: s[3],
            m: self.masses[id],
            material: parts.material(id),
        }
    }

    /// The contacts of the sphere at sorted position `at` with the spheres of `runs` and the
    /// walls, keeping `S`; writes those with history to `held` (as many as fit) and counts them
    /// all. `seen(partner, normal, tangential, overlap)` receives the forces on the sphere of
    /// each contact with a sphere (its input index) or a box wall ([`box_wall_id`]).
    #[inline(always)]
    fn sphere<S: Kept>(
        &self,
        at: usize,
        runs: &[std::ops::Range<usize>; 9],
        held: &mut [S::Slot],
        mut seen: impl FnMut(i64, Vec3, Vec3, f32),
    ) -> SphereSum {
        let (grid, p, parts) = (self.grid, self.params, self.particles);
        let keeps = p.friction.has_history();
        let body = |q: usize| self.body(q);
        let s = grid.spheres[at];
        let i = grid.ids[at] as usize;
        let me = body(at);
        let kept = parts.history.of(i);
        let kept_loads = match <S::Slot as Slot>::LOADED {
            true => parts.history.loads_of(i),
            false => &[],
        };
        // The springs kept of a partner, and whether there were any (it touched at the last
        // step).
        let old = |partner: u32| -> (S, bool) {
            match kept.iter().position(|e| e.partner == partner) {
                Some(k) => (S::of_entry(&kept[k], kept_loads.get(k)), true),
                None => (S::default(), false),
            }
        };
        let cohesive = p.friction.cohesive;
        let mut count = 0u32;
        let mut keep = |partner: u32, springs: S| {
            if let Some(slot) = held.get_mut(count as usize) {
                *slot = springs.slot(partner);
            }
            count += 1;
        };
        let mut force = Vec3::ZERO;
        let mut torque = Vec3::ZERO;
        let mut touching = 0;
        for run in runs {
            for q in run.clone() {
                // Cheap rejection first: most candidates do not touch.
                let t = grid.spheres[q];
                let (dx, dy, dz) = (t[0] - s[0], t[1] - s[1], t[2] - s[2]);
                let reach = s[3] + t[3];
                let within = reach + self.margin;
                if dx * dx + dy * dy + dz * dz > within * within || q == at {
                    continue;
                }
                let j = grid.ids[q];
                if self.one_clump(i, j as usize) {
                    continue;
                }
                let (springs, bonded) = if keeps { old(j) } else { (S::default(), false) };
                if let Some(c) = pair_contact(p, &me, &body(q), springs, bonded && cohesive) {
                    let overlap = reach - (dx * dx + dy * dy + dz * dz).sqrt();
                    seen(j as i64, c.normal, c.force - c.normal, overlap);
                    touching += 1;
                    force += c.force;
                    torque += c.torque;
                    if keeps {
                        keep(j, c.springs);
                    }
                }
            }
        }
        if self.box_walls {
            let walls = wall_contacts(
                p,
                &me,
                |w| old(FIRST_WALL + w),
                |w, springs| keep(FIRST_WALL + w, springs),
                |w, normal, tangential, overlap| seen(box_wall_id(w), normal, tangential, overlap),
            );
            // The paper's law sums exactly as its GPU twins: pairs, then walls.
            force += walls.normal;
            if p.friction.turns() {
                force += walls.tangential;
                torque += walls.torque;
            }
        }
        if let Some(mesh) = self.mesh {
            let (sum, entries, loaded) = mesh.of(i);
            force += sum.force;
            torque += sum.torque;
            for e in entries {
                keep(e.partner, S::of_entry(e, None));
            }
            for e in loaded {
                keep(e.entry.partner, S::of_entry(&e.entry, Some(&e.load)));
            }
        }
        SphereSum {
            force,
            torque,
            touching,
            held: count,
        }
    }
}

/// The contact pass of a step whose contacts keep `S`: gathers every sorted sphere's contacts
/// into `sums` and their new history into `side` (`slots` entries a sphere), growing the slots
/// and resolving again while some sphere has more contacts than slots (the old history is only
/// read, so the redo sees the same state).
fn resolve_kept<S: Kept>(
    pass: &ContactPass,
    grid: &SortedGrid,
    sums: &mut [SphereSum],
    side: &mut Vec<S::Slot>,
    slots: &mut usize,
) -> Result<()> {
    let n = grid.keys.len();
    loop {
        let k = *slots;
        let entries = n.checked_mul(k).ok_or_else(|| Error::TooLarge {
            what: format!("contact history slots of {n} spheres"),
            got: k as u64,
            limit: (usize::MAX / n.max(1)) as u64,
        })?;
        side.clear();
        side.try_reserve(entries).map_err(|_| Error::OutOfMemory {
            what: format!("the contact history of {n} spheres ({k} contacts each)"),
            bytes: (entries * std::mem::size_of::<S::Slot>()) as u64,
        })?;
        side.resize(entries, S::Slot::default());
        gather_with_side(grid, sums, side, k, |at, runs, held| {
            pass.sphere::<S>(at, runs, held, |_, _, _, _| {})
        });
        let most = sums.iter().map(|s| s.held).max().unwrap_or(0) as usize;
        if most <= k {
            return Ok(());
        }
        // Room for this sphere and some more, rather than a redo per extra contact.
        *slots = most + most / 4;
    }
}

impl Stepper for CpuStepper {
    fn describe(&self) -> String {
        let threads = rayon::current_num_threads();
        match &self.mesh {
            None if self.box_walls => format!("cpu ({threads} threads)"),
            None => format!("cpu ({threads} threads, no walls)"),
            Some(mesh) => format!("cpu ({threads} threads, {})", mesh.walls().describe()),
        }
    }

    fn advance(&mut self, steps: u32) -> Result<Advance> {
        let mut times = StageTimes::default();
        let mut contacts = 0;
        let ms = |t: Instant| t.elapsed().as_secs_f64() * 1e3;
        for _ in 0..steps {
            let t = Instant::now();
            self.bin()?;
            times.build_ms += ms(t);
            let t = Instant::now();
            self.resolve_mesh()?;
            contacts = self.resolve_contacts()?;
            times.dcd_ms += ms(t);
            let t = Instant::now();
            self.integrate_all()?;
            self.flow_after_step()?;
            times.update_ms += ms(t);
        }
        self.particles.check_stable()?;
        Ok(Advance {
            steps,
            contacts,
            times,
            clock: Clock::Wall,
        })
    }

    fn particles(&mut self) -> Result<Particles> {
        self.particles.try_clone()
    }

    fn step(&self) -> u64 {
        self.particles.step
    }

    fn set_motion(&mut self, motion: &Motion<'_>) -> Result<()> {
        motion.check_clumps(&self.particles)?;
        motion.apply(&mut self.particles)
    }

    fn set_gravity(&mut self, gravity: [f32; 3]) -> Result<()> {
        self.params.gravity = gravity;
        Ok(())
    }

    fn set_external_loads(&mut self, loads: &ExternalLoads) -> Result<()> {
        loads.check(self.particles.len())?;
        if loads.turns() && !self.params.friction.turns() {
            return Err(rows::no_spin());
        }
        if self.flow.is_some() && !loads.is_empty() {
            return Err(rows::not_fixed());
        }
        self.external = (!loads.is_empty()).then(|| loads.clone());
        Ok(())
    }

    fn flow_counts(&self) -> Option<FlowCounts> {
        self.flow.as_ref().map(|(_, counts)| *counts)
    }

    fn wall_loads(&self) -> Vec<WallLoad> {
        self.mesh
            .as_ref()
            .map_or_else(Vec::new, |mesh| mesh.loads().to_vec())
    }
}
