//! The registry: which backends this build knows, which can run on this machine and the one
//! `auto` rule (opening them is `open.rs`'s).

#[cfg(feature = "optix")]
use super::optix;
use super::wgpu::compute;
use crate::error::{Error, Result};
use crate::gpu::{self, Need};

/// The backends this build of mochi knows. The first paragraph of each variant's doc is its
/// help on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum BackendKind {
    /// OptiX custom primitives on NVIDIA GPUs (cargo feature `optix`).
    ///
    /// Each sphere's proxy box is a custom primitive of one OptiX acceleration structure.
    Optix,
    /// Proxy boxes in a hardware BVH, WGSL ray queries.
    ///
    /// One point ray per sphere.
    #[cfg_attr(feature = "clap", value(name = "wgpu-rq"))]
    WgpuRq,
    /// Sorted proxy grid in WGSL compute shaders.
    ///
    /// For GPUs without ray queries.
    #[cfg_attr(feature = "clap", value(name = "wgpu-compute"))]
    WgpuCompute,
    /// Multi-threaded sorted proxy grid on the CPU.
    ///
    /// Runs everywhere.
    Cpu,
}

crate::names::named!(BackendKind {
    Optix => "optix",
    WgpuRq => "wgpu-rq",
    WgpuCompute => "wgpu-compute",
    Cpu => "cpu",
});

impl BackendKind {
    /// Every backend, in the order `auto` prefers them.
    pub const ALL: [BackendKind; 4] = [
        BackendKind::Optix,
        BackendKind::WgpuRq,
        BackendKind::WgpuCompute,
        BackendKind::Cpu,
    ];

    /// Every backend, in the order `auto` prefers them for a scene whose spheres flow in or
    /// out: wgpu-compute flows on the device, while the optix and wgpu-rq steps read every
    /// sphere back and reopen at each flow event (docs/performance-log/: a second an event at a
    /// million spheres), which costs more than their faster steps save.
    pub const FLOWING: [BackendKind; 4] = [
        BackendKind::WgpuCompute,
        BackendKind::Optix,
        BackendKind::WgpuRq,
        BackendKind::Cpu,
    ];

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
    pub fn auto_skip(self) -> Option<String> {
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
    pub structure: compute::Structure,
    /// How `wgpu-compute` builds its grid: dense table, sorted keys, or auto.
    pub grid_build: compute::GridBuild,
    /// When a DEM step with a refittable BVH rebuilds it (grids re-bin and `wgpu-rq` rebuilds
    /// every step whatever this says).
    pub rebuild: RebuildPolicy,
}

/// When a DEM step whose acceleration structure can be refitted (the `optix` BVH) rebuilds it
/// instead: refitting is cheaper, but the boxes of a refitted BVH grow apart as the spheres move
/// and each ray meets more of them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum RebuildPolicy {
    /// Rebuild once the refitted steps (refit and detection) cost more than the average step
    /// since the last rebuild, the rebuild's own cost included, else refit.
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

/// What was opened for the user's choice of backend (its detection, `Box<dyn Backend>`, ready
/// for [`Backend::build`](crate::Backend::build), or its DEM step, `Box<dyn Stepper>`), which backend it is and, for
/// `auto`, why it was picked.
pub struct Opened<T> {
    /// The detection or the DEM step.
    pub value: T,
    /// Which backend it is.
    pub kind: BackendKind,
    /// For `auto`: one line naming the pick and why the faster ones were skipped.
    pub reason: Option<String>,
}

/// A backend named by the user, or `auto`; spelt `auto` or a backend's [`BackendKind::name`]
/// on the command line and in files alike (any case is read).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum BackendChoice {
    /// The fastest backend that can run here (the registry's one `auto` rule).
    #[default]
    Auto,
    /// This backend.
    Named(BackendKind),
}

impl BackendChoice {
    /// `auto`, then every backend of [`BackendKind::ALL`]: the values the command line lists.
    const ALL: [BackendChoice; BackendKind::ALL.len() + 1] = {
        let mut all = [BackendChoice::Auto; BackendKind::ALL.len() + 1];
        let mut k = 0;
        while k < BackendKind::ALL.len() {
            all[k + 1] = BackendChoice::Named(BackendKind::ALL[k]);
            k += 1;
        }
        all
    };

    /// The backend named, or `None` for `auto`.
    pub fn kind(self) -> Option<BackendKind> {
        match self {
            BackendChoice::Auto => None,
            BackendChoice::Named(kind) => Some(kind),
        }
    }

    /// Name, as on the command line.
    pub fn name(self) -> &'static str {
        self.kind().map_or("auto", BackendKind::name)
    }
}

impl crate::names::Named for BackendChoice {
    const ALL: &'static [Self] = &Self::ALL;

    fn name(self) -> &'static str {
        BackendChoice::name(self)
    }
}

#[cfg(feature = "clap")]
impl clap::ValueEnum for BackendChoice {
    fn value_variants<'a>() -> &'a [Self] {
        &Self::ALL
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        match self {
            BackendChoice::Auto => Some(
                clap::builder::PossibleValue::new("auto")
                    .help("The fastest backend that can run here"),
            ),
            BackendChoice::Named(kind) => kind.to_possible_value(),
        }
    }
}

impl std::str::FromStr for BackendChoice {
    type Err = String;

    /// `auto` or a backend's name, in any case.
    fn from_str(name: &str) -> std::result::Result<Self, String> {
        crate::names::parse(name, "backend")
    }
}

impl TryFrom<String> for BackendChoice {
    type Error = String;

    fn try_from(name: String) -> std::result::Result<Self, String> {
        name.parse()
    }
}

impl From<BackendChoice> for String {
    fn from(choice: BackendChoice) -> String {
        choice.name().to_owned()
    }
}

impl std::fmt::Display for BackendChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The one `auto` rule of detection, simulation and rendering: the first of `candidates` (not
/// empty, in the order of [`BackendKind::ALL`]) that probes ([`BackendKind::probe`]), that
/// [`BackendKind::auto_skip`] keeps and that `open` opens, with one line naming the pick and why
/// each faster one was passed over. The last candidate (cpu) runs everywhere, so it is opened
/// without asking, and an error of its about the input is the result rather than a reason to go
/// on; if it cannot run either, the result is [`Error::NoBackend`] with every candidate's reason.
pub(crate) fn open_auto<T>(
    candidates: &[BackendKind],
    mut open: impl FnMut(BackendKind) -> Result<T>,
) -> Result<(T, String)> {
    let mut skipped = Vec::new();
    let (last, faster) = candidates
        .split_last()
        .expect("every caller offers at least the cpu");
    for &kind in faster {
        if let Some(why) = kind.probe().err().or_else(|| kind.auto_skip()) {
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
        let (picked, reason) = open_auto(&BackendKind::ALL, only_cpu).expect("cpu opens");
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
        let refused = open_auto::<()>(&BackendKind::ALL, |kind| match kind {
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
        let none = open_auto::<()>(&BackendKind::ALL, |kind| Err(unavailable(kind)));
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

    #[test]
    fn the_choices_are_auto_then_every_backend_by_its_name() {
        use crate::names::Named;
        let names: Vec<&str> = <BackendChoice as Named>::ALL
            .iter()
            .map(crate::names::name)
            .collect();
        let mut want = vec!["auto"];
        want.extend(BackendKind::ALL.map(BackendKind::name));
        assert_eq!(names, want);
        for &choice in <BackendChoice as Named>::ALL {
            let name = choice.to_string();
            assert_eq!(name.parse(), Ok(choice));
            assert_eq!(name.to_uppercase().parse(), Ok(choice));
            let json = serde_json::to_string(&choice).unwrap();
            assert_eq!(json, format!("\"{name}\""));
            assert_eq!(
                serde_json::from_str::<BackendChoice>(&json).unwrap(),
                choice
            );
        }
        let wrong = "gpu".parse::<BackendChoice>().unwrap_err();
        assert!(wrong.contains("unknown backend \"gpu\""), "{wrong}");
        assert!(serde_json::from_str::<BackendChoice>("\"gpu\"").is_err());
    }

    #[test]
    fn auto_considers_only_its_candidates() {
        let mut asked = Vec::new();
        let (picked, reason) = open_auto(&[BackendKind::WgpuCompute, BackendKind::Cpu], |kind| {
            asked.push(kind);
            match kind {
                BackendKind::Cpu => Ok(kind),
                _ => Err(unavailable(kind)),
            }
        })
        .expect("cpu opens");
        assert_eq!(picked, BackendKind::Cpu);
        assert_eq!(asked.last(), Some(&BackendKind::Cpu));
        assert!(
            asked
                .iter()
                .all(|&k| k != BackendKind::Optix && k != BackendKind::WgpuRq)
        );
        assert!(
            reason.starts_with("auto picked cpu; skipped wgpu-compute: "),
            "{reason}"
        );
        assert!(
            !reason.contains("optix") && !reason.contains("wgpu-rq"),
            "{reason}"
        );
    }

    #[cfg(not(feature = "optix"))]
    #[test]
    fn auto_passes_over_a_backend_whose_probe_fails_without_opening_it() {
        let mut asked = Vec::new();
        let (_, reason) = open_auto(&BackendKind::ALL, |kind| {
            asked.push(kind);
            match kind {
                BackendKind::Cpu => Ok(()),
                _ => Err(unavailable(kind)),
            }
        })
        .expect("cpu opens");
        assert!(!asked.contains(&BackendKind::Optix), "{asked:?}");
        assert!(
            reason.contains(&format!("skipped optix: {NO_OPTIX_FEATURE}")),
            "{reason}"
        );
    }
}
