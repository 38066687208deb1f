//! Opening a backend's [`Stepper`]: the one place that knows every backend's DEM step.

use super::model::StepParams;
use super::stepper::Stepper;
use crate::backend::{BackendChoice, BackendKind, Options};
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
            return Err(crate::error::Error::BackendUnavailable {
                backend: "optix",
                reason: crate::backend::NO_OPTIX_FEATURE.into(),
            });
        }
    })
}

/// Opens the DEM step the user chose; `auto` takes the first of wgpu-rq, wgpu-compute (on a
/// hardware adapter) and cpu that opens, and says why it passed over the others.
pub fn open_choice(
    choice: BackendChoice,
    particles: Particles,
    params: StepParams,
    mode: ProxyMode,
    options: &Options,
) -> Result<(Box<dyn Stepper>, Option<String>)> {
    let kind = match choice {
        BackendChoice::Auto => None,
        BackendChoice::Optix => Some(BackendKind::Optix),
        BackendChoice::WgpuRq => Some(BackendKind::WgpuRq),
        BackendChoice::WgpuCompute => Some(BackendKind::WgpuCompute),
        BackendChoice::Cpu => Some(BackendKind::Cpu),
    };
    if let Some(kind) = kind {
        return Ok((open_stepper(kind, particles, params, mode, options)?, None));
    }
    let mut skipped = Vec::new();
    for kind in BackendKind::ALL {
        let why = kind.auto_skip().or_else(|| kind.probe().err());
        if let Some(why) = why {
            skipped.push(format!("skipped {}: {why}", kind.name()));
            continue;
        }
        match open_stepper(kind, particles.clone(), params, mode, options) {
            Ok(s) => {
                let mut reason = format!("auto picked {}", kind.name());
                for why in &skipped {
                    reason.push_str("; ");
                    reason.push_str(why);
                }
                return Ok((s, Some(reason)));
            }
            Err(e) if kind != BackendKind::Cpu => {
                skipped.push(format!("skipped {}: {e}", kind.name()))
            }
            Err(e) => return Err(e),
        }
    }
    Err(crate::error::Error::Usage(skipped.join("; ")))
}
