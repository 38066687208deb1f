//! The wgpu-rq backend's DEM step: the paper's pipeline on WGSL ray queries, resident on the GPU.
//! Per step the proxy boxes of all spheres, a BLAS and TLAS rebuilt from them (wgpu has no refit,
//! so "rebuild every step" is the only policy), one point ray per sphere that resolves every pair
//! the proxy rule keeps (equal and opposite forces, atomics), then `dem_physics.wgsl`'s
//! integration (`wgsl/rq/dem_rq.wgsl`). The spheres stay in input order: the generated scenes are
//! laid out along a lattice, so the BVH's primitives are already spatially coherent.
//!
//! A scene with friction, rolling resistance, rotation or another law than the paper's runs the
//! granular variant of the step (`wgsl/rq/dem_rq_granular.wgsl`, [`Granular`]): its own module and
//! pipelines, with angular velocities, torques and the contact history bound besides (a
//! sphere's index is its stable id); the walls are resolved in the contact pass, where their
//! history lives. The paper's scenes run the paper's kernels as before.

use super::accel::Accel;
use super::shaders::dem_rq::{self, BOXES, COUNTERS, RQ_PARAMS, RqParams, TLAS};
use crate::dem::stepper::{Advance, ExternalLoads, Motion, Snapshot, StageTimes, Stepper};
use crate::dem::walls::WallLoad;
use crate::engines::common::flow::Room;
use crate::engines::common::rows::{
    StateRows, advance_in_batches, particles_with, residual_rows, rows,
};
use crate::engines::setup::DemSetup;
use crate::engines::wgpu::clumps::shader::ENTRY as CLUMPS_ENTRY;
use crate::engines::wgpu::state::{ExternalRows, ParamsUniform, write_motion};
use crate::engines::wgpu::step::physics::{CLOCK, DEM, EXTERNAL, FORCE, POS, POS_LO, VEL};
use crate::engines::wgpu::step::{
    BatchParts, DemModule, GROUP, Granular, KernelSet, MAX_BATCH, RedoableBatch, StepTimer, Turn,
    max_spheres, run_batch,
};
use crate::engines::wgpu::walls;
use crate::error::Result;
use crate::gpu::{self, Gpu, Need};
use crate::particles::Particles;
use crate::proxy::BOX_PADDING;

/// Labels of the mesh walls' kernels' dispatches and bind groups, in the order of
/// `walls::ENTRY_POINTS`.
const MESH_LABELS: [&str; 2] = ["mochi.dem.rq.mesh_near", "mochi.dem.rq.mesh_walls"];

struct Pipelines {
    proxy_boxes: wgpu::ComputePipeline,
    resolve: wgpu::ComputePipeline,
    /// The mesh walls' kernels (granular step with mesh walls only), in the order of
    /// `walls::ENTRY_POINTS`.
    mesh: Option<[wgpu::ComputePipeline; 2]>,
    /// The clumps' step (before the integration; with clumps only) and its workgroups.
    clumps: Option<(wgpu::ComputePipeline, (u32, u32))>,
    integrate: wgpu::ComputePipeline,
}

struct Binds {
    proxy_boxes: wgpu::BindGroup,
    /// For the steps of each parity (which history they read, in the granular step; the same
    /// in the paper's).
    resolve: [wgpu::BindGroup; 2],
    /// The mesh walls' kernels', by parity as `resolve`, each in the order of `Pipelines::mesh`.
    mesh: Option<[[wgpu::BindGroup; 2]; 2]>,
    /// The clumps' step's (with clumps only).
    clumps: Option<wgpu::BindGroup>,
    integrate: wgpu::BindGroup,
}

/// What a non-empty set of spheres keeps on the GPU.
struct Resident {
    accel: Accel,
    rq: wgpu::Buffer,
    clock: wgpu::Buffer,
    force: wgpu::Buffer,
    counters: wgpu::Buffer,
    /// The external loads (by input index).
    external: ExternalRows,
    binds: Binds,
}

/// The wgpu-rq DEM step.
pub struct RqStepper {
    gpu: Gpu,
    pipelines: Pipelines,
    n: u32,
    step: u64,
    groups: (u32, u32),
    pos: wgpu::Buffer,
    /// The residuals of the centres in `pos` (`vec4`: x, y, z, 0).
    lo: wgpu::Buffer,
    vel: wgpu::Buffer,
    /// `None` for no spheres.
    resident: Option<Resident>,
    timer: Option<StepTimer>,
    atomics: &'static str,
    /// The granular step's state (`None`: a variant of the paper's step).
    granular: Option<Granular>,
    /// The step's parameters (binding `DEM`).
    dem: ParamsUniform,
    /// Parity of the next step (which history buffer it reads).
    parity: usize,
    /// Whether the step turns its spheres (integrates their angular velocities).
    turns: bool,
}

impl RqStepper {
    /// The step of `setup` running `kernels` on the best adapter with ray queries.
    pub fn open(setup: DemSetup, kernels: KernelSet) -> Result<Self> {
        Self::open_on(Gpu::open(Need::RayQuery)?, setup, kernels)
    }

    /// The step of `setup` running `kernels` on `gpu` (opened with ray queries): a step
    /// reopened on the device of the last, whose compiled pipelines it reuses.
    pub fn open_on(gpu: Gpu, setup: DemSetup, kernels: KernelSet) -> Result<Self> {
        let DemSetup {
            mut particles,
            params,
            mode,
            walls,
        } = setup;
        let walls = &walls;
        particles.separate_coincident()?;
        let limit = max_spheres(&gpu).min(
            gpu.limits.max_blas_primitive_count as u64 * gpu.limits.max_tlas_instance_count as u64,
        );
        let DemModule {
            atomics,
            granular,
            params: mut dem,
            module,
            constants,
        } = DemModule::open(
            &gpu,
            "wgpu-rq",
            &particles,
            &params,
            walls,
            limit,
            // One state set, in input order, with room for the particles.
            (1, Room::of(&particles)),
            kernels,
            |accumulators, _, variant| dem_rq::variant_source(variant, accumulators),
        )?;
        let n64 = particles.len() as u64;
        let n = n64 as u32;
        let pipeline = |entry: &str| {
            gpu.pipeline_with(&format!("mochi.dem.rq.{entry}"), &module, entry, &constants)
        };
        let pipelines = Pipelines {
            proxy_boxes: pipeline("proxy_boxes"),
            resolve: pipeline("resolve"),
            mesh: granular
                .as_ref()
                .is_some_and(|g| g.mesh().any())
                .then(|| walls::ENTRY_POINTS.map(pipeline)),
            clumps: granular
                .as_ref()
                .and_then(|g| g.clumps())
                .map(|c| (pipeline(CLUMPS_ENTRY), gpu.grid(c.count(), GROUP))),
            // A run with clumps leaves their components to them.
            integrate: pipeline(match particles.clumps.clumps.is_empty() {
                true => "integrate",
                false => "integrate_clumped",
            }),
        };
        let groups = gpu.grid(n, GROUP);
        dem.update(&gpu, |p| p.row = groups.0 * GROUP);
        let none = wgpu::BufferUsages::empty();
        let (pos_rows, vel_rows) = rows(&particles, &params.materials);
        let lo_rows = residual_rows(&particles);
        let (_, r_max) = particles.radius_range();
        let (pos, lo, vel, resident) = gpu.checked("allocating the wgpu-rq DEM buffers", || {
            let pos = gpu.storage("mochi.dem.rq.pos", n64 * 16, none);
            let lo = gpu.storage("mochi.dem.rq.pos_lo", n64 * 16, none);
            let vel = gpu.storage("mochi.dem.rq.vel", n64 * 16, none);
            let clock = gpu.storage("mochi.dem.rq.clock", 4, none);
            gpu.queue
                .write_buffer(&clock, 0, bytemuck::bytes_of(&(particles.step as u32)));
            let resident = (n > 0).then(|| {
                let chunk = gpu.limits.max_blas_primitive_count.min(n).max(1);
                let accel = Accel::new(&gpu, n, chunk);
                let rq = gpu.uniform(
                    "mochi.dem.rq.rq_params",
                    &RqParams {
                        chunk,
                        pad_rel: BOX_PADDING,
                        mode: mode.code(),
                        r_max,
                    },
                );
                let force = gpu.storage("mochi.dem.rq.force", n64 * 12, none);
                let counters = gpu.storage("mochi.dem.rq.counters", 16, none);
                let buffers = (
                    &pos,
                    &lo,
                    &vel,
                    &rq,
                    dem.buffer(),
                    &clock,
                    &accel.boxes,
                    &force,
                    &counters,
                );
                let external = ExternalRows::new(&gpu);
                let binds = bind(
                    &gpu,
                    &pipelines,
                    buffers,
                    (accel.tlas(), external.buffer()),
                    granular.as_ref(),
                );
                Resident {
                    accel,
                    rq,
                    clock,
                    force,
                    counters,
                    external,
                    binds,
                }
            });
            (pos, lo, vel, resident)
        })?;
        gpu.queue
            .write_buffer(&pos, 0, bytemuck::cast_slice(&pos_rows));
        gpu.queue
            .write_buffer(&lo, 0, bytemuck::cast_slice(&lo_rows));
        gpu.queue
            .write_buffer(&vel, 0, bytemuck::cast_slice(&vel_rows));
        Ok(RqStepper {
            timer: StepTimer::new(&gpu),
            pipelines,
            n,
            step: particles.step,
            groups,
            pos,
            lo,
            vel,
            resident,
            atomics,
            granular,
            dem,
            parity: 0,
            turns: params.friction.turns(),
            gpu,
        })
    }
}

impl RqStepper {
    /// The buffers the next step starts from (one state set, in input order).
    fn turn(&self) -> Turn {
        Turn {
            set: 0,
            parity: self.parity,
        }
    }

    /// The state read back in input order ([`Error::Unstable`] if it is not finite), with
    /// the history where `springs` (else each sphere's contacts counted).
    fn state(&self, springs: bool) -> Result<Snapshot> {
        let n = self.n as usize;
        let pos: Vec<[f32; 4]> = self.gpu.read(&self.pos, n)?;
        let lo: Vec<[f32; 4]> = self.gpu.read(&self.lo, n)?;
        let vel: Vec<[f32; 4]> = self.gpu.read(&self.vel, n)?;
        let rotation = || {
            let g = self.granular.as_ref();
            g.map(|g| g.read(&self.gpu, self.turn(), None, springs))
                .transpose()
        };
        let rows = StateRows {
            pos: &pos,
            lo: &lo,
            vel: &vel,
        };
        let mut particles = particles_with(rows, None, self.step, rotation)?;
        let granular = self.granular.as_ref();
        if let Some(c) = granular.and_then(|g| g.clumps()) {
            particles.clumps = c.read(&self.gpu)?;
        }
        let contacts = match (springs, granular) {
            (false, Some(g)) => g.contact_counts(&self.gpu, self.turn(), None, true)?,
            _ => particles.history.counts(n),
        };
        Ok(Snapshot {
            particles,
            contacts,
        })
    }
}

impl RedoableBatch for RqStepper {
    fn batch_parts(&mut self) -> BatchParts<'_> {
        let turn = self.turn();
        let r = self.resident.as_ref().expect("spheres to step");
        let state = vec![&self.pos, &self.lo, &self.vel, &r.clock];
        (
            &self.gpu,
            self.granular.as_mut(),
            turn,
            state,
            &mut self.dem,
        )
    }

    fn record_batch(
        &mut self,
        mut encoder: wgpu::CommandEncoder,
        steps: u32,
    ) -> Result<(u64, Option<StageTimes>)> {
        let gpu = &self.gpu;
        let r = self.resident.as_ref().expect("spheres to step");
        let p = &self.pipelines;
        let timer = self.timer.as_ref();
        let mut parity = self.parity;
        for s in 0..steps {
            StepTimer::mark(timer, &mut encoder, s, 0);
            gpu.dispatch(
                &mut encoder,
                "mochi.dem.rq.proxy_boxes",
                &p.proxy_boxes,
                &r.binds.proxy_boxes,
                self.groups,
            );
            r.accel.encode_build(&mut encoder);
            StepTimer::mark(timer, &mut encoder, s, 1);
            encoder.clear_buffer(&r.counters, 0, None);
            gpu.dispatch(
                &mut encoder,
                "mochi.dem.rq.resolve",
                &p.resolve,
                &r.binds.resolve[parity],
                self.groups,
            );
            if let (Some(pipelines), Some(binds)) = (&p.mesh, &r.binds.mesh) {
                for ((pipeline, bind), label) in
                    pipelines.iter().zip(&binds[parity]).zip(MESH_LABELS)
                {
                    gpu.dispatch(&mut encoder, label, pipeline, bind, self.groups);
                }
            }
            parity = 1 - parity;
            StepTimer::mark(timer, &mut encoder, s, 2);
            if let (Some((pipeline, groups)), Some(bind)) = (&p.clumps, &r.binds.clumps) {
                let label = "mochi.dem.rq.advance_clumps";
                gpu.dispatch(&mut encoder, label, pipeline, bind, *groups);
            }
            gpu.dispatch(
                &mut encoder,
                "mochi.dem.rq.integrate",
                &p.integrate,
                &r.binds.integrate,
                self.groups,
            );
            StepTimer::mark(timer, &mut encoder, s, 3);
        }
        if let Some(t) = timer {
            t.end(&mut encoder, steps);
        }
        gpu.checked("running wgpu-rq DEM steps", || {
            gpu.queue.submit([encoder.finish()])
        })?;
        self.step += steps as u64;
        self.parity = parity;
        let contacts = gpu.read::<u32>(&r.counters, 1)?[0] as u64;
        let times = timer.map(|t| t.read(gpu, steps)).transpose()?;
        Ok((contacts, times))
    }

    fn rewind(&mut self, steps: u32) {
        self.step -= steps as u64;
        self.parity = (self.parity + steps as usize) % 2;
    }

    fn rebind(&mut self) {
        let r = self.resident.as_mut().expect("spheres to step");
        let buffers = (
            &self.pos,
            &self.lo,
            &self.vel,
            &r.rq,
            self.dem.buffer(),
            &r.clock,
            &r.accel.boxes,
            &r.force,
            &r.counters,
        );
        let more = (r.accel.tlas(), r.external.buffer());
        r.binds = bind(
            &self.gpu,
            &self.pipelines,
            buffers,
            more,
            self.granular.as_ref(),
        );
    }
}

/// Flow events read the state back and reopen the step.
impl crate::engines::common::flow::DeviceFlow for RqStepper {
    fn sum_wall_loads_within(&mut self, bounds: ([f32; 3], [f32; 3])) {
        if let Some(g) = &mut self.granular {
            g.mesh_mut().sum_loads_within(&self.gpu, bounds);
        }
    }
}

impl Stepper for RqStepper {
    fn describe(&self) -> String {
        let history = self.granular.as_ref().and_then(Granular::describe_history);
        format!(
            "wgpu-rq ({}; {}{})",
            gpu::describe(&self.gpu.info),
            self.atomics,
            history.map(|h| format!("; {h}")).unwrap_or_default()
        )
    }

    fn advance(&mut self, steps: u32) -> Result<Advance> {
        if self.resident.is_none() {
            // No spheres: only the clock moves.
            return advance_in_batches(steps, false, |left| {
                self.step += left as u64;
                Ok((left, 0, None))
            });
        }
        if let Some(g) = &mut self.granular {
            g.mesh_mut()
                .sum_loads_in(&self.gpu, self.step + steps as u64 - 1);
        }
        let advance = advance_in_batches(steps, self.timer.is_some(), |left| {
            let batch = left.min(MAX_BATCH);
            let (contacts, times) = run_batch(self, batch)?;
            Ok((batch, contacts, times))
        })?;
        if let Some(g) = &mut self.granular {
            g.mesh_mut().read_loads(&self.gpu)?;
        }
        Ok(advance)
    }

    fn wall_loads(&self) -> Vec<WallLoad> {
        self.granular
            .as_ref()
            .map_or_else(Vec::new, |g| g.mesh().loads().to_vec())
    }

    fn step(&self) -> u64 {
        self.step
    }

    fn particles(&mut self) -> Result<Particles> {
        Ok(self.state(true)?.particles)
    }

    fn snapshot(&mut self) -> Result<Snapshot> {
        self.state(false)
    }

    fn set_gravity(&mut self, gravity: [f32; 3]) -> Result<()> {
        self.dem.update(&self.gpu, |p| p.gravity = gravity.into());
        Ok(())
    }

    fn set_motion(&mut self, motion: &Motion<'_>) -> Result<()> {
        if self.granular.as_ref().is_some_and(|g| g.clumps().is_some()) {
            motion.check_clumps(&self.particles()?)?;
        }
        let omega = self.granular.as_ref().map(|g| g.omega_of(0));
        let buffers = (&self.pos, &self.lo, &self.vel, omega);
        // The acceleration structure is rebuilt every step, over where the spheres are.
        write_motion(&self.gpu, buffers, self.n as usize, None, motion).map(|_| ())
    }

    fn set_external_loads(&mut self, loads: &ExternalLoads) -> Result<()> {
        let Some(r) = &mut self.resident else {
            return loads.check(0);
        };
        // The state is in input order and no sphere enters or leaves it.
        if r.external
            .set(&self.gpu, loads, (self.n, self.turns, true))?
        {
            RedoableBatch::rebind(self);
        }
        let on = !loads.is_empty() as u32;
        self.dem.update(&self.gpu, |p| p.loaded = on);
        Ok(())
    }
}

/// The step's buffers: positions, their residuals, velocities, the ray-query and step uniforms,
/// the clock, the proxy boxes, the force accumulators and the counters.
type StepBuffers<'a> = (
    &'a wgpu::Buffer,
    &'a wgpu::Buffer,
    &'a wgpu::Buffer,
    &'a wgpu::Buffer,
    &'a wgpu::Buffer,
    &'a wgpu::Buffer,
    &'a wgpu::Buffer,
    &'a wgpu::Buffer,
    &'a wgpu::Buffer,
);

/// The bind groups of the step over `buffers`, `tlas` and the external loads `external`,
/// with the granular step's where it has one.
fn bind(
    gpu: &Gpu,
    p: &Pipelines,
    buffers: StepBuffers,
    (tlas, external): (&wgpu::Tlas, &wgpu::Buffer),
    granular: Option<&Granular>,
) -> Binds {
    let (pos, lo, vel, rq, dem, clock, boxes, force, counters) = buffers;
    let resolve = |parity: usize| {
        let mut all = vec![
            (RQ_PARAMS, rq),
            (DEM, dem),
            (POS, pos),
            (VEL, vel),
            (FORCE, force),
            (COUNTERS, counters),
        ];
        if let Some(g) = granular {
            all.extend(g.resolve_bindings(Turn { set: 0, parity }));
            all.extend(g.contact_bindings());
        }
        gpu.bind_with_tlas("mochi.dem.rq.resolve", &p.resolve, &all, (TLAS, tlas))
    };
    let mut integrate = vec![
        (DEM, dem),
        (POS, pos),
        (POS_LO, lo),
        (VEL, vel),
        (FORCE, force),
        (CLOCK, clock),
        (EXTERNAL, external),
    ];
    let clumps = granular
        .zip(p.clumps.as_ref())
        .and_then(|(g, (pipeline, _))| {
            let all = [&integrate[..], &g.advance_bindings(0)?].concat();
            Some(gpu.bind("mochi.dem.rq.advance_clumps", pipeline, &all))
        });
    if let Some(g) = granular {
        integrate.extend(g.integrate_bindings(0));
    }
    Binds {
        proxy_boxes: gpu.bind(
            "mochi.dem.rq.proxy_boxes",
            &p.proxy_boxes,
            &[
                (RQ_PARAMS, rq),
                (DEM, dem),
                (BOXES, boxes),
                (POS, pos),
                (CLOCK, clock),
            ],
        ),
        resolve: [resolve(0), resolve(1)],
        mesh: granular.zip(p.mesh.as_ref()).and_then(|(g, pipelines)| {
            let state = [
                (DEM, dem),
                (POS, pos),
                (CLOCK, clock),
                (VEL, vel),
                (FORCE, force),
            ];
            let bind = |parity: usize| -> Option<[wgpu::BindGroup; 2]> {
                let [near, contacts] = g.mesh_bindings(Turn { set: 0, parity })?;
                Some([
                    gpu.bind(
                        MESH_LABELS[0],
                        &pipelines[0],
                        &[&state[..3], &near].concat(),
                    ),
                    gpu.bind(
                        MESH_LABELS[1],
                        &pipelines[1],
                        &[&state[..], &contacts].concat(),
                    ),
                ])
            };
            Some([bind(0)?, bind(1)?])
        }),
        clumps,
        integrate: gpu.bind("mochi.dem.rq.integrate", &p.integrate, &integrate),
    }
}
