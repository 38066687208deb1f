//! The [`Stepper`] trait that every backend's DEM step implements, and how to open one.

use super::model::StepParams;
use crate::backend::{BackendChoice, BackendKind, Options};
use crate::error::Result;
use crate::particles::Particles;
use crate::proxy::ProxyMode;

/// Time spent per phase of the step, summed over the steps of one [`Stepper::advance`] \[ms\].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimes {
    /// Maintaining the acceleration structure (binning, sorting, building).
    pub build_ms: f64,
    /// Collision detection with the contact forces resolved in the same pass.
    pub dcd_ms: f64,
    /// Walls, gravity and integration.
    pub update_ms: f64,
}

impl StageTimes {
    /// All three phases.
    pub fn total_ms(&self) -> f64 {
        self.build_ms + self.dcd_ms + self.update_ms
    }

    /// Adds `other` to these sums.
    pub fn add(&mut self, other: &StageTimes) {
        self.build_ms += other.build_ms;
        self.dcd_ms += other.dcd_ms;
        self.update_ms += other.update_ms;
    }
}

/// How the stage times were taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Clock {
    /// GPU timestamps: time on the device itself.
    Gpu,
    /// Host wall-clock time around each phase.
    Wall,
    /// Not measured (a GPU without timestamps).
    None,
}

/// What one [`Stepper::advance`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Advance {
    /// Steps taken.
    pub steps: u32,
    /// Touching pairs found in the last step.
    pub contacts: u64,
    /// Phase times summed over the steps.
    pub times: StageTimes,
    /// How `times` were measured.
    pub clock: Clock,
}

/// One backend's DEM step: keeps the particles (on the GPU for GPU backends) and advances them.
pub trait Stepper {
    /// Backend name and device, in words.
    fn describe(&self) -> String;

    /// Takes `steps` time steps.
    fn advance(&mut self, steps: u32) -> Result<Advance>;

    /// The particles now, in input order (a read-back on GPU backends).
    fn particles(&mut self) -> Result<Particles>;

    /// Whether this step refits its acceleration structure between rebuilds, and so obeys
    /// [`Options::rebuild`] (default: no; grids re-bin and `wgpu-rq` rebuilds every step).
    fn refits(&self) -> bool {
        false
    }
}

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
