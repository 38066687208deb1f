//! The cpu backend's DEM step: the sorted proxy grid of [`crate::engines::cpu`], re-binned every
//! step, and a full-neighbourhood gather in which every sphere sums the forces of its own
//! contacts. Each pair is computed from both sides (twice the narrow phase of a one-sided
//! search) but no sphere is written by two threads: no atomics, no locks, and a force sum whose
//! order depends only on the state, so a run is bit-for-bit reproducible (and resumable) on any
//! number of threads.

use super::grid::SortedGrid;
use super::query::gather;
use crate::dem::model::{StepParams, contact_force, integrate, mass, wall_force};
use crate::dem::stepper::{Advance, Clock, StageTimes, Stepper};
use crate::error::{Result, try_vec};
use crate::particles::Particles;
use crate::proxy::ProxyMode;
use rayon::prelude::*;
use std::time::Instant;

/// The cpu DEM step.
pub struct CpuStepper {
    particles: Particles,
    params: StepParams,
    masses: Vec<f32>,
    cell_size: f32,
    /// Region the grid covers: the box and a margin of one cell.
    region: ([f32; 3], [f32; 3]),
    grid: SortedGrid,
    /// Force and contact count of each sorted sphere.
    sorted_forces: Vec<([f32; 3], u32)>,
    /// Force of each sphere, in input order.
    forces: Vec<[f32; 3]>,
}

impl CpuStepper {
    /// A stepper over `particles` (validated by the caller).
    pub fn new(mut particles: Particles, params: StepParams, mode: ProxyMode) -> Result<Self> {
        particles.separate_coincident()?;
        let (_, r_max) = particles.radius_range();
        let cell_size = mode.cell_size(r_max);
        let margin = cell_size;
        let region = (
            params.box_lo.map(|x| x - margin),
            params.box_hi.map(|x| x + margin),
        );
        let n = particles.len();
        let mut masses = try_vec(n, || format!("the masses of {n} spheres"))?;
        masses.extend(particles.radii.iter().map(|&r| mass(params.density, r)));
        Ok(Self {
            masses,
            cell_size,
            region,
            grid: SortedGrid::default(),
            sorted_forces: Vec::new(),
            forces: Vec::new(),
            params,
            particles,
        })
    }

    /// Sums every sorted sphere's contact forces; returns the number of touching pairs.
    fn resolve_contacts(&mut self) -> u64 {
        let grid = &self.grid;
        let (velocities, masses, p) = (&self.particles.velocities, &self.masses, &self.params);
        self.sorted_forces.resize(grid.keys.len(), ([0.0; 3], 0));
        gather(grid, &mut self.sorted_forces, |at, runs| {
            let s = grid.spheres[at];
            let i = grid.ids[at] as usize;
            let (c_i, v_i, m_i) = ([s[0], s[1], s[2]], velocities[i], masses[i]);
            let mut total = [0.0f32; 3];
            let mut touching = 0;
            for run in runs {
                for q in run.clone() {
                    // Cheap rejection first: most candidates do not touch.
                    let t = grid.spheres[q];
                    let (dx, dy, dz) = (t[0] - s[0], t[1] - s[1], t[2] - s[2]);
                    let reach = s[3] + t[3];
                    if dx * dx + dy * dy + dz * dz > reach * reach || q == at {
                        continue;
                    }
                    let j = grid.ids[q] as usize;
                    let c_j = [t[0], t[1], t[2]];
                    if let Some(f) =
                        contact_force(p, c_i, v_i, s[3], m_i, c_j, velocities[j], t[3], masses[j])
                    {
                        touching += 1;
                        for a in 0..3 {
                            total[a] += f[a];
                        }
                    }
                }
            }
            (total, touching)
        });
        let mut pairs_twice = 0u64;
        self.forces.resize(self.sorted_forces.len(), [0.0; 3]);
        for (&(f, k), &id) in self.sorted_forces.iter().zip(&grid.ids) {
            self.forces[id as usize] = f;
            pairs_twice += k as u64;
        }
        pairs_twice / 2
    }

    /// Walls, gravity and one semi-implicit Euler step for every sphere.
    fn integrate_all(&mut self) {
        let p = &self.params;
        let g = p.gravity_at(self.particles.step);
        let parts = &mut self.particles;
        let (forces, masses) = (&self.forces, &self.masses);
        parts
            .positions
            .par_iter_mut()
            .zip(parts.velocities.par_iter_mut())
            .zip(parts.radii.par_iter())
            .zip(forces.par_iter().zip(masses.par_iter()))
            .for_each(|(((c, v), &r), (f, &m))| {
                let w = wall_force(p, *c, *v, r, m);
                let total = [f[0] + w[0], f[1] + w[1], f[2] + w[2]];
                integrate(p.dt, c, v, total, m, g);
            });
        parts.step += 1;
    }
}

impl Stepper for CpuStepper {
    fn describe(&self) -> String {
        format!("cpu ({} threads)", rayon::current_num_threads())
    }

    fn advance(&mut self, steps: u32) -> Result<Advance> {
        let mut times = StageTimes::default();
        let mut contacts = 0;
        let ms = |t: Instant| t.elapsed().as_secs_f64() * 1e3;
        for _ in 0..steps {
            let t = Instant::now();
            let (lo, hi) = self.region;
            let parts = &self.particles;
            self.grid
                .bin_within(&parts.positions, &parts.radii, lo, hi, self.cell_size);
            times.build_ms += ms(t);
            let t = Instant::now();
            contacts = self.resolve_contacts();
            times.dcd_ms += ms(t);
            let t = Instant::now();
            self.integrate_all();
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
        Ok(self.particles.clone())
    }
}
