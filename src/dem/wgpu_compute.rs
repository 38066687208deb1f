//! The wgpu-compute backend's DEM step, resident on the GPU: per step a counting sort of the
//! spheres by cell (the backend's sorted proxy grid, re-binned every step), one pass that finds
//! every touching pair once and adds equal and opposite forces to both spheres (float atomics,
//! or compare-and-swap loops where the adapter has none), and one pass for walls, gravity and
//! integration (`wgsl/dem_step.wgsl`). Many steps go into one submission; the host reads back
//! only the contact count and timestamps per batch, and the particles when asked.
//!
//! The grid's layout (cell size, dense or hashed table over the centres' bounds) is re-derived
//! from a GPU reduction of the bounds every [`RELAYOUT_EVERY`] steps. Between, spheres that
//! leave the layout's region are clamped into its border cells: exact, only slower.
//! Float atomics add in no fixed order, so GPU runs are not bit-for-bit reproducible.

use super::model::{StepParams, mass};
use super::particles::Particles;
use super::stepper::{Advance, Clock, StageTimes, Stepper};
use crate::backend::wgpu_compute::{GridParams, grid_layout};
use crate::error::{Error, Result};
use crate::gpu::scan::{ExclusiveScan, PreparedScan};
use crate::gpu::{self, Gpu, Need};
use crate::proxy::ProxyMode;

const STEP_WGSL: &str = concat!(
    include_str!("../../wgsl/grid_params.wgsl"),
    include_str!("../../wgsl/dem_step.wgsl")
);
const FORCE_F32_WGSL: &str = include_str!("../../wgsl/dem_force_f32.wgsl");
const FORCE_CAS_WGSL: &str = include_str!("../../wgsl/dem_force_cas.wgsl");

/// Every WGSL module of the DEM step, by label, exactly as the device may get it.
pub fn shaders() -> [(&'static str, String); 2] {
    [
        ("dem_step_f32", format!("{STEP_WGSL}{FORCE_F32_WGSL}")),
        ("dem_step_cas", format!("{STEP_WGSL}{FORCE_CAS_WGSL}")),
    ]
}

/// Workgroup size of every kernel of the step (as in the shader).
const GROUP: u32 = 256;

/// Steps between two re-derivations of the grid layout.
pub const RELAYOUT_EVERY: u64 = 100;

/// Most steps recorded into one submission (and timed by one query set).
const MAX_BATCH: u32 = 200;

/// Keep in sync with `DemParams` in `wgsl/dem_step.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct DemParams {
    box_lo: [f32; 3],
    n: u32,
    box_hi: [f32; 3],
    _pad0: u32,
    gravity: [f32; 3],
    dt: f32,
    stiffness: f32,
    damping_ratio: f32,
    gravity_spin: f32,
    _pad1: u32,
}
const _: () = assert!(size_of::<DemParams>() == 64);

/// How forces are accumulated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ForceAtomics {
    /// Float atomics where the adapter has them, else compare-and-swap.
    Auto,
    /// Compare-and-swap loops on the bit patterns (any adapter).
    CompareExchange,
}

/// One set of the ping-ponged state, in sorted order.
struct StateSet {
    pos: wgpu::Buffer,
    vel: wgpu::Buffer,
    ids: wgpu::Buffer,
}

struct Pipelines {
    bin_count: wgpu::ComputePipeline,
    bin_scatter: wgpu::ComputePipeline,
    resolve: wgpu::ComputePipeline,
    integrate: wgpu::ComputePipeline,
    reduce_bounds: wgpu::ComputePipeline,
}

/// Bind groups of one parity (which state set is the source of the next binning).
struct Binds {
    bin_count: wgpu::BindGroup,
    bin_scatter: wgpu::BindGroup,
    resolve: wgpu::BindGroup,
    integrate: wgpu::BindGroup,
    reduce_bounds: wgpu::BindGroup,
}

/// Timestamps of up to [`MAX_BATCH`] steps: four per step (start, built, resolved, integrated).
struct StepTimer {
    queries: wgpu::QuerySet,
    resolved: wgpu::Buffer,
}

/// The wgpu-compute DEM step.
pub struct GridStepper {
    gpu: Gpu,
    pipelines: Pipelines,
    scan: ExclusiveScan,
    prepared: Option<PreparedScan>,
    n: u32,
    mode_cell: f64,
    params: StepParams,
    layout: GridParams,
    /// Step count at the last layout.
    laid_out_at: Option<u64>,
    step: u64,
    groups: (u32, u32),
    grid_uniform: wgpu::Buffer,
    dem_uniform: wgpu::Buffer,
    sets: [StateSet; 2],
    /// Which set the next step bins from.
    current: usize,
    keys_in: wgpu::Buffer,
    ranks: wgpu::Buffer,
    keys: wgpu::Buffer,
    cell_table: wgpu::Buffer,
    force: wgpu::Buffer,
    counters: wgpu::Buffer,
    bounds: wgpu::Buffer,
    clock: wgpu::Buffer,
    binds: Option<[Binds; 2]>,
    timer: Option<StepTimer>,
    atomics: &'static str,
}

impl GridStepper {
    /// Uploads `particles` to the best adapter with compute shaders.
    pub fn new(particles: Particles, params: StepParams, mode: ProxyMode) -> Result<Self> {
        Self::with_atomics(particles, params, mode, ForceAtomics::Auto)
    }

    /// As [`new`](Self::new), choosing how forces are accumulated.
    pub fn with_atomics(
        particles: Particles,
        params: StepParams,
        mode: ProxyMode,
        atomics: ForceAtomics,
    ) -> Result<Self> {
        let gpu = Gpu::open(Need::Compute)?;
        let n64 = particles.len() as u64;
        let max = (gpu
            .limits
            .max_storage_buffer_binding_size
            .min(gpu.limits.max_buffer_size)
            / 16)
            .min(u32::MAX as u64 / 4);
        if n64 > max {
            return Err(Error::TooLarge {
                what: format!("spheres for the wgpu-compute DEM on {}", gpu.info.name),
                got: n64,
                limit: max,
            });
        }
        let n = n64 as u32;
        let float_atomics = atomics == ForceAtomics::Auto
            && gpu
                .device
                .features()
                .contains(wgpu::Features::SHADER_FLOAT32_ATOMIC);
        let (atomics, force_wgsl) = if float_atomics {
            ("float atomics", FORCE_F32_WGSL)
        } else {
            ("compare-and-swap", FORCE_CAS_WGSL)
        };
        let module = gpu.module("mochi.dem.step", &format!("{STEP_WGSL}{force_wgsl}"));
        let pipeline = |entry: &str| gpu.pipeline(&format!("mochi.dem.{entry}"), &module, entry);
        let pipelines = Pipelines {
            bin_count: pipeline("bin_count"),
            bin_scatter: pipeline("bin_scatter"),
            resolve: pipeline("resolve"),
            integrate: pipeline("integrate"),
            reduce_bounds: pipeline("reduce_bounds"),
        };
        let (_, r_max) = particles.radius_range();
        let none = wgpu::BufferUsages::empty();
        let make = |label: &str, bytes: u64| gpu.storage(label, bytes, none);
        let stepper = gpu.checked("allocating the DEM buffers", || {
            let set = |k: usize| StateSet {
                pos: make(&format!("mochi.dem.pos{k}"), n64 * 16),
                vel: make(&format!("mochi.dem.vel{k}"), n64 * 16),
                ids: make(&format!("mochi.dem.ids{k}"), n64 * 4),
            };
            let timer = gpu
                .device
                .features()
                .contains(
                    wgpu::Features::TIMESTAMP_QUERY
                        | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS,
                )
                .then(|| StepTimer {
                    queries: gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                        label: Some("mochi.dem.timer"),
                        ty: wgpu::QueryType::Timestamp,
                        count: 4 * MAX_BATCH,
                    }),
                    resolved: gpu.storage(
                        "mochi.dem.timer.resolved",
                        4 * MAX_BATCH as u64 * 8,
                        wgpu::BufferUsages::QUERY_RESOLVE,
                    ),
                });
            GridStepper {
                scan: ExclusiveScan::new(&gpu),
                prepared: None,
                pipelines,
                n,
                mode_cell: mode.cell_size(r_max) as f64,
                params,
                layout: GridParams::default(),
                laid_out_at: None,
                step: particles.step,
                groups: gpu.grid(n, GROUP),
                grid_uniform: gpu.uniform("mochi.dem.grid", &GridParams::default()),
                dem_uniform: gpu.uniform("mochi.dem.params", &DemParams::default()),
                sets: [set(0), set(1)],
                current: 0,
                keys_in: make("mochi.dem.keys_in", n64 * 4),
                ranks: make("mochi.dem.ranks", n64 * 4),
                keys: make("mochi.dem.keys", n64 * 4),
                cell_table: make("mochi.dem.cells", 16),
                force: make("mochi.dem.force", n64 * 12),
                counters: make("mochi.dem.counters", 16),
                bounds: make("mochi.dem.bounds", 24),
                clock: make("mochi.dem.clock", 4),
                binds: None,
                timer,
                atomics,
                gpu: gpu.clone(),
            }
        })?;
        let mut stepper = stepper;
        stepper.upload(&particles)?;
        Ok(stepper)
    }

    /// Writes the particles (in input order) into the current set and the parameters.
    fn upload(&mut self, particles: &Particles) -> Result<()> {
        let density = self.params.density;
        let pos: Vec<[f32; 4]> = particles
            .positions
            .iter()
            .zip(&particles.radii)
            .map(|(c, &r)| [c[0], c[1], c[2], r])
            .collect();
        let vel: Vec<[f32; 4]> = particles
            .velocities
            .iter()
            .zip(&particles.radii)
            .map(|(v, &r)| [v[0], v[1], v[2], mass(density, r)])
            .collect();
        let ids: Vec<u32> = (0..self.n).collect();
        let p = &self.params;
        let dem = DemParams {
            box_lo: p.box_lo,
            n: self.n,
            box_hi: p.box_hi,
            gravity: p.gravity,
            dt: p.dt,
            stiffness: p.stiffness,
            damping_ratio: p.damping_ratio,
            gravity_spin: p.gravity_spin,
            ..DemParams::default()
        };
        let q = &self.gpu.queue;
        let set = &self.sets[self.current];
        q.write_buffer(&set.pos, 0, bytemuck::cast_slice(&pos));
        q.write_buffer(&set.vel, 0, bytemuck::cast_slice(&vel));
        q.write_buffer(&set.ids, 0, bytemuck::cast_slice(&ids));
        q.write_buffer(&self.dem_uniform, 0, bytemuck::bytes_of(&dem));
        q.write_buffer(&self.clock, 0, bytemuck::bytes_of(&(self.step as u32)));
        Ok(())
    }

    /// The centres' bounds now (a GPU reduction), or `None` for no spheres.
    fn bounds(&self) -> Result<Option<([f32; 3], [f32; 3])>> {
        if self.n == 0 {
            return Ok(None);
        }
        let empty: [u32; 6] = [u32::MAX, u32::MAX, u32::MAX, 0, 0, 0];
        let gpu = &self.gpu;
        gpu.queue
            .write_buffer(&self.bounds, 0, bytemuck::cast_slice(&empty));
        let binds = self.binds.as_ref().expect("laid out");
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        gpu.dispatch(
            &mut encoder,
            "mochi.dem.reduce_bounds",
            &self.pipelines.reduce_bounds,
            &binds[self.current].reduce_bounds,
            self.groups,
        );
        gpu.queue.submit([encoder.finish()]);
        let keys: Vec<u32> = gpu.read(&self.bounds, 6)?;
        let value = |k: u32| {
            f32::from_bits(if k & 0x8000_0000 != 0 {
                k & 0x7fff_ffff
            } else {
                !k
            })
        };
        let lo = [value(keys[0]), value(keys[1]), value(keys[2])];
        let hi = [value(keys[3]), value(keys[4]), value(keys[5])];
        if lo.iter().chain(&hi).any(|x| !x.is_finite()) {
            return Err(Error::Gpu(format!(
                "the simulation became unstable by step {}: a sphere has a non-finite position \
                 (try a smaller time step or a softer stiffness)",
                self.step
            )));
        }
        Ok(Some((lo, hi)))
    }

    /// Re-derives the grid layout from the current bounds (clipped to the box and a margin:
    /// walls keep the spheres in, so far-away outliers cannot stretch the grid).
    fn relayout(&mut self) -> Result<()> {
        if self.binds.is_none() {
            // Bounds need bind groups; a first layout over the box gives them.
            let (lo, hi) = (self.params.box_lo, self.params.box_hi);
            self.apply_layout(lo, hi)?;
        }
        let Some((lo, hi)) = self.bounds()? else {
            self.laid_out_at = Some(self.step);
            return Ok(());
        };
        let margin = self.mode_cell as f32;
        let lo: [f32; 3] = std::array::from_fn(|a| lo[a].max(self.params.box_lo[a] - margin));
        let hi: [f32; 3] =
            std::array::from_fn(|a| hi[a].min(self.params.box_hi[a] + margin).max(lo[a]));
        self.apply_layout(lo, hi)
    }

    fn apply_layout(&mut self, lo: [f32; 3], hi: [f32; 3]) -> Result<()> {
        let gpu = &self.gpu;
        let layout = GridParams {
            row: self.groups.0 * GROUP,
            ..grid_layout(
                &gpu.limits,
                lo,
                hi,
                self.n as u64,
                self.mode_cell,
                Some(&|_| true),
            )
        };
        let table_bytes = (layout.cells as u64 + 1) * 4;
        if self.cell_table.size() < table_bytes || self.binds.is_none() {
            self.cell_table = gpu.checked("allocating the DEM cell table", || {
                gpu.storage("mochi.dem.cells", table_bytes, wgpu::BufferUsages::empty())
            })?;
            self.binds = Some([self.make_binds(0), self.make_binds(1)]);
        }
        self.prepared = Some(
            self.scan
                .prepare(gpu, &self.cell_table, 0, layout.cells + 1),
        );
        gpu.queue
            .write_buffer(&self.grid_uniform, 0, bytemuck::bytes_of(&layout));
        self.layout = layout;
        self.laid_out_at = Some(self.step);
        Ok(())
    }

    /// Bind groups for binning from set `from` into the other.
    fn make_binds(&self, from: usize) -> Binds {
        let (a, b) = (&self.sets[from], &self.sets[1 - from]);
        let p = &self.pipelines;
        let gpu = &self.gpu;
        Binds {
            bin_count: gpu.bind(
                "mochi.dem.bin_count",
                &p.bin_count,
                &[
                    (0, &self.grid_uniform),
                    (2, &a.pos),
                    (5, &self.keys_in),
                    (6, &self.ranks),
                    (7, &self.cell_table),
                    (16, &self.clock),
                ],
            ),
            bin_scatter: gpu.bind(
                "mochi.dem.bin_scatter",
                &p.bin_scatter,
                &[
                    (0, &self.grid_uniform),
                    (2, &a.pos),
                    (3, &a.vel),
                    (4, &a.ids),
                    (5, &self.keys_in),
                    (6, &self.ranks),
                    (8, &self.cell_table),
                    (9, &self.keys),
                    (10, &b.pos),
                    (11, &b.vel),
                    (12, &b.ids),
                ],
            ),
            resolve: gpu.bind(
                "mochi.dem.resolve",
                &p.resolve,
                &[
                    (0, &self.grid_uniform),
                    (1, &self.dem_uniform),
                    (8, &self.cell_table),
                    (9, &self.keys),
                    (10, &b.pos),
                    (11, &b.vel),
                    (13, &self.force),
                    (14, &self.counters),
                ],
            ),
            integrate: gpu.bind(
                "mochi.dem.integrate",
                &p.integrate,
                &[
                    (0, &self.grid_uniform),
                    (1, &self.dem_uniform),
                    (10, &b.pos),
                    (11, &b.vel),
                    (13, &self.force),
                    (16, &self.clock),
                ],
            ),
            reduce_bounds: gpu.bind(
                "mochi.dem.reduce_bounds",
                &p.reduce_bounds,
                &[(0, &self.grid_uniform), (2, &a.pos), (15, &self.bounds)],
            ),
        }
    }

    /// Records `steps` steps (≤ [`MAX_BATCH`]) into one submission and waits for it.
    fn run_batch(&mut self, steps: u32) -> Result<(u64, Option<StageTimes>)> {
        let gpu = &self.gpu;
        let binds = self.binds.as_ref().expect("laid out");
        let prepared = self.prepared.as_ref().expect("laid out");
        let p = &self.pipelines;
        let table_bytes = (self.layout.cells as u64 + 1) * 4;
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        let mut current = self.current;
        for s in 0..steps {
            let b = &binds[current];
            let mark = |encoder: &mut wgpu::CommandEncoder, k: u32| {
                if let Some(t) = &self.timer {
                    encoder.write_timestamp(&t.queries, 4 * s + k);
                }
            };
            mark(&mut encoder, 0);
            encoder.clear_buffer(&self.cell_table, 0, Some(table_bytes));
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("mochi.dem.build"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(&p.bin_count);
                pass.set_bind_group(0, &b.bin_count, &[]);
                pass.dispatch_workgroups(self.groups.0, self.groups.1, 1);
                prepared.record(&mut pass);
                pass.set_pipeline(&p.bin_scatter);
                pass.set_bind_group(0, &b.bin_scatter, &[]);
                pass.dispatch_workgroups(self.groups.0, self.groups.1, 1);
            }
            mark(&mut encoder, 1);
            encoder.clear_buffer(&self.force, 0, None);
            encoder.clear_buffer(&self.counters, 0, None);
            gpu.dispatch(
                &mut encoder,
                "mochi.dem.resolve",
                &p.resolve,
                &b.resolve,
                self.groups,
            );
            mark(&mut encoder, 2);
            gpu.dispatch(
                &mut encoder,
                "mochi.dem.integrate",
                &p.integrate,
                &b.integrate,
                self.groups,
            );
            mark(&mut encoder, 3);
            current = 1 - current;
        }
        if let Some(t) = &self.timer {
            encoder.resolve_query_set(&t.queries, 0..4 * steps, &t.resolved, 0);
        }
        gpu.checked("running DEM steps", || gpu.queue.submit([encoder.finish()]))?;
        self.current = current;
        self.step += steps as u64;
        let contacts = gpu.read::<u32>(&self.counters, 1)?[0] as u64;
        let times = match &self.timer {
            None => None,
            Some(t) => {
                let ticks: Vec<u64> = gpu.read(&t.resolved, 4 * steps as usize)?;
                let period = gpu.queue.get_timestamp_period() as f64 * 1e-6;
                let span = |a: u64, b: u64| b.saturating_sub(a) as f64 * period;
                let mut times = StageTimes::default();
                for t in ticks.chunks_exact(4) {
                    times.build_ms += span(t[0], t[1]);
                    times.dcd_ms += span(t[1], t[2]);
                    times.update_ms += span(t[2], t[3]);
                }
                Some(times)
            }
        };
        Ok((contacts, times))
    }
}

impl Stepper for GridStepper {
    fn describe(&self) -> String {
        format!(
            "wgpu-compute ({}; {})",
            gpu::describe(&self.gpu.info),
            self.atomics
        )
    }

    fn advance(&mut self, steps: u32) -> Result<Advance> {
        let mut times = StageTimes::default();
        let mut timed = self.timer.is_some();
        let mut contacts = 0;
        let mut left = steps;
        if self.n == 0 {
            self.step += steps as u64;
            left = 0;
        }
        while left > 0 {
            let due = match self.laid_out_at {
                None => true,
                Some(at) => self.step >= at + RELAYOUT_EVERY,
            };
            if due {
                self.relayout()?;
            }
            let until_relayout = self.laid_out_at.unwrap_or(self.step) + RELAYOUT_EVERY - self.step;
            let batch = left.min(MAX_BATCH).min(until_relayout.max(1) as u32);
            let (c, t) = self.run_batch(batch)?;
            contacts = c;
            match t {
                Some(t) => times.add(&t),
                None => timed = false,
            }
            left -= batch;
        }
        Ok(Advance {
            steps,
            contacts,
            times,
            clock: if timed { Clock::Gpu } else { Clock::None },
        })
    }

    fn particles(&mut self) -> Result<Particles> {
        let n = self.n as usize;
        let set = &self.sets[self.current];
        let pos: Vec<[f32; 4]> = self.gpu.read(&set.pos, n)?;
        let vel: Vec<[f32; 4]> = self.gpu.read(&set.vel, n)?;
        let ids: Vec<u32> = self.gpu.read(&set.ids, n)?;
        let mut out = Particles {
            positions: vec![[0.0; 3]; n],
            velocities: vec![[0.0; 3]; n],
            radii: vec![0.0; n],
            step: self.step,
        };
        for ((p, v), &i) in pos.iter().zip(&vel).zip(&ids) {
            let i = i as usize;
            out.positions[i] = [p[0], p[1], p[2]];
            out.velocities[i] = [v[0], v[1], v[2]];
            out.radii[i] = p[3];
        }
        out.validate().map_err(|e| {
            Error::Gpu(format!(
                "the simulation became unstable by step {} ({e}); try a smaller time step",
                self.step
            ))
        })?;
        Ok(out)
    }
}
