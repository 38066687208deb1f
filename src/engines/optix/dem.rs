//! The optix backend's DEM step (cargo feature `optix`), the paper's own pipeline: per step
//! (1) the proxy boxes of the spheres (a CUDA kernel) and the acceleration structure refitted to
//! them, or rebuilt as the [`RebuildPolicy`] says; (2) one point ray per sphere whose
//! intersection program applies the proxy rule and resolves each kept contact at once, equal and
//! opposite forces with atomics (`optix/dem.cu`); (3) walls, gravity and integration (a CUDA
//! kernel). The state stays on the GPU, in Morton order (coherent rays); every
//! [`RESORT_EVERY`] steps it is re-sorted (positions read back, the order computed on the host,
//! the state permuted on the GPU) with a rebuild. Phases are timed with CUDA events.
//!
//! A run that needs more than the paper's law (Hertz–Mindlin or per-pair contacts, friction,
//! rolling resistance, spinning spheres, contact history, mesh walls or no box walls) runs the
//! granular programs instead (`granular.rs`) over the same structure maintenance and batches;
//! such a batch starts over with more history slots where a sphere had more contacts than
//! slots.
//!
//! The `auto` policy refits while that pays: it rebuilds once the last steps cost more (refit
//! plus detection) than the average step since the last rebuild, the rebuild's own cost
//! included. Refitting leaves the leaf boxes exact, so candidates per ray do not change with it;
//! what decays is the traversal's cost, and that is what the policy watches.

use super::device::{AccelOp, COUNTER_SLOTS, Device, Gas, Order, State, cuda};
use super::engine::{MAX_COORDINATE, morton_order_of, open_device};
use super::granular::{self, Granular};
use super::launches::{DemBuffers, DemProgram, Kernels};
use crate::dem::model::LawParams;
use crate::dem::stepper::{
    Advance, ExternalLoads, Motion, StageTimes, Stepper, needs_granular_step,
};
use crate::dem::walls::WallLoad;
use crate::engines::RebuildPolicy;
use crate::engines::common::rows::{
    StateRows, advance_in_batches, no_spin, particles_from, place_positions, place_triples,
    residual_rows, rows,
};
use crate::engines::setup::DemSetup;
use crate::error::{Error, OptixError, Result};
use crate::particles::Particles;
use crate::proxy::BOX_PADDING;
use crate::proxy::ProxyMode;
use cudarc::driver::{CudaEvent, CudaSlice, sys::CUevent_flags};
use std::sync::Arc;

/// Steps recorded between two reads of the counters and timers.
const BATCH: u32 = 50;

/// Steps between two checks of the `auto` policy.
const AUTO_CHECK: u32 = 10;

/// The `auto` policy rebuilds when the last steps cost this much more than the cycle's average.
const AUTO_MARGIN: f64 = 1.01;

/// Steps after which the state is re-sorted in Morton order (with a rebuild).
pub const RESORT_EVERY: u64 = 2000;

/// Rebuilds and refits since the start, and the cost of the current rebuild cycle.
#[derive(Debug, Clone, Copy, Default)]
struct Maintenance {
    rebuilds: u64,
    refits: u64,
    /// Steps since the last rebuild (that step included).
    cycle_steps: u64,
    /// Build plus detection time of those steps \[ms\].
    cycle_ms: f64,
    /// A rebuild is due at the next step.
    rebuild_due: bool,
    /// Step of the last Morton re-sort.
    sorted_at: u64,
}

/// How a step resolves contacts and integrates (one per stepper: the variants' sizes do not
/// matter).
#[allow(clippy::large_enum_variant)]
enum Physics {
    /// The paper's law (`optix/dem.cu` and `dem_integrate`).
    Frictionless { program: DemProgram, dem: LawParams },
    /// Everything else (`optix/granular.cu` and `optix/granular_kernels.cu`).
    Granular(Granular),
}

/// The optix DEM step.
pub struct OptixStepper {
    device: Arc<Device>,
    physics: Physics,
    kernels: Kernels,
    n: u32,
    mode: ProxyMode,
    r_max: f32,
    /// How much the proxy boxes grow each radius: half the reach past touching at which
    /// contacts may hold (0 but where they adhere).
    grow: f32,
    policy: RebuildPolicy,
    step: u64,
    state: State,
    spare: State,
    boxes: CudaSlice<f32>,
    force: CudaSlice<f32>,
    /// The external loads by input index (8 floats per sphere; 8 zeros until a load is given).
    external: CudaSlice<f32>,
    contacts: CudaSlice<u32>,
    candidates: CudaSlice<u64>,
    gas: Option<Gas>,
    maintenance: Maintenance,
    /// Candidates per ray of the last step.
    last_candidates: f64,
    /// Whether the particles came with their materials (read back as they came: with them, or
    /// without, all of the first).
    materials_given: bool,
}

impl OptixStepper {
    /// Uploads `particles` to GPU 0 (in Morton order) and builds the acceleration structure,
    /// for a step inside `walls`.
    pub fn open(setup: DemSetup, policy: RebuildPolicy) -> Result<Self> {
        let DemSetup {
            mut particles,
            params,
            mode,
            walls,
        } = setup;
        let walls = &walls;
        particles.separate_coincident()?;
        let device = open_device()?;
        let kernels = Kernels::load(&device)?;
        let n64 = particles.len() as u64;
        let limit = (device.max_primitives as u64).min(u32::MAX as u64 / 6);
        if n64 > limit {
            return Err(Error::TooLarge {
                what: format!("spheres for the optix DEM step on {}", device.name),
                got: n64,
                limit,
            });
        }
        let n = n64 as u32;
        let r_max = particles.radius_range().1;
        let reach = params
            .box_lo
            .iter()
            .chain(&params.box_hi)
            .fold(0.0f32, |m, x| m.max(x.abs()))
            + 2.0 * r_max;
        if reach > MAX_COORDINATE / 2.0 {
            return Err(Error::InvalidConfig {
                what: "optix".into(),
                reason: format!(
                    "the box reaches coordinate {reach:e}; OptiX traverses reliably only within \
                     ±{MAX_COORDINATE:e}: use wgpu-compute or cpu for this scene"
                ),
            });
        }
        granular::check_materials(&particles, &params, walls)?;
        let stream = device.stream.clone();
        let (pos, vel) = rows(&particles, &params.materials);
        let lo = residual_rows(&particles);
        let order = morton_order_of(&particles.positions);
        let pick = |rows: &[[f32; 4]]| -> Vec<f32> {
            order.iter().flat_map(|&i| rows[i as usize]).collect()
        };
        let alloc = cuda("allocating the state");
        let upload = |host: &[f32]| {
            if host.is_empty() {
                stream.alloc_zeros::<f32>(4)
            } else {
                stream.clone_htod(host)
            }
            .map_err(&alloc)
        };
        let zeros_f32 = |len: usize| stream.alloc_zeros::<f32>(len.max(4)).map_err(&alloc);
        let zeros_u32 = |len: usize| stream.alloc_zeros::<u32>(len.max(1)).map_err(&alloc);
        let ids = if order.is_empty() {
            zeros_u32(1)?
        } else {
            stream.clone_htod(&order).map_err(&alloc)?
        };
        let len = n as usize;
        let physics = if needs_granular_step(&particles, &params, walls) {
            Physics::Granular(Granular::new(&device, &particles, &params, &order, walls)?)
        } else {
            Physics::Frictionless {
                program: DemProgram::new(&device)?,
                dem: LawParams::new(&params, n, 0),
            }
        };
        let mut stepper = OptixStepper {
            physics,
            kernels,
            n,
            mode,
            r_max,
            grow: 0.5 * params.search_margin(r_max),
            policy,
            step: particles.step,
            state: State {
                pos: upload(&pick(&pos))?,
                lo: upload(&pick(&lo))?,
                vel: upload(&pick(&vel))?,
                ids,
            },
            spare: State {
                pos: zeros_f32(4 * len)?,
                lo: zeros_f32(4 * len)?,
                vel: zeros_f32(4 * len)?,
                ids: zeros_u32(len)?,
            },
            boxes: zeros_f32(6 * len)?,
            force: zeros_f32(3 * len)?,
            external: zeros_f32(8)?,
            contacts: stream.alloc_zeros::<u32>(COUNTER_SLOTS).map_err(&alloc)?,
            candidates: stream.alloc_zeros::<u64>(COUNTER_SLOTS).map_err(&alloc)?,
            gas: None,
            maintenance: Maintenance {
                sorted_at: particles.step,
                // The first step rebuilds (timed like every other).
                rebuild_due: true,
                cycle_steps: u64::MAX,
                ..Maintenance::default()
            },
            last_candidates: 0.0,
            materials_given: !particles.materials.is_empty(),
            device,
        };
        if n > 0 {
            stepper.write_boxes()?;
            let gas = Gas::build(&stepper.device, &stepper.boxes, n)?;
            stepper.gas = Some(gas);
        }
        Ok(stepper)
    }

    fn event(&self) -> std::result::Result<CudaEvent, OptixError> {
        record_event(&self.device)
    }

    /// The proxy boxes of the current state.
    fn write_boxes(&mut self) -> Result<()> {
        self.kernels.dem_boxes(
            &self.state.pos,
            &mut self.boxes,
            self.n,
            self.mode,
            self.r_max,
            BOX_PADDING,
            self.grow,
        )?;
        Ok(())
    }

    /// Re-sorts the state in Morton order of the current positions (the caller rebuilds).
    fn resort(&mut self) -> Result<()> {
        let stream = self.device.stream.clone();
        let pos = stream
            .clone_dtoh(&self.state.pos)
            .map_err(cuda("reading the positions back"))?;
        let centers: Vec<[f32; 3]> = pos
            .chunks_exact(4)
            .take(self.n as usize)
            .map(|p| [p[0], p[1], p[2]])
            .collect();
        let order = Order::upload(&stream, &morton_order_of(&centers))?;
        self.kernels
            .dem_permute(&self.state, &order, &mut self.spare, self.n)?;
        std::mem::swap(&mut self.state, &mut self.spare);
        if let Physics::Granular(g) = &mut self.physics {
            g.permute(&order)?;
        }
        self.maintenance.sorted_at = self.step;
        Ok(())
    }

    /// Whether the next step rebuilds (else it refits).
    fn rebuilds_now(&self) -> bool {
        let m = &self.maintenance;
        match self.policy {
            RebuildPolicy::Every(k) => m.cycle_steps >= k as u64,
            RebuildPolicy::Auto => m.rebuild_due,
        }
    }

    /// Records one step; returns its four events (start, built, resolved, integrated).
    fn record_step(&mut self, rebuild: bool) -> Result<[CudaEvent; 4]> {
        let stream = self.device.stream.clone();
        let start = self.event()?;
        self.write_boxes()?;
        let op = if rebuild {
            AccelOp::Build
        } else {
            AccelOp::Update
        };
        let gas = self.gas.as_mut().expect("built for n > 0");
        gas.run(&self.device, &self.boxes, op)?;
        let built = self.event()?;
        let gas = self.gas.as_ref().expect("built for n > 0");
        let clear = cuda("clearing the counters");
        stream.memset_zeros(&mut self.contacts).map_err(&clear)?;
        stream.memset_zeros(&mut self.candidates).map_err(&clear)?;
        let resolved = match &mut self.physics {
            Physics::Frictionless { program, dem } => {
                let buffers = DemBuffers {
                    pos: &self.state.pos,
                    vel: &self.state.vel,
                    force: &mut self.force,
                    contacts: &mut self.contacts,
                    candidates: &mut self.candidates,
                };
                program.launch(gas, self.mode, *dem, buffers)?;
                let resolved = record_event(&self.device)?;
                self.kernels.dem_integrate(
                    &mut self.state,
                    (&mut self.force, &self.external),
                    dem,
                    self.step as u32,
                )?;
                resolved
            }
            Physics::Granular(g) => {
                g.resolve(
                    gas,
                    self.mode,
                    &self.state,
                    &mut self.force,
                    &mut self.contacts,
                    &mut self.candidates,
                )?;
                let resolved = record_event(&self.device)?;
                let accumulated = (&mut self.force, &self.external);
                g.integrate(&mut self.state, accumulated, self.step as u32)?;
                resolved
            }
        };
        let integrated = self.event()?;
        self.step += 1;
        Ok([start, built, resolved, integrated])
    }

    /// Records `steps` steps and reads their counters back; returns each step's events, whether
    /// it rebuilt, and the contacts of the last.
    #[allow(clippy::type_complexity)]
    fn record_batch(&mut self, steps: u32) -> Result<(Vec<[CudaEvent; 4]>, Vec<bool>, u64)> {
        let mut events = Vec::with_capacity(steps as usize);
        let mut rebuilt = Vec::with_capacity(steps as usize);
        for _ in 0..steps {
            let rebuild = self.rebuilds_now();
            events.push(self.record_step(rebuild)?);
            rebuilt.push(rebuild);
            let m = &mut self.maintenance;
            if rebuild {
                m.rebuilds += 1;
                m.cycle_steps = 0;
                m.cycle_ms = 0.0;
                m.rebuild_due = false;
            } else {
                m.refits += 1;
            }
            m.cycle_steps += 1;
        }
        let stream = &self.device.stream;
        let read = cuda("reading the counters back");
        let contacts: u64 = stream
            .clone_dtoh(&self.contacts)
            .map_err(&read)?
            .iter()
            .map(|&c| c as u64)
            .sum();
        let candidates: u64 = stream
            .clone_dtoh(&self.candidates)
            .map_err(&read)?
            .iter()
            .sum();
        self.last_candidates = candidates as f64 / self.n.max(1) as f64;
        Ok((events, rebuilt, contacts))
    }

    /// Runs up to `steps` steps (at most one batch); returns how many, the contacts of the last
    /// and the phase times.
    fn run_batch(&mut self, steps: u32) -> Result<(u32, u64, StageTimes)> {
        if self.step >= self.maintenance.sorted_at + RESORT_EVERY {
            self.resort()?;
            self.maintenance.rebuild_due = true;
            self.maintenance.cycle_steps = u64::MAX; // any policy rebuilds now
        }
        let mut steps = steps.min(BATCH);
        if self.policy == RebuildPolicy::Auto {
            // A rebuild step runs alone, so the cycle's first refits are measured apart.
            steps = if self.maintenance.rebuild_due {
                1
            } else {
                steps.min(AUTO_CHECK)
            };
        }
        let (events, rebuilt, contacts) = loop {
            let at_start = (self.step, self.maintenance);
            if let Physics::Granular(g) = &mut self.physics
                && g.may_start_over()
            {
                g.begin_batch(&self.device.stream, &self.state, &mut self.spare)?;
            }
            let (events, rebuilt, contacts) = self.record_batch(steps)?;
            if let Physics::Granular(g) = &mut self.physics {
                if g.may_start_over()
                    && let Some(need) = g.overflow(&self.device.stream)?
                {
                    // A sphere had more contacts than slots: from the batch's start again.
                    g.start_over(&self.device, &mut self.state, &self.spare, need)?;
                    (self.step, self.maintenance) = at_start;
                    continue;
                }
                g.end_batch();
            }
            break (events, rebuilt, contacts);
        };
        let ms = |a: &CudaEvent, b: &CudaEvent| {
            a.elapsed_ms(b)
                .map(f64::from)
                .map_err(cuda("reading the GPU timers"))
        };
        let mut times = StageTimes::default();
        let mut refit_ms = 0.0;
        for ([start, built, resolved, integrated], rebuild) in events.iter().zip(&rebuilt) {
            let step = StageTimes {
                build_ms: ms(start, built)?,
                dcd_ms: ms(built, resolved)?,
                update_ms: ms(resolved, integrated)?,
            };
            let cost = step.build_ms + step.dcd_ms;
            self.maintenance.cycle_ms += cost;
            if !rebuild {
                refit_ms += cost;
            }
            times.add(&step);
        }
        let refits = rebuilt.iter().filter(|&&r| !r).count();
        if self.policy == RebuildPolicy::Auto && refits > 0 {
            let m = &mut self.maintenance;
            let average = m.cycle_ms / m.cycle_steps as f64;
            m.rebuild_due = refit_ms / refits as f64 > AUTO_MARGIN * average;
        }
        Ok((steps, contacts, times))
    }
}

/// Flow events read the state back and reopen the step.
impl crate::engines::common::flow::DeviceFlow for OptixStepper {
    fn sum_wall_loads_within(&mut self, bounds: ([f32; 3], [f32; 3])) {
        if let Physics::Granular(g) = &mut self.physics {
            g.sum_loads_within(bounds);
        }
    }
}

impl Stepper for OptixStepper {
    fn describe(&self) -> String {
        let m = &self.maintenance;
        let granular = match &self.physics {
            Physics::Frictionless { .. } => String::new(),
            Physics::Granular(g) => format!("; granular step, {} history slots", g.slots()),
        };
        format!(
            "optix ({}; rebuild {}: {} rebuilds, {} refits; {:.2} candidates per ray{granular})",
            self.device.name, self.policy, m.rebuilds, m.refits, self.last_candidates
        )
    }

    fn advance(&mut self, steps: u32) -> Result<Advance> {
        if self.n == 0 {
            return advance_in_batches(steps, false, |left| {
                self.step += left as u64;
                Ok((left, 0, None))
            });
        }
        if let Physics::Granular(g) = &mut self.physics
            && steps > 0
        {
            g.sum_loads_in(&self.device.stream, self.step + steps as u64 - 1)?;
        }
        let advance = advance_in_batches(steps, true, |left| {
            let (done, contacts, times) = self.run_batch(left)?;
            Ok((done, contacts, Some(times)))
        })?;
        if let Physics::Granular(g) = &mut self.physics {
            g.read_loads(&self.device.stream)?;
        }
        Ok(advance)
    }

    fn wall_loads(&self) -> Vec<WallLoad> {
        match &self.physics {
            Physics::Granular(g) => g.loads().to_vec(),
            Physics::Frictionless { .. } => Vec::new(),
        }
    }

    fn set_gravity(&mut self, gravity: [f32; 3]) -> Result<()> {
        match &mut self.physics {
            Physics::Frictionless { dem, .. } => dem.gravity = gravity.into(),
            Physics::Granular(g) => g.set_gravity(gravity),
        }
        Ok(())
    }

    fn set_external_loads(&mut self, loads: &ExternalLoads) -> Result<()> {
        let n = self.n as usize;
        loads.check(n)?;
        let turns = match &self.physics {
            Physics::Granular(g) => g.turns(),
            Physics::Frictionless { .. } => false,
        };
        if loads.turns() && !turns {
            return Err(no_spin());
        }
        let on = !loads.is_empty();
        if on {
            let rows = loads.rows(n);
            let flat: &[f32] = bytemuck::cast_slice(&rows);
            let write = cuda("writing the external loads");
            if self.external.len() < flat.len() {
                self.external = self.device.stream.clone_htod(flat).map_err(write)?;
            } else {
                let stream = &self.device.stream;
                stream
                    .memcpy_htod(flat, &mut self.external)
                    .map_err(write)?;
            }
        }
        match &mut self.physics {
            Physics::Frictionless { dem, .. } => dem.loaded = on as u32,
            Physics::Granular(g) => g.set_external(on),
        }
        Ok(())
    }

    fn set_motion(&mut self, motion: &Motion<'_>) -> Result<()> {
        let n = self.n as usize;
        motion.check(n)?;
        if matches!(&self.physics, Physics::Granular(g) if g.has_clumps()) {
            motion.check_clumps(&self.particles()?)?;
        }
        let granular = matches!(self.physics, Physics::Granular(_));
        if motion.turns() && !granular {
            return Err(no_spin());
        }
        if n == 0 || motion.is_empty() {
            return Ok(());
        }
        let stream = self.device.stream.clone();
        let read = cuda("reading the state to set the spheres' motion");
        let write = cuda("writing the spheres' motion");
        let mut ids = stream.clone_dtoh(&self.state.ids).map_err(&read)?;
        ids.truncate(n);
        fn rows(flat: &mut [f32], n: usize) -> &mut [[f32; 4]] {
            bytemuck::cast_slice_mut(&mut flat[..4 * n])
        }
        let rewrite = |slice: &mut CudaSlice<f32>, values: &[[f32; 3]]| -> Result<()> {
            let mut flat = stream.clone_dtoh(slice).map_err(&read)?;
            place_triples(values, Some(&ids), rows(&mut flat, n));
            Ok(stream.memcpy_htod(&flat, slice).map_err(&write)?)
        };
        if let Some(v) = motion.velocities {
            rewrite(&mut self.state.vel, v)?;
        }
        if let (Some(w), Physics::Granular(g)) = (motion.angular_velocities, &mut self.physics) {
            rewrite(g.spin_mut(), w)?;
        }
        if let Some(positions) = motion.positions {
            let mut centres = stream.clone_dtoh(&self.state.pos).map_err(&read)?;
            let mut residuals = stream.clone_dtoh(&self.state.lo).map_err(&read)?;
            let (at, rest) = (rows(&mut centres, n), rows(&mut residuals, n));
            place_positions(positions, Some(&ids), at, rest);
            stream
                .memcpy_htod(&centres, &mut self.state.pos)
                .map_err(&write)?;
            stream
                .memcpy_htod(&residuals, &mut self.state.lo)
                .map_err(&write)?;
            // Moved spheres: the next step builds its acceleration structure afresh.
            self.maintenance.rebuild_due = true;
            self.maintenance.cycle_steps = u64::MAX;
        }
        Ok(())
    }

    fn step(&self) -> u64 {
        self.step
    }

    fn particles(&mut self) -> Result<Particles> {
        let stream = &self.device.stream;
        let n = self.n as usize;
        let rows4 = |flat: Vec<f32>| -> Vec<[f32; 4]> {
            flat.chunks_exact(4)
                .take(n)
                .map(|r| [r[0], r[1], r[2], r[3]])
                .collect()
        };
        let read = cuda("reading the state back");
        let pos = rows4(stream.clone_dtoh(&self.state.pos).map_err(&read)?);
        let lo = rows4(stream.clone_dtoh(&self.state.lo).map_err(&read)?);
        let vel = rows4(stream.clone_dtoh(&self.state.vel).map_err(&read)?);
        let mut ids = stream.clone_dtoh(&self.state.ids).map_err(&read)?;
        ids.truncate(n);
        let rows = StateRows {
            pos: &pos,
            lo: &lo,
            vel: &vel,
        };
        let mut out = particles_from(rows, Some(&ids), self.step)?;
        if let Physics::Granular(g) = &self.physics {
            out.clumps = g.read_clumps(stream)?;
            let back = g.read_back(stream, &ids)?;
            out.angular_velocities = back.angular_velocities;
            out.check_stable()?;
            out.history = back.history;
            if self.materials_given {
                out.materials = back.materials;
            }
        } else if self.materials_given {
            // The frictionless step runs one material.
            out.materials = vec![0; n];
        }
        Ok(out)
    }

    fn refits(&self) -> bool {
        true
    }
}

/// An event recorded on `device`'s stream now.
fn record_event(device: &Device) -> std::result::Result<CudaEvent, OptixError> {
    device
        .stream
        .record_event(Some(CUevent_flags::CU_EVENT_DEFAULT))
        .map_err(cuda("recording an event"))
}
