//! Opening a backend's [`Stepper`]: the one place that knows every backend's DEM step.

use super::registry::{BackendChoice, BackendKind, Options};
use crate::dem::model::{NormalLaw, StepParams};
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
    // The optix step runs the granular physics too (engines/optix/granular.rs).
    if !matches!(kind, BackendKind::Cpu | BackendKind::Optix)
        && let Some(missing) = beyond_the_gpu_steps(&particles, &params)
    {
        return Err(Error::BackendUnavailable {
            backend: kind.name(),
            reason: format!("its DEM step has no {missing} yet (the cpu backend has)"),
        });
    }
    Ok(match kind {
        BackendKind::Cpu => Box::new(super::cpu::CpuStepper::new(particles, params, mode)?),
        BackendKind::WgpuCompute => Box::new(
            super::wgpu_compute::GridStepper::new(particles, params, mode)?
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
            return Err(Error::BackendUnavailable {
                backend: "optix",
                reason: super::registry::NO_OPTIX_FEATURE.into(),
            });
        }
    })
}

/// What a run needs that the GPU engines' DEM step does not have yet (their step is the paper's
/// linear law with one stiffness, no friction, no rotation), in words; `None` when they can run
/// it.
fn beyond_the_gpu_steps(particles: &Particles, params: &StepParams) -> Option<String> {
    let mut missing = Vec::new();
    match params.law {
        NormalLaw::Linear => {}
        NormalLaw::LinearPerPair { .. } => missing.push("per-pair stiffness"),
        NormalLaw::Hertz { .. } => missing.push("Hertz–Mindlin contact"),
    }
    let f = &params.friction;
    if f.sliding > 0.0 || f.wall_sliding > 0.0 {
        missing.push("friction");
    }
    if f.rolling > 0.0 {
        missing.push("rolling resistance");
    }
    if particles.spin() {
        missing.push("rotation (spheres with angular velocities)");
    }
    if !particles.history.is_empty() {
        missing.push("contact history");
    }
    match missing.split_last() {
        None => None,
        Some((last, [])) => Some(last.to_string()),
        Some((last, rest)) => Some(format!("{} or {last}", rest.join(", "))),
    }
}

/// Opens the DEM step the user chose; `auto` follows the registry's one rule
/// (`open_auto` in the registry) and says why it passed over the faster backends.
pub fn open_choice(
    choice: BackendChoice,
    particles: Particles,
    params: StepParams,
    mode: ProxyMode,
    options: &Options,
) -> Result<(Box<dyn Stepper>, Option<String>)> {
    if let Some(kind) = choice.kind() {
        return Ok((open_stepper(kind, particles, params, mode, options)?, None));
    }
    let (stepper, reason) = super::registry::open_auto(&BackendKind::ALL, |kind| {
        open_stepper(kind, particles.clone(), params, mode, options)
    })?;
    Ok((stepper, Some(reason)))
}
