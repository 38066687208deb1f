//! What a benchmark run measures: the experiments, the scale, the backends and the repeats.

use mochi::engines::BackendKind;
use mochi::engines::wgpu::compute::Structure;
use mochi::{Error, Result};
use serde::{Deserialize, Serialize};

/// Steps of experiment 8's drop: the paper's (and the comparison with Taichi's) 0.5 s at
/// [`DROP_DT`], every one of them timed.
pub const DROP_STEPS: u32 = 5000;

/// Time step of experiment 8's drop \[s\] (the paper's; the mesh scene's own is 2.5e-5).
pub const DROP_DT: f64 = 1e-4;

/// Copies of the mesh in experiment 8, as in the paper's scene.
pub const MESH_DROP_COPIES: u32 = 14;

/// The wide box of experiment 8, per side over the scene's own.
pub const WIDE_BOX_SCALE: u32 = 10;

/// One of the paper's experiments (docs/method.md, "The paper's workloads"), numbered 1–8 as
/// `mochi bench` lists them (docs/guide/bench.md; [`Experiment::number`]).
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    PartialOrd,
    Ord,
    Hash,
    Serialize,
    Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum Experiment {
    /// 1: detection only, `mochi` against `nns` mode, radius ratios 1.2, 12 and 120.
    Dcd,
    /// 2: the DEM step on dataset 1 falling freely: build, DCD and update per step.
    Freefall,
    /// 3: the same under gravity rotating at 0.25π rad/s.
    Rotating,
    /// 4: the DEM step against the rebuild interval of a refitted BVH.
    Rebuild,
    /// 5: the DEM step from 1,000 spheres up in steps of ×10.
    Scaling,
    /// 6: the DEM steps the performance targets name: the landed slab, and the poured
    /// `polylog` pile with the single and the multi-level grid side by side.
    Targets,
    /// 7: the Hertz–Mindlin step (friction with contact history, rotation, EPSD rolling
    /// resistance) on the settled slab, with its contacts and the size of the history.
    Friction,
    /// 8: the paper's 14-bunny drop (14 copies of `--mesh`, or of the built-in torus, filled
    /// with as many spheres as the paper's bunnies hold at `--scale paper`) at the paper's dt
    /// 1e-4, every one of its 5,000 steps timed, and the same spheres in a box 10× wider per
    /// side: a step whose grid build should cost by the spheres, not by the box;
    /// `wgpu-compute` with its dense and its sorted build.
    Clustered,
}

impl Experiment {
    /// Every experiment, in order.
    pub const ALL: [Experiment; 8] = [
        Experiment::Dcd,
        Experiment::Freefall,
        Experiment::Rotating,
        Experiment::Rebuild,
        Experiment::Scaling,
        Experiment::Targets,
        Experiment::Friction,
        Experiment::Clustered,
    ];

    /// Number, 1–8, as on the command line (`--experiments 1,6`) and in the report's headings:
    /// the paper's detection and DEM experiments 1–5, then the steps the performance targets
    /// name (6), the Hertz–Mindlin step (7) and the clustered scenes (8), in the order of
    /// [`Experiment::ALL`].
    pub fn number(self) -> u8 {
        self as u8 + 1
    }

    /// Name, as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Experiment::Dcd => "dcd",
            Experiment::Freefall => "freefall",
            Experiment::Rotating => "rotating",
            Experiment::Rebuild => "rebuild",
            Experiment::Scaling => "scaling",
            Experiment::Targets => "targets",
            Experiment::Friction => "friction",
            Experiment::Clustered => "clustered",
        }
    }

    /// A heading for reports.
    pub fn title(self) -> &'static str {
        match self {
            Experiment::Dcd => "DCD only, mochi vs nns mode, radius ratio 1.2 / 12 / 120",
            Experiment::Freefall => "DEM freefall (dataset 1), time per step by phase",
            Experiment::Rotating => "DEM under rotating gravity (0.25π rad/s), time per step",
            Experiment::Rebuild => "DEM step against the rebuild interval",
            Experiment::Scaling => "DEM step from 1k spheres up, ×10 each",
            Experiment::Targets => {
                "DEM steps with targets: landed slab, poured polylog pile (grid vs mlgrid)"
            }
            Experiment::Friction => {
                "Hertz–Mindlin step (friction, rotation, EPSD rolling) on the settled slab and \
                 the poured polylog pile"
            }
            Experiment::Clustered => {
                "14 filled meshes dropped (whole drop, dt 1e-4), in their box and in one 10× wider"
            }
        }
    }

    /// The workload measured, exactly: scene, spheres, law and time step, the steps run before
    /// the timed ones, the steps timed and the contacts reported.
    pub fn workload(self, s: &Settings) -> String {
        let (n, w, r, steps) = (s.spheres, s.warmup as u64, s.repeats as u64, s.steps as u64);
        let runs = |k: u64| format!("{k} run{}", if k == 1 { "" } else { "s" });
        let continued = |before: &str| {
            format!(
                "timed: {} of {steps} steps after {} untimed (warm-up), each run continuing \
                 the last: steps {}–{} after {before} (each row says its own)",
                runs(r),
                runs(w),
                w * steps,
                (w + r) * steps
            )
        };
        let contacts = "reported: the contacts (touching pairs) in the last timed step";
        match self {
            Experiment::Dcd => format!(
                "`poly1.2`, `poly12` and `poly120` (radius ratios 1.2, 12 and 120) of {n} spheres \
                 at uniform random centres (overlaps allowed), each detected in `mochi` and in \
                 `nns` mode; timed: build + detection of every pair, {} after {} untimed \
                 (warm-up); reported: the pairs found and their digest.",
                runs(r),
                runs(w)
            ),
            Experiment::Freefall | Experiment::Rotating => format!(
                "`{}` (dataset 1: radii 0.5–0.6 mm in a lattice) of {n} spheres falling from rest \
                 at t = 0{}, the paper's linear law (one stiffness, frictionless), dt 1e-4 s; {}; \
                 {contacts}.",
                if self == Experiment::Rotating {
                    "rotating"
                } else {
                    "freefall"
                },
                if self == Experiment::Rotating {
                    " under gravity turning at 0.25π rad/s about y"
                } else {
                    ""
                },
                continued("the start")
            ),
            Experiment::Rebuild => format!(
                "as experiment 2 (`freefall` of {n} spheres from rest, linear, dt 1e-4 s), once \
                 per rebuild interval ({}, auto) from a fresh start on steps that refit, once \
                 (\"every step\") on the others; {}; {contacts}.",
                REBUILD_INTERVALS.map(|i| i.to_string()).join(", "),
                continued("the start")
            ),
            Experiment::Scaling => format!(
                "as experiment 2 (`freefall` from rest, linear, dt 1e-4 s) with 1,000, 10,000, … \
                 up to {} spheres; {}; {contacts}.",
                s.max_spheres,
                continued("the start")
            ),
            Experiment::Targets => format!(
                "the `slab` (radii 0.5–0.6 mm) of {n} spheres under the paper's linear law, dt \
                 1e-4 s, after {} untimed steps of landing (`--settle`); the `polylog` pile \
                 (radii 0.5 mm–6 cm, log-uniform) of {n} spheres under the linear law with the \
                 per-pair stiffness (every contact 10 steps), frictionless, dt 1e-4 s, poured from \
                 its layers for {} (`--pile`), timed in `mochi` mode (wgpu-compute: \
                 the single and the multi-level grid) and in `nns` mode from the same pile; {}; \
                 {contacts}. A target is judged only on a state with contacts.",
                s.settle,
                s.pile.map_or_else(
                    || "1.5 times its top spheres' fall time (untimed; the rows say the steps)"
                        .to_owned(),
                    |p| format!("{p} untimed steps")
                ),
                continued("the settling or the pouring")
            ),
            Experiment::Friction => format!(
                "the `slab` of {n} spheres under Hertz–Mindlin (the default material: E 1e7 Pa, \
                 μ 0.5, EPSD rolling μ_r 0.1, dt 0.2 Rayleigh time of the smallest sphere) on a \
                 floor raised to its underside, after {} untimed steps of landing (`--settle`){}; \
                 {}; {contacts}, and the contact history.",
                s.settle,
                if s.pour > 0 {
                    format!(
                        "; the `polylog` pile of {n} spheres poured for {} untimed steps under \
                         Hertz–Mindlin (`--pour`)",
                        s.pour
                    )
                } else {
                    String::new()
                },
                continued("the settling or the pouring")
            ),
            Experiment::Clustered => format!(
                "{MESH_DROP_COPIES} copies of {} filled with about {} spheres (the paper's \
                 1,151,878 × {n} / 1,000,000), the paper's linear law (one stiffness, \
                 frictionless), dt {DROP_DT:e} s, dropped from rest at t = 0 under gravity −z \
                 (9.81 m/s²) in their box and in \
                 one {WIDE_BOX_SCALE}× wider per side; timed: every step of the drop, steps \
                 0–{DROP_STEPS} ({:.1} s), every run from the start ({} after {} untimed \
                 (warm-up); `--steps` does not apply); reported: the contacts at the end of the \
                 drop.",
                s.mesh.as_ref().map_or_else(
                    || "the built-in torus (the paper's is the Stanford bunny: `--mesh`)"
                        .to_owned(),
                    |m| format!("`{}`", m.display())
                ),
                (1_151_878.0 * n as f64 / 1e6).round(),
                DROP_STEPS as f64 * DROP_DT,
                runs(r),
                runs(w)
            ),
        }
    }

    /// Parses a name (`dcd`, …) or a number (`1`–`8`).
    pub fn parse(s: &str) -> std::result::Result<Self, String> {
        let s = s.trim();
        Experiment::ALL
            .into_iter()
            .find(|e| e.name().eq_ignore_ascii_case(s) || e.number().to_string() == s)
            .ok_or_else(|| {
                format!(
                    "unknown experiment `{s}`: use 1-8 or dcd, freefall, rotating, rebuild, \
                     scaling, targets, friction, clustered"
                )
            })
    }
}

/// Preset sizes of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Scale {
    /// 10,000 spheres, scaling 1k–10k, 20 steps: a quick look (seconds on a laptop CPU).
    #[default]
    Small,
    /// 100,000 spheres, scaling 1k–100k, 100 steps.
    Medium,
    /// The paper's 1,000,000 spheres, scaling 1k–1M, 200 steps.
    Paper,
}

impl Scale {
    /// Spheres of every experiment but scaling.
    pub fn spheres(self) -> usize {
        match self {
            Scale::Small => 10_000,
            Scale::Medium => 100_000,
            Scale::Paper => 1_000_000,
        }
    }

    /// Timed DEM steps per repeat.
    pub fn steps(self) -> u32 {
        match self {
            Scale::Small => 20,
            Scale::Medium => 100,
            Scale::Paper => 200,
        }
    }
}

/// Which backends to run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BackendSelection {
    /// Those `auto` would consider: every backend that runs here except software adapters and
    /// OptiX without RT cores.
    Auto,
    /// Every backend that runs here.
    All,
    /// These backends; one that cannot run here is an error.
    List(Vec<BackendKind>),
}

impl std::str::FromStr for BackendSelection {
    type Err = String;

    /// `auto`, `all`, or a comma-separated list of backend names.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        use clap::ValueEnum;
        match s.trim() {
            "auto" => Ok(BackendSelection::Auto),
            "all" => Ok(BackendSelection::All),
            list => list
                .split(',')
                .map(|name| {
                    BackendKind::from_str(name.trim(), true).map_err(|_| {
                        let names = BackendKind::ALL.map(BackendKind::name).join(", ");
                        format!(
                            "unknown backend `{}`: use auto, all, or names from {names}",
                            name.trim()
                        )
                    })
                })
                .collect::<std::result::Result<Vec<_>, _>>()
                .map(BackendSelection::List),
        }
    }
}

/// A backend that was left out, and why.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct BackendStatus {
    /// The backend.
    #[serde(with = "mochi::names::by_name")]
    pub name: BackendKind,
    /// The device it runs on, when it runs.
    pub device: Option<String>,
    /// Why it was left out, when it was.
    pub left_out: Option<String>,
}

impl BackendSelection {
    /// The backends to run, and the status of every backend this build knows.
    pub fn resolve(&self) -> Result<(Vec<BackendKind>, Vec<BackendStatus>)> {
        let mut chosen = Vec::new();
        let mut status = Vec::new();
        for kind in BackendKind::ALL {
            let wanted = match self {
                BackendSelection::List(list) => list.contains(&kind),
                _ => true,
            };
            let probe = kind.probe();
            let left_out = match (&probe, self) {
                _ if !wanted => Some("not selected".to_owned()),
                (Err(why), BackendSelection::List(_)) => {
                    return Err(Error::BackendUnavailable {
                        backend: kind.name(),
                        reason: why.clone(),
                    });
                }
                (Err(why), _) => Some(why.clone()),
                (Ok(_), BackendSelection::Auto) => kind.auto_skip(),
                (Ok(_), _) => None,
            };
            if left_out.is_none() {
                chosen.push(kind);
            }
            status.push(BackendStatus {
                name: kind,
                device: probe.ok(),
                left_out,
            });
        }
        Ok((chosen, status))
    }
}

/// The settings of a run: what it measures and how often (the report records them as used).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    /// Experiments to run, in order.
    pub experiments: Vec<Experiment>,
    /// Spheres of every experiment but scaling.
    pub spheres: usize,
    /// Largest sphere count of the scaling experiment (from 1,000 up, ×10).
    pub max_spheres: usize,
    /// Timed DEM steps per repeat (experiment 8 times its whole drop, [`DROP_STEPS`], instead).
    pub steps: u32,
    /// Untimed steps that let the slab of experiments 6 and 7 land before it is timed (run once
    /// per experiment, on the first backend whose DEM step runs it; every backend then starts
    /// from that state).
    pub settle: u32,
    /// Untimed steps that pour experiment 6's `polylog` pile before it is timed (once, like
    /// `settle`); `None`: 1.5 times the time its top spheres take to fall to the floor
    /// (the bench's `pour_steps`; a report holds the steps that [`super::run`] ran).
    #[serde(default)]
    pub pile: Option<u64>,
    /// Untimed steps of the `polylog` pile poured under Hertz–Mindlin before experiment 7 times
    /// it (0: experiment 7 measures the slab alone).
    #[serde(default)]
    pub pour: u64,
    /// Timed repeats per measurement (at least 1).
    pub repeats: usize,
    /// Untimed runs before the timed ones.
    pub warmup: usize,
    /// Grid structure of `wgpu-compute`.
    pub structure: Structure,
    /// Seed of the generated scenes.
    pub seed: u64,
    /// Mesh of experiment 8 (`None`: the built-in torus).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh: Option<std::path::PathBuf>,
}

/// Everything one benchmark run does.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// Backends to run it on.
    pub backends: Vec<BackendKind>,
    /// What to measure and how often.
    pub settings: Settings,
}

/// The most timed (and untimed) runs per measurement.
pub const MAX_RUNS: usize = 10_000;

/// Rebuild intervals swept on steps that refit (experiment 4), before `auto`.
pub const REBUILD_INTERVALS: [u32; 6] = [1, 5, 10, 25, 50, 100];

impl Plan {
    /// Rejects plans that would measure nothing.
    pub fn validate(&self) -> Result<()> {
        let bad = |reason: &str| {
            Err(Error::InvalidConfig {
                what: "bench".into(),
                reason: reason.to_owned(),
            })
        };
        if self.settings.repeats == 0 {
            return bad("--repeats must be at least 1");
        }
        if self.settings.repeats > MAX_RUNS || self.settings.warmup > MAX_RUNS {
            return bad(&format!(
                "--repeats and --warmup must be at most {MAX_RUNS} each (runs of every \
                 measurement), got {} and {}",
                self.settings.repeats, self.settings.warmup
            ));
        }
        if self.settings.steps == 0 {
            return bad("--steps must be at least 1");
        }
        if self.settings.spheres < 2 {
            return bad("--spheres must be at least 2");
        }
        mochi::check_count(self.settings.spheres)?;
        mochi::check_count(self.settings.max_spheres)?;
        if self.settings.experiments.contains(&Experiment::Scaling)
            && self.settings.max_spheres < 1000
        {
            return bad("--max-spheres must be at least 1000 (scaling starts at 1,000)");
        }
        if self.backends.is_empty() {
            return bad("no backend to run");
        }
        Ok(())
    }

    /// Timed steps per run of `experiment`: the whole drop ([`DROP_STEPS`]) for experiment 8,
    /// else `--steps`.
    pub fn steps_of(&self, experiment: Experiment) -> u32 {
        match experiment {
            Experiment::Clustered => DROP_STEPS,
            _ => self.settings.steps,
        }
    }

    /// Sphere counts of the scaling experiment: 1,000, 10,000, … up to `max_spheres`.
    pub fn scaling_sizes(&self) -> Vec<usize> {
        std::iter::successors(Some(1000usize), |n| n.checked_mul(10))
            .take_while(|&n| n <= self.settings.max_spheres)
            .collect()
    }

    /// Measurements the plan makes (rows, at most), for a progress bar.
    pub fn units(&self) -> u64 {
        let per_backend: usize = self
            .settings
            .experiments
            .iter()
            .map(|e| match e {
                Experiment::Dcd => 6,
                Experiment::Freefall | Experiment::Rotating => 1,
                Experiment::Rebuild => REBUILD_INTERVALS.len() + 1,
                Experiment::Scaling => self.scaling_sizes().len(),
                // Settling, slab, pouring, polylog with two structures, polylog in nns mode.
                Experiment::Targets => 6,
                // Settling, the slab; pouring, the polylog pile.
                Experiment::Friction => 2 + 2 * (self.settings.pour > 0) as usize,
                // The drop in its box and in the wide box, each with both grid builds
                // (wgpu-compute; one row each elsewhere).
                Experiment::Clustered => 4,
            })
            .sum();
        (per_backend * self.backends.len()) as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn experiments_parse_by_name_and_number() {
        assert_eq!(Experiment::parse("1"), Ok(Experiment::Dcd));
        assert_eq!(Experiment::parse("Rebuild"), Ok(Experiment::Rebuild));
        assert_eq!(Experiment::parse("5"), Ok(Experiment::Scaling));
        assert_eq!(Experiment::parse("6"), Ok(Experiment::Targets));
        assert_eq!(Experiment::parse("friction"), Ok(Experiment::Friction));
        assert_eq!(Experiment::parse("7"), Ok(Experiment::Friction));
        assert_eq!(Experiment::parse("clustered"), Ok(Experiment::Clustered));
        assert_eq!(Experiment::parse("8"), Ok(Experiment::Clustered));
        assert!(Experiment::parse("9").unwrap_err().contains("unknown"));
    }

    #[test]
    fn backend_lists_parse() {
        let s: BackendSelection = "cpu, wgpu-compute".parse().unwrap();
        assert_eq!(
            s,
            BackendSelection::List(vec![BackendKind::Cpu, BackendKind::WgpuCompute])
        );
        assert!("cpu,gpu".parse::<BackendSelection>().is_err());
        let e = "cpu,gpu".parse::<BackendSelection>().unwrap_err();
        assert!(
            e.contains("`gpu`: use auto, all, or names from optix, wgpu-rq, wgpu-compute, cpu"),
            "{e}"
        );
    }

    #[test]
    fn scaling_goes_up_tenfold_to_the_maximum() {
        let plan = Plan {
            backends: vec![BackendKind::Cpu],
            settings: Settings {
                experiments: vec![Experiment::Scaling],
                spheres: 10,
                max_spheres: 250_000,
                steps: 1,
                settle: 0,
                pile: None,
                pour: 0,
                repeats: 1,
                warmup: 0,
                structure: Structure::Auto,
                seed: 1,
                mesh: None,
            },
        };
        assert_eq!(plan.scaling_sizes(), vec![1000, 10_000, 100_000]);
        assert_eq!(plan.units(), 3);
    }
}
