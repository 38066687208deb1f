//! Issue 7's targets and issue 21's, checked against the rows of a report. A target is judged
//! only where the report measured what it names (its scene at its size); otherwise it says what
//! to run.

use super::plan::Experiment;
use super::report::{DemRow, Report};
use crate::dem::scene::SceneKind;
use crate::dem::scene::by_name;
use crate::engines::BackendKind;
use crate::proxy::ProxyMode;
use crate::scenes::Scene;
use serde::{Deserialize, Serialize};

/// One target and how the report meets it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Check {
    /// The target, in words.
    pub target: String,
    /// What was measured (backend, value, size).
    pub measured: String,
    /// Met, missed, or `None` where the report has no measurement at the target's size.
    pub met: Option<bool>,
}

/// The scenes the targets name.
const SLAB: SceneKind = SceneKind::Generated(Scene::Slab);
const POLYLOG: SceneKind = SceneKind::Generated(Scene::Polylog);
const POLY120: SceneKind = SceneKind::Generated(Scene::Poly120);

/// Spheres of the DEM targets.
const MILLION: usize = 1_000_000;

/// The whole drop of experiment 8 (the paper's bunnies fall and land in about this many steps).
const WHOLE_DROP_STEPS: u32 = 5000;

/// Every target of issues 7 and 21, checked against `report`.
pub fn check(report: &Report) -> Vec<Check> {
    vec![
        dem_target(
            report,
            SLAB,
            "landed slab 1M: full DEM step ≤ 0.45 ms on the fastest backend",
            0.45,
            // Only a slab that had steps to land is the landed slab.
            report.settings.settle > 0,
        ),
        dem_target(
            report,
            POLYLOG,
            "polylog 1M: full DEM step ≤ 0.5 ms (grid and mlgrid side by side)",
            0.5,
            true,
        ),
        five_million(report),
        detect_ratio_120(report),
        dem_dcd_ratio_120(report),
        cpu_poly120(report),
        mesh_drop(report),
        wide_box(report),
    ]
}

/// Experiment 8's rows in the meshes' own box (`wide`: in the box 10× wider), fastest first.
fn clustered(report: &Report, wide: bool) -> Vec<&DemRow> {
    let mut rows: Vec<&DemRow> = report
        .dem
        .iter()
        .filter(|r| r.experiment == Experiment::Clustered && r.box_scale.is_some() == wide)
        .collect();
    rows.sort_by(|a, b| a.total_ms.median.total_cmp(&b.total_ms.median));
    rows
}

/// Issue 21: the paper's 14 bunnies (a mesh given, a million spheres or more) dropped for the
/// whole drop, the fastest row at ≤ 0.12 ms a step with its build at ≤ 0.03.
fn mesh_drop(report: &Report) -> Check {
    let rows = clustered(report, false);
    let fastest = rows.first();
    let settings = &report.settings;
    let judged = settings.mesh.is_some() && settings.steps >= WHOLE_DROP_STEPS;
    Check {
        target: format!(
            "14 meshes dropped (experiment 8, --mesh, ≥ 1M spheres, --steps {WHOLE_DROP_STEPS}): \
             full DEM step ≤ 0.12 ms, build ≤ 0.03 ms"
        ),
        measured: fastest.map_or_else(
            || "not measured (experiment 8)".to_owned(),
            |r| {
                format!(
                    "{} {} n={} over {} steps: {:.3} ms, build {:.3} ms",
                    r.backend.name(),
                    r.setup(),
                    r.n,
                    r.steps,
                    r.total_ms.median,
                    r.build_ms.median
                )
            },
        ),
        met: fastest
            .filter(|r| judged && r.n >= MILLION)
            .map(|r| r.total_ms.median <= 0.12 && r.build_ms.median <= 0.03),
    }
}

/// Issue 21: the same spheres in a box 10× wider per side, the fastest row within 10 % of the
/// fastest in their own box.
fn wide_box(report: &Report) -> Check {
    let (own, wide) = (clustered(report, false), clustered(report, true));
    let pair = own.first().zip(wide.first());
    Check {
        target: "experiment 8 in a box 10× wider: full DEM step within 10 % of its own box's"
            .to_owned(),
        measured: pair.map_or_else(
            || "not measured (experiment 8)".to_owned(),
            |(own, wide)| {
                format!(
                    "{} {}: {:.3} ms against {} {}: {:.3} ms",
                    wide.backend.name(),
                    wide.setup(),
                    wide.total_ms.median,
                    own.backend.name(),
                    own.setup(),
                    own.total_ms.median
                )
            },
        ),
        met: pair.map(|(own, wide)| wide.total_ms.median <= 1.1 * own.total_ms.median),
    }
}

/// The fastest experiment-6 row of `scene` at 1M spheres against `limit_ms` (judged only where
/// `judged`).
fn dem_target(
    report: &Report,
    scene: SceneKind,
    target: &str,
    limit_ms: f64,
    judged: bool,
) -> Check {
    let rows: Vec<&DemRow> = report
        .dem
        .iter()
        .filter(|r| {
            r.experiment == Experiment::Targets && r.scene == scene && r.mode == ProxyMode::Mochi
        })
        .collect();
    let listed = rows
        .iter()
        .map(|r| {
            format!(
                "{} {} n={}: {:.3} ms",
                r.backend.name(),
                by_name::name(&r.structure),
                r.n,
                r.total_ms.median
            )
        })
        .collect::<Vec<_>>()
        .join("; ");
    let fastest = rows
        .iter()
        .filter(|r| r.n == MILLION)
        .map(|r| r.total_ms.median)
        .min_by(f64::total_cmp);
    Check {
        target: target.to_owned(),
        measured: if listed.is_empty() {
            "not measured (experiment 6)".to_owned()
        } else {
            listed
        },
        met: fastest.filter(|_| judged).map(|t| t <= limit_ms),
    }
}

/// Whether a DEM run of 5M or more spheres completed.
fn five_million(report: &Report) -> Check {
    let ran = report.dem.iter().find(|r| r.n >= 5 * MILLION);
    Check {
        target: "5M spheres fit and run".to_owned(),
        measured: ran.map_or_else(
            || "not run (e.g. --spheres 5000000 --experiments freefall)".to_owned(),
            |r| {
                format!(
                    "{} n={}: {:.3} ms/step",
                    r.backend.name(),
                    r.n,
                    r.total_ms.median
                )
            },
        ),
        met: ran.map(|_| true),
    }
}

/// "mochi ≥ 3× faster than nns at radius ratio 120, every backend", judged at 1M spheres on
/// `speedups` (backend, size, speed-up).
fn at_ratio_120(target: &str, missing: &str, speedups: &[(&str, usize, f64)]) -> Check {
    let at_million: Vec<f64> = speedups
        .iter()
        .filter(|(_, n, _)| *n == MILLION)
        .map(|s| s.2)
        .collect();
    Check {
        target: target.to_owned(),
        measured: if speedups.is_empty() {
            missing.to_owned()
        } else {
            speedups
                .iter()
                .map(|(b, n, s)| format!("{b} n={n}: {s:.2}×"))
                .collect::<Vec<_>>()
                .join("; ")
        },
        met: (!at_million.is_empty()).then(|| at_million.iter().all(|s| *s >= 3.0)),
    }
}

/// Experiment 1, `poly120`: the detection of mochi mode against nns mode.
fn detect_ratio_120(report: &Report) -> Check {
    let speedups: Vec<(&str, usize, f64)> = report
        .detect
        .iter()
        .filter(|r| r.scene == POLY120)
        .filter_map(|r| Some((r.backend.name(), r.n, r.detect_speedup_vs_nns?)))
        .collect();
    at_ratio_120(
        "detection in mochi mode ≥ 3× faster than nns at radius ratio 120 (poly120), every backend",
        "not measured (experiment 1)",
        &speedups,
    )
}

/// Experiment 6, `polylog` (radius ratio 120): the DEM step's DCD phase, the fastest mochi
/// structure of each backend against its nns row.
fn dem_dcd_ratio_120(report: &Report) -> Check {
    let polylog = |mode: ProxyMode| {
        report.dem.iter().filter(move |r| {
            r.experiment == Experiment::Targets && r.scene == POLYLOG && r.mode == mode
        })
    };
    let speedups: Vec<(&str, usize, f64)> = polylog(ProxyMode::Nns)
        .filter_map(|nns| {
            let mochi = polylog(ProxyMode::Mochi)
                .filter(|m| m.backend == nns.backend && m.n == nns.n)
                .map(|m| m.dcd_ms.median)
                .min_by(f64::total_cmp)?;
            Some((nns.backend.name(), nns.n, nns.dcd_ms.median / mochi))
        })
        .collect();
    at_ratio_120(
        "DEM DCD phase in mochi mode ≥ 3× faster than nns at radius ratio 120 (polylog), every \
         backend",
        "not measured (experiment 6)",
        &speedups,
    )
}

/// Experiment 1 on the cpu backend: 100k poly120 spheres built and detected in ≤ 7 ms (the
/// target is for 2 cores; the row says how many threads ran).
fn cpu_poly120(report: &Report) -> Check {
    let row = report.detect.iter().find(|r| {
        r.backend == BackendKind::Cpu && r.scene == POLY120 && r.mode == ProxyMode::Mochi
    });
    Check {
        target: "cpu backend, 2 cores, 100k poly120: build + detect ≤ 7 ms".to_owned(),
        measured: row.map_or_else(
            || "not measured (experiment 1 on cpu)".to_owned(),
            |r| {
                format!(
                    "n={}, {} threads: {:.2} ms",
                    r.n, report.machine.threads, r.total_ms.median
                )
            },
        ),
        met: row
            .filter(|r| r.n == 100_000 && report.machine.threads == 2)
            .map(|r| r.total_ms.median <= 7.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::plan::{BackendStatus, Settings};
    use crate::bench::report::{Machine, SCHEMA_VERSION};
    use crate::bench::stats::Spread;
    use crate::dem::Clock;
    use crate::engines::wgpu_compute::Structure;
    use clap::ValueEnum;

    fn ms(v: f64) -> Spread {
        Spread::of(&[v]).unwrap()
    }

    fn row(scene: &str, mode: &str, structure: &str, dcd: f64, total: f64) -> DemRow {
        DemRow {
            experiment: Experiment::Targets,
            backend: BackendKind::WgpuCompute,
            device: "GPU".into(),
            scene: scene.parse().unwrap(),
            n: MILLION,
            mode: ProxyMode::from_str(mode, false).unwrap(),
            structure: Structure::from_str(structure, false).unwrap(),
            rebuild: "every step".into(),
            refits: false,
            steps: 10,
            contacts: 0,
            clock: Clock::Gpu,
            build_ms: ms(total - dcd),
            dcd_ms: ms(dcd),
            update_ms: ms(0.0),
            total_ms: ms(total),
            wall_ms: ms(total),
            speedup_vs_cpu: None,
            history: None,
            box_scale: None,
            grid_build: None,
        }
    }

    fn report(settle: u32) -> Report {
        Report {
            schema_version: SCHEMA_VERSION,
            mochi_version: "0".into(),
            date: "2026-11-22T00:00:00Z".into(),
            command: "mochi bench".into(),
            machine: Machine::here(),
            settings: Settings {
                experiments: vec![Experiment::Targets],
                spheres: MILLION,
                max_spheres: MILLION,
                steps: 10,
                settle,
                pour: 0,
                repeats: 1,
                warmup: 0,
                structure: Structure::Auto,
                seed: 1,
                mesh: None,
            },
            backends: Vec::<BackendStatus>::new(),
            detect: Vec::new(),
            dem: vec![
                row("slab", "mochi", "auto", 0.2, 0.4),
                row("polylog", "mochi", "grid", 1.7, 1.9),
                row("polylog", "mochi", "mlgrid", 0.3, 0.55),
                row("polylog", "nns", "grid", 6.9, 7.0),
            ],
            skipped: Vec::new(),
            targets: Vec::new(),
        }
    }

    #[test]
    fn targets_are_judged_on_the_fastest_row_at_their_size() {
        let checks = check(&report(3000));
        let met: Vec<Option<bool>> = checks.iter().map(|c| c.met).collect();
        // slab met, polylog missed (mlgrid 0.55 > 0.5), no 5M, no detection rows, DEM DCD
        // 6.9 / 0.3 = 23× met, no cpu row.
        assert_eq!(
            met,
            [
                Some(true),
                Some(false),
                None,
                None,
                Some(true),
                None,
                None,
                None
            ]
        );
        assert!(checks[1].measured.contains("mlgrid"), "{:?}", checks[1]);
        assert!(checks[4].measured.contains("23.00×"), "{:?}", checks[4]);
        // A slab that never had steps to land is not judged.
        assert_eq!(check(&report(0))[0].met, None);
    }

    /// Experiment 8's rows: the dense and the sorted build, in the own box and the wide one.
    fn clustered_report(steps: u32, mesh: bool, dense: f64, wide: f64) -> Report {
        let mut r = report(0);
        r.settings.steps = steps;
        r.settings.mesh = mesh.then(|| "bunny.obj".into());
        r.dem.clear();
        for (box_scale, build, total) in [
            (None, "dense", dense),
            (None, "sorted", 0.6),
            (Some(10), "dense", wide),
            (Some(10), "sorted", 0.6),
        ] {
            let mut row = row("mesh", "mochi", "auto", 0.07, total);
            row.experiment = Experiment::Clustered;
            row.n = 1_151_878;
            row.build_ms = ms(0.005);
            row.box_scale = box_scale;
            row.grid_build = Some(build.into());
            r.dem.push(row);
        }
        r
    }

    #[test]
    fn the_mesh_drop_is_judged_over_the_whole_drop_and_the_wide_box_against_its_own() {
        let judged = |steps, mesh, dense, wide| {
            let checks = check(&clustered_report(steps, mesh, dense, wide));
            (checks[6].met, checks[7].met)
        };
        assert_eq!(judged(5000, true, 0.113, 0.115), (Some(true), Some(true)));
        assert_eq!(judged(5000, true, 0.125, 0.14), (Some(false), Some(false)));
        // 200 steps are not the whole drop, and the built-in torus is not the paper's bunny.
        assert_eq!(judged(200, true, 0.113, 0.115), (None, Some(true)));
        assert_eq!(judged(5000, false, 0.113, 0.115), (None, Some(true)));
        let checks = check(&clustered_report(5000, true, 0.113, 0.115));
        assert!(
            checks[6].measured.contains("dense build"),
            "{:?}",
            checks[6]
        );
        assert!(checks[7].measured.contains("box ×10"), "{:?}", checks[7]);
    }
}
