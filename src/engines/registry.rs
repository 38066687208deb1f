//! The registry: which backends this build knows, which can run on this machine, the one `auto`
//! rule, and opening a backend's detection ([`open`]) or DEM step ([`super::open_stepper`]).

#[cfg(feature = "optix")]
use super::optix;
use super::{cpu, wgpu_compute, wgpu_rq};
use crate::detect::Backend;
use crate::error::{Error, Result};
use crate::gpu::{self, Need};

/// The backends this build of mochi knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BackendKind {
    /// Proxy boxes as OptiX custom primitives on NVIDIA GPUs (cargo feature `optix`).
    Optix,
    /// Proxy boxes in a hardware BVH, one point ray per sphere (WGSL ray queries).
    #[value(name = "wgpu-rq")]
    WgpuRq,
    /// Sorted proxy grid in WGSL compute shaders, for GPUs without ray queries.
    #[value(name = "wgpu-compute")]
    WgpuCompute,
    /// Multi-threaded sorted proxy grid on the CPU; runs everywhere.
    Cpu,
}

impl BackendKind {
    /// Every backend, in the order `auto` prefers them.
    pub const ALL: [BackendKind; 4] = [
        BackendKind::Optix,
        BackendKind::WgpuRq,
        BackendKind::WgpuCompute,
        BackendKind::Cpu,
    ];

    /// Name, as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            BackendKind::Optix => "optix",
            BackendKind::WgpuRq => "wgpu-rq",
            BackendKind::WgpuCompute => "wgpu-compute",
            BackendKind::Cpu => "cpu",
        }
    }

    /// The device this backend would run on, or why it cannot run here.
    pub fn probe(self) -> Result<String, String> {
        match self {
            BackendKind::Optix => probe_optix(),
            BackendKind::WgpuRq => gpu::probe(Need::RayQuery).map(|a| gpu::describe(&a)),
            BackendKind::WgpuCompute => gpu::probe(Need::Compute).map(|a| gpu::describe(&a)),
            BackendKind::Cpu => Ok(format!("CPU, {} threads", rayon::current_num_threads())),
        }
    }

    /// Why `auto` should pass over this backend although it can run (a software GPU is slower
    /// than the cpu backend; OptiX without RT cores is slower than wgpu-compute).
    pub(crate) fn auto_skip(self) -> Option<String> {
        let need = match self {
            #[cfg(feature = "optix")]
            BackendKind::Optix => return optix::auto_skip(),
            #[cfg(not(feature = "optix"))]
            BackendKind::Optix => return None,
            BackendKind::WgpuRq => Need::RayQuery,
            BackendKind::WgpuCompute => Need::Compute,
            BackendKind::Cpu => return None,
        };
        match gpu::probe(need) {
            Ok(a) if a.device_type == wgpu::DeviceType::Cpu => Some(format!(
                "{} is a software adapter, slower than the cpu backend",
                a.name
            )),
            _ => None,
        }
    }

    /// Opens the backend with default options, or says why it cannot run here.
    pub fn open(self) -> Result<Box<dyn Backend>> {
        self.open_with(&Options::default())
    }

    /// Opens the backend with `options`, or says why it cannot run here.
    pub fn open_with(self, options: &Options) -> Result<Box<dyn Backend>> {
        self.probe().map_err(|reason| Error::BackendUnavailable {
            backend: self.name(),
            reason,
        })?;
        Ok(match self {
            #[cfg(feature = "optix")]
            BackendKind::Optix => Box::new(optix::OptixBackend::new()?),
            #[cfg(not(feature = "optix"))]
            BackendKind::Optix => {
                return Err(Error::BackendUnavailable {
                    backend: "optix",
                    reason: NO_OPTIX_FEATURE.into(),
                });
            }
            BackendKind::WgpuRq => Box::new(wgpu_rq::WgpuRqBackend::new()?),
            BackendKind::WgpuCompute => {
                Box::new(wgpu_compute::WgpuComputeBackend::new()?.with_structure(options.structure))
            }
            BackendKind::Cpu => Box::new(cpu::CpuBackend::new()),
        })
    }
}

/// Whether the optix backend can run here.
fn probe_optix() -> Result<String, String> {
    #[cfg(feature = "optix")]
    return optix::probe();
    #[cfg(not(feature = "optix"))]
    Err(NO_OPTIX_FEATURE.into())
}

/// Why optix is unavailable in a build without its feature.
#[cfg(not(feature = "optix"))]
pub(crate) const NO_OPTIX_FEATURE: &str =
    "this mochi was built without the `optix` feature (cargo build --release --features optix)";

/// Settings of the backends that have any.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Options {
    /// Grid structure of `wgpu-compute`.
    pub structure: wgpu_compute::Structure,
    /// When a DEM step with a refittable BVH rebuilds it (grids re-bin and `wgpu-rq` rebuilds
    /// every step whatever this says).
    pub rebuild: RebuildPolicy,
}

/// When a DEM step whose acceleration structure can be refitted (the `optix` BVH) rebuilds it
/// instead: refitting is cheaper, but the boxes of a refitted BVH grow apart as the spheres move
/// and each ray meets more of them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum RebuildPolicy {
    /// Rebuild when refitting has made the rays meet clearly more boxes than just after the
    /// last rebuild (candidates per ray grow), else refit.
    #[default]
    Auto,
    /// Rebuild every `k` steps and refit in between (`1`: rebuild every step).
    Every(u32),
}

impl std::str::FromStr for RebuildPolicy {
    type Err = String;

    /// `auto` or a positive step count.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        if s == "auto" {
            return Ok(RebuildPolicy::Auto);
        }
        match s.parse::<u32>() {
            Ok(k) if k > 0 => Ok(RebuildPolicy::Every(k)),
            _ => Err(format!(
                "expected `auto` or a positive number of steps, got `{s}`"
            )),
        }
    }
}

impl std::fmt::Display for RebuildPolicy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RebuildPolicy::Auto => write!(f, "auto"),
            RebuildPolicy::Every(k) => write!(f, "{k}"),
        }
    }
}

/// A backend named by the user, or `auto`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum BackendChoice {
    /// The fastest backend that can run here.
    #[default]
    Auto,
    /// OptiX custom primitives on NVIDIA GPUs (cargo feature `optix`).
    Optix,
    /// Proxy boxes in a hardware BVH, WGSL ray queries.
    #[value(name = "wgpu-rq")]
    WgpuRq,
    /// Sorted proxy grid in WGSL compute shaders.
    #[value(name = "wgpu-compute")]
    WgpuCompute,
    /// Multi-threaded sorted proxy grid on the CPU.
    Cpu,
}

/// An opened backend and, for `auto`, why it was picked.
pub struct Opened {
    /// The backend, ready for [`Backend::build`].
    pub backend: Box<dyn Backend>,
    /// For `auto`: one line naming the pick and why the faster ones were skipped.
    pub reason: Option<String>,
}

impl BackendChoice {
    /// The backend named, or `None` for `auto`.
    pub fn kind(self) -> Option<BackendKind> {
        match self {
            BackendChoice::Auto => None,
            BackendChoice::Optix => Some(BackendKind::Optix),
            BackendChoice::WgpuRq => Some(BackendKind::WgpuRq),
            BackendChoice::WgpuCompute => Some(BackendKind::WgpuCompute),
            BackendChoice::Cpu => Some(BackendKind::Cpu),
        }
    }
}

/// Opens the backend the user chose; `auto` tries each in order of preference.
pub fn open(choice: BackendChoice, options: &Options) -> Result<Opened> {
    let Some(kind) = choice.kind() else {
        let (backend, reason) = open_auto(|kind| kind.open_with(options))?;
        return Ok(Opened {
            backend,
            reason: Some(reason),
        });
    };
    Ok(Opened {
        backend: kind.open_with(options)?,
        reason: None,
    })
}

/// The one `auto` rule of detection and simulation: the first backend of [`BackendKind::ALL`]
/// that [`BackendKind::auto_skip`] keeps and `open` opens, with one line naming the pick and why
/// each faster one was passed over. The last backend (cpu) runs everywhere, so an error of its
/// about the input is the result rather than a reason to go on; if it cannot run either, the
/// result is [`Error::NoBackend`] with every backend's reason.
pub(crate) fn open_auto<T>(mut open: impl FnMut(BackendKind) -> Result<T>) -> Result<(T, String)> {
    let mut skipped = Vec::new();
    let (last, faster) = BackendKind::ALL.split_last().expect("ALL names backends");
    for &kind in faster {
        if let Some(why) = kind.auto_skip() {
            skipped.push((kind.name(), why));
            continue;
        }
        match open(kind) {
            Ok(opened) => return Ok((opened, auto_reason(kind, &skipped))),
            Err(e) => skipped.push((kind.name(), e.into_reason())),
        }
    }
    match open(*last) {
        Ok(opened) => Ok((opened, auto_reason(*last, &skipped))),
        Err(e @ Error::BackendUnavailable { .. }) => {
            skipped.push((last.name(), e.into_reason()));
            Err(Error::NoBackend { reasons: skipped })
        }
        Err(e) => Err(e),
    }
}

/// "auto picked {kind}; skipped {name}: {why}; …".
fn auto_reason(kind: BackendKind, skipped: &[(&str, String)]) -> String {
    let mut reason = format!("auto picked {}", kind.name());
    for (name, why) in skipped {
        reason.push_str(&format!("; skipped {name}: {why}"));
    }
    reason
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unavailable(kind: BackendKind) -> Error {
        Error::BackendUnavailable {
            backend: kind.name(),
            reason: format!("no {}", kind.name()),
        }
    }

    #[test]
    fn auto_names_every_backend_it_passed_over_and_returns_the_last_ones_error() {
        let only_cpu = |kind| match kind {
            BackendKind::Cpu => Ok(kind),
            _ => Err(unavailable(kind)),
        };
        let (picked, reason) = open_auto(only_cpu).expect("cpu opens");
        assert_eq!(picked, BackendKind::Cpu);
        assert!(
            reason.starts_with("auto picked cpu; skipped optix: "),
            "{reason}"
        );
        for kind in &BackendKind::ALL[1..3] {
            assert!(
                reason.contains(&format!("skipped {}: ", kind.name())),
                "{reason}"
            );
        }
        // An error about the input, not the machine, is the last backend's result as it is.
        let refused = open_auto::<()>(|kind| match kind {
            BackendKind::Cpu => Err(Error::InvalidConfig {
                what: "scene".into(),
                reason: "no cpu".into(),
            }),
            _ => Err(unavailable(kind)),
        });
        assert!(
            matches!(&refused, Err(Error::InvalidConfig { reason, .. }) if reason == "no cpu"),
            "{:?}",
            refused.err()
        );
    }

    #[test]
    fn auto_without_any_backend_is_no_backend_with_every_reason() {
        let none = open_auto::<()>(|kind| Err(unavailable(kind)));
        let Err(Error::NoBackend { reasons }) = &none else {
            panic!("{:?}", none.err());
        };
        // optix may be passed over by auto_skip (no RT cores) with its own words.
        let names: Vec<&str> = reasons.iter().map(|(name, _)| *name).collect();
        let all: Vec<&str> = BackendKind::ALL.iter().map(|k| k.name()).collect();
        assert_eq!(names, all);
        assert_eq!(reasons.last(), Some(&("cpu", "no cpu".to_string())));
        let message = none.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(
            message.starts_with("no backend can run here: optix: "),
            "{message}"
        );
        assert!(message.ends_with("; cpu: no cpu"), "{message}");
    }
}
