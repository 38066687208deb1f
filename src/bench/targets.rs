//! Issue 7's targets, checked against the rows of a report. A target is judged only where the
//! report measured what it names (its scene at its size); otherwise it says what to run.

use super::plan::Experiment;
use super::report::{DemRow, Report};
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

/// Spheres of the DEM targets.
const MILLION: usize = 1_000_000;

/// Every target of issue 7, checked against `report`.
pub fn check(report: &Report) -> Vec<Check> {
    vec![
        dem_target(
            report,
            "slab",
            "landed slab 1M: full DEM step ≤ 0.45 ms on the fastest backend",
            0.45,
        ),
        dem_target(
            report,
            "polylog",
            "polylog 1M: full DEM step ≤ 0.5 ms (grid and mlgrid side by side)",
            0.5,
        ),
        five_million(report),
        mochi_vs_nns(report),
        cpu_poly120(report),
    ]
}

/// The fastest experiment-6 row of `scene` at 1M spheres against `limit_ms`.
fn dem_target(report: &Report, scene: &str, target: &str, limit_ms: f64) -> Check {
    let rows: Vec<&DemRow> = report
        .dem
        .iter()
        .filter(|r| r.experiment == Experiment::Targets && r.scene == scene)
        .collect();
    let listed = rows
        .iter()
        .map(|r| {
            format!(
                "{} {} n={}: {:.3} ms",
                r.backend, r.structure, r.n, r.total_ms.median
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
        met: fastest.map(|t| t <= limit_ms),
    }
}

/// Whether a DEM run of 5M or more spheres completed.
fn five_million(report: &Report) -> Check {
    let ran = report.dem.iter().find(|r| r.n >= 5 * MILLION);
    Check {
        target: "5M spheres fit and run".to_owned(),
        measured: ran.map_or_else(
            || "not run (e.g. --spheres 5000000 --experiments freefall)".to_owned(),
            |r| format!("{} n={}: {:.3} ms/step", r.backend, r.n, r.total_ms.median),
        ),
        met: ran.map(|_| true),
    }
}

/// Experiment 1 at radius ratio 120: mochi's detection ≥ 3× faster than nns, every backend.
fn mochi_vs_nns(report: &Report) -> Check {
    let speedups: Vec<(&str, f64)> = report
        .detect
        .iter()
        .filter(|r| r.scene == "poly120")
        .filter_map(|r| Some((r.backend.as_str(), r.detect_speedup_vs_nns?)))
        .collect();
    Check {
        target: "DCD in mochi mode ≥ 3× faster than nns at radius ratio 120, every backend"
            .to_owned(),
        measured: if speedups.is_empty() {
            "not measured (experiment 1)".to_owned()
        } else {
            speedups
                .iter()
                .map(|(b, s)| format!("{b}: {s:.2}×"))
                .collect::<Vec<_>>()
                .join("; ")
        },
        met: (!speedups.is_empty()).then(|| speedups.iter().all(|(_, s)| *s >= 3.0)),
    }
}

/// Experiment 1 on the cpu backend: 100k poly120 spheres built and detected in ≤ 7 ms (the
/// target is for 2 cores; the row says how many threads ran).
fn cpu_poly120(report: &Report) -> Check {
    let row = report
        .detect
        .iter()
        .find(|r| r.backend == "cpu" && r.scene == "poly120" && r.mode == "mochi");
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
