//! Opening a backend's [`Stepper`]: the one place that knows every backend's DEM step.

use super::registry::{BackendChoice, BackendKind, Options};
use crate::dem::model::StepParams;
use crate::dem::scene::Start;
use crate::dem::stepper::Stepper;
use crate::dem::walls::WallSet;
use crate::error::{Error, Result};
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

/// Opens the DEM step of backend `kind` over `particles` inside `walls` (the box walls on:
/// without them, spheres leave below the box, which only the cpu step's flow handles).
fn open_walled(
    kind: BackendKind,
    particles: Particles,
    params: StepParams,
    mode: ProxyMode,
    options: &Options,
    walls: WallSet,
) -> Result<Box<dyn Stepper>> {
    particles.validate()?;
    let atomics = super::gpu_step::ForceAtomics::Auto;
    Ok(match kind {
        BackendKind::Cpu => {
            Box::new(super::cpu::CpuStepper::new(particles, params, mode)?.with_walls(walls)?)
        }
        BackendKind::WgpuCompute => Box::new(
            super::wgpu_compute::GridStepper::with_walls(
                particles,
                params,
                mode,
                atomics,
                options.grid_build,
                &walls,
            )?
            .with_structure(options.structure),
        ),
        BackendKind::WgpuRq => Box::new(super::wgpu_rq::RqStepper::with_walls(
            particles, params, mode, atomics, &walls,
        )?),
        #[cfg(feature = "optix")]
        BackendKind::Optix if !walls.is_box_only() => {
            return Err(Error::BackendUnavailable {
                backend: "optix",
                reason: format!(
                    "this scene has {}, which the optix step does not run yet; the cpu and \
                     wgpu backends run it",
                    walls.describe()
                ),
            });
        }
        #[cfg(feature = "optix")]
        BackendKind::Optix => Box::new(super::optix::OptixStepper::new(
            particles,
            params,
            mode,
            options.rebuild,
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
            open_walled(kind, particles.clone(), params, mode, options, walls)?,
            kind,
        ))
    })?;
    Ok((stepper, kind, Some(reason)))
}

/// Opens the DEM step the user chose for the scene `start`. The box walls run on every
/// backend, mesh walls on cpu and the wgpu backends ([`open_choice`]; optix refuses them); a
/// box switched off, inflows and outflows run on the cpu backend only until the GPU engines
/// gain them: a GPU backend named is refused, saying so, and `auto` opens cpu and says why.
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
    if walls.box_walls && flow.is_empty() {
        return choose_walled(choice, particles, params, mode, options, walls);
    }
    let needs = match (walls.box_walls, flow.is_empty()) {
        (false, false) => format!("{} and spheres flowing in or out", walls.describe()),
        (false, true) => walls.describe(),
        _ => "spheres flowing in or out".to_owned(),
    };
    match choice.kind() {
        Some(BackendKind::Cpu) | None => {
            particles.validate()?;
            let stepper = super::cpu::CpuStepper::new(particles, params, mode)?
                .with_walls(walls)?
                .with_flow(flow, mode);
            let reason = choice.kind().is_none().then(|| {
                format!("auto: cpu, the one backend that runs a scene with {needs} so far")
            });
            Ok((Box::new(stepper), BackendKind::Cpu, reason))
        }
        Some(kind) => Err(Error::BackendUnavailable {
            backend: kind.name(),
            reason: format!(
                "this scene has {needs}, which the {} step does not run yet; the cpu backend \
                 runs it (--backend cpu)",
                kind.name()
            ),
        }),
    }
}
