//! Opening a backend's [`Stepper`]: the one place that knows every backend's DEM step.

use super::registry::{BackendChoice, BackendKind, Options};
use crate::dem::model::StepParams;
use crate::dem::scene::Start;
use crate::dem::stepper::Stepper;
use crate::error::{Error, Result};
use crate::particles::Particles;
use crate::proxy::ProxyMode;

/// Opens the DEM step of backend `kind` over `particles`.
pub fn open_stepper(
    kind: BackendKind,
    particles: Particles,
    params: StepParams,
    mode: ProxyMode,
    options: &Options,
) -> Result<Box<dyn Stepper>> {
    particles.validate()?;
    Ok(match kind {
        BackendKind::Cpu => Box::new(super::cpu::CpuStepper::new(particles, params, mode)?),
        BackendKind::WgpuCompute => Box::new(
            super::wgpu_compute::GridStepper::with_options(
                particles,
                params,
                mode,
                super::gpu_step::ForceAtomics::Auto,
                options.grid_build,
            )?
            .with_structure(options.structure),
        ),
        BackendKind::WgpuRq => Box::new(super::wgpu_rq::RqStepper::new(particles, params, mode)?),
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
    if let Some(kind) = choice.kind() {
        let stepper = open_stepper(kind, particles, params, mode, options)?;
        return Ok((stepper, kind, None));
    }
    let ((stepper, kind), reason) = super::registry::open_auto(&BackendKind::ALL, |kind| {
        Ok((
            open_stepper(kind, particles.clone(), params, mode, options)?,
            kind,
        ))
    })?;
    Ok((stepper, kind, Some(reason)))
}

/// Opens the DEM step the user chose for the scene `start`. The box walls alone run on every
/// backend ([`open_choice`]); mesh walls, a box switched off, inflows and outflows run on the
/// cpu backend only until the GPU engines gain them: a GPU backend named is refused, saying
/// so, and `auto` opens cpu and says why.
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
    if walls.is_box_only() && flow.is_empty() {
        return open_choice(choice, particles, params, mode, options);
    }
    let needs = match (walls.is_box_only(), flow.is_empty()) {
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
