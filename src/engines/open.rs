//! Opening a backend's [`Stepper`]: the one place that knows every backend's DEM step.

use super::flow_step::{DeviceFlow, FlowStep, Reopen};
use super::registry::{BackendChoice, BackendKind, Options};
use crate::dem::model::StepParams;
use crate::dem::scene::Start;
use crate::dem::stepper::Stepper;
use crate::dem::walls::WallSet;
use crate::error::{Error, Result};
use crate::gpu::{Gpu, Need};
use crate::particles::Particles;
use crate::proxy::ProxyMode;

/// Opens the DEM step of backend `kind` over `particles` in the box.
pub fn open_stepper(
    kind: BackendKind,
    particles: Particles,
    params: StepParams,
    mode: ProxyMode,
    options: &Options,
) -> Result<Box<dyn Stepper>> {
    open_walled(kind, particles, params, mode, options, WallSet::default())
}

/// Opens the DEM step of backend `kind` over `particles` inside `walls`.
fn open_walled(
    kind: BackendKind,
    particles: Particles,
    params: StepParams,
    mode: ProxyMode,
    options: &Options,
    walls: WallSet,
) -> Result<Box<dyn Stepper>> {
    particles.validate()?;
    let kernels = super::gpu_step::KernelSet::Auto;
    Ok(match kind {
        BackendKind::Cpu => {
            Box::new(super::cpu::CpuStepper::new(particles, params, mode)?.with_walls(walls)?)
        }
        BackendKind::WgpuCompute => Box::new(
            super::wgpu_compute::GridStepper::with_walls(
                particles,
                params,
                mode,
                kernels,
                options.grid_build,
                &walls,
            )?
            .with_structure(options.structure),
        ),
        BackendKind::WgpuRq => Box::new(super::wgpu_rq::RqStepper::with_walls(
            particles, params, mode, kernels, &walls,
        )?),
        #[cfg(feature = "optix")]
        BackendKind::Optix => Box::new(super::optix::OptixStepper::new(
            particles,
            params,
            mode,
            options.rebuild,
            &walls,
        )?),
        #[cfg(not(feature = "optix"))]
        BackendKind::Optix => {
            return Err(crate::error::Error::BackendUnavailable {
                backend: "optix",
                reason: super::registry::NO_OPTIX_FEATURE.into(),
            });
        }
    })
}

/// Opens the DEM step the user chose, and names the backend it runs on; `auto` follows the
/// registry's one rule (`open_auto` in the registry) and says why it passed over the faster
/// backends.
pub fn open_choice(
    choice: BackendChoice,
    particles: Particles,
    params: StepParams,
    mode: ProxyMode,
    options: &Options,
) -> Result<(Box<dyn Stepper>, BackendKind, Option<String>)> {
    choose_walled(choice, particles, params, mode, options, WallSet::default())
}

/// [`open_choice`] inside `walls`.
fn choose_walled(
    choice: BackendChoice,
    particles: Particles,
    params: StepParams,
    mode: ProxyMode,
    options: &Options,
    walls: WallSet,
) -> Result<(Box<dyn Stepper>, BackendKind, Option<String>)> {
    if let Some(kind) = choice.kind() {
        let stepper = open_walled(kind, particles, params, mode, options, walls)?;
        return Ok((stepper, kind, None));
    }
    let ((stepper, kind), reason) = super::registry::open_auto(&BackendKind::ALL, |kind| {
        let walls = walls.clone();
        Ok((
            open_walled(
                kind,
                particles.clone(),
                params.clone(),
                mode,
                options,
                walls,
            )?,
            kind,
        ))
    })?;
    Ok((stepper, kind, Some(reason)))
}

/// Opens the DEM step the user chose for the scene `start` (`auto`: in the order of
/// [`BackendKind::FLOWING`] where spheres flow). The box walls, mesh walls and a box switched
/// off run on every backend; spheres flowing in and out on every backend, the GPU ones through `FlowStep` (`engines/flow_step.rs`).
pub fn open_scene(
    choice: BackendChoice,
    start: Start,
    options: &Options,
) -> Result<(Box<dyn Stepper>, BackendKind, Option<String>)> {
    let Start {
        particles,
        params,
        mode,
        walls,
        flow,
    } = start;
    if flow.is_empty() {
        return choose_walled(choice, particles, params, mode, options, walls);
    }
    let open = |kind: BackendKind| -> Result<Box<dyn Stepper>> {
        particles.validate()?;
        if kind == BackendKind::Cpu {
            let stepper = super::cpu::CpuStepper::new(particles.clone(), params.clone(), mode)?
                .with_walls(walls.clone())?
                .with_flow(flow.clone(), mode);
            return Ok(Box::new(stepper));
        }
        let reopen = reopener(kind, params.clone(), mode, options, walls.clone())?;
        let step = FlowStep::new(
            particles.clone(),
            flow.clone(),
            params.dt,
            params.materials.densities.clone(),
            reopen,
        )?;
        Ok(Box::new(step))
    };
    if let Some(kind) = choice.kind() {
        return Ok((open(kind)?, kind, None));
    }
    let ((stepper, kind), reason) =
        super::registry::open_auto(&BackendKind::FLOWING, |kind| Ok((open(kind)?, kind)))?;
    let why = "wgpu-compute first where spheres flow: its flow events stay on the device";
    Ok((stepper, kind, Some(format!("{reason} ({why})"))))
}

/// How [`FlowStep`] opens GPU backend `kind`'s step again over new spheres: on the device
/// opened now, inside `walls`.
fn reopener(
    kind: BackendKind,
    params: StepParams,
    mode: ProxyMode,
    options: &Options,
    walls: WallSet,
) -> Result<Reopen> {
    let kernels = super::gpu_step::KernelSet::Auto;
    Ok(match kind {
        BackendKind::Cpu => {
            return Err(Error::Usage(
                "the cpu step runs its flows itself (CpuStepper::with_flow)".into(),
            ));
        }
        BackendKind::WgpuCompute => {
            let gpu = Gpu::open(Need::Compute)?;
            let (build, structure) = (options.grid_build, options.structure);
            Box::new(move |parts, room| {
                let step = super::wgpu_compute::GridStepper::flowing_on(
                    gpu.clone(),
                    parts,
                    room,
                    params.clone(),
                    mode,
                    kernels,
                    build,
                    &walls,
                )?;
                Ok(Box::new(step.with_structure(structure)) as Box<dyn DeviceFlow>)
            })
        }
        BackendKind::WgpuRq => {
            let gpu = Gpu::open(Need::RayQuery)?;
            Box::new(move |parts, _room| {
                let step = super::wgpu_rq::RqStepper::on_gpu(
                    gpu.clone(),
                    parts,
                    params.clone(),
                    mode,
                    kernels,
                    &walls,
                )?;
                Ok(Box::new(step) as Box<dyn DeviceFlow>)
            })
        }
        #[cfg(feature = "optix")]
        BackendKind::Optix => {
            let rebuild = options.rebuild;
            Box::new(move |parts, _room| {
                let step =
                    super::optix::OptixStepper::new(parts, params.clone(), mode, rebuild, &walls)?;
                Ok(Box::new(step) as Box<dyn DeviceFlow>)
            })
        }
        #[cfg(not(feature = "optix"))]
        BackendKind::Optix => {
            return Err(Error::BackendUnavailable {
                backend: "optix",
                reason: super::registry::NO_OPTIX_FEATURE.into(),
            });
        }
    })
}
