//! Opening a backend's [`Stepper`]: the one place that knows every backend's DEM step.

use super::registry::{BackendChoice, BackendKind, Options};
use crate::dem::model::StepParams;
use crate::dem::stepper::Stepper;
use crate::error::Result;
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
