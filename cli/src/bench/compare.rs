//! `mochi bench --compare FILE`: other codes' figures (a JSON list that the comparison runs
//! write) beside mochi's measured rows of the same experiment, with the ratio where the two
//! measured the same size.
//!
//! ```json
//! [{"experiment": "clustered", "peer": "Taichi", "ms_per_step": 0.983,
//!   "workload": "14 bunnies dropped, 5,000 steps at dt 1e-4, gravity -z",
//!   "spheres": 1151878, "device": "H100", "date": "2026-11-28"}]
//! ```
//!
//! `experiment` is a DEM experiment's name (`freefall` … `clustered`), `peer`, `ms_per_step`
//! (positive) and `workload` (the peer's workload in words, never empty) are required; `scene`
//! (picks the rows of one scene, e.g. `polylog` in `targets`), `spheres` (the peer's count: mochi's
//! row must have as many to be compared), `contacts`, `device`, `date` and `commit` are optional.

use super::plan::Experiment;
use super::report::{Comparison, DemRow, PeerFigure, Report, thousands};
use mochi::proxy::ProxyMode;
use mochi::{Error, Result};
use std::path::Path;

/// Reads and checks the figures of `path`.
pub fn read(path: &Path) -> Result<Vec<PeerFigure>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::InvalidConfig {
        what: format!("--compare {}", path.display()),
        reason: format!("cannot read it: {e}"),
    })?;
    parse(&text).map_err(|reason| Error::InvalidConfig {
        what: format!("--compare {}", path.display()),
        reason,
    })
}

/// The figures of a JSON list, checked: every one names a DEM experiment, a peer, a positive
/// time and its workload.
pub fn parse(text: &str) -> std::result::Result<Vec<PeerFigure>, String> {
    let figures: Vec<PeerFigure> = serde_json::from_str(text).map_err(|e| {
        format!(
            "{e} (expected a JSON list of {{\"experiment\", \"peer\", \"ms_per_step\", \
             \"workload\"}} objects, optionally with \"scene\", \"spheres\", \"contacts\", \
             \"device\", \"date\", \"commit\")"
        )
    })?;
    if figures.is_empty() {
        return Err("the list has no figures".to_owned());
    }
    for (k, f) in figures.iter().enumerate() {
        let bad = |why: String| Err(format!("figure {} ({}): {why}", k + 1, f.peer.trim()));
        if f.experiment == Experiment::Dcd {
            return bad(
                "experiment dcd times detection, not a step: compare a DEM experiment \
                 (freefall, rotating, rebuild, scaling, targets, friction, clustered)"
                    .to_owned(),
            );
        }
        if f.peer.trim().is_empty() {
            return bad("\"peer\" is empty: name the other code".to_owned());
        }
        if !(f.ms_per_step.is_finite() && f.ms_per_step > 0.0) {
            return bad(format!(
                "\"ms_per_step\" must be a positive number, got {}",
                f.ms_per_step
            ));
        }
        if f.workload.trim().is_empty() {
            return bad(
                "\"workload\" is empty: say what the other code ran (scene, spheres, dt, steps \
                 timed)"
                    .to_owned(),
            );
        }
        if f.spheres == Some(0) {
            return bad("\"spheres\" must be at least 1".to_owned());
        }
    }
    Ok(figures)
}

/// Each figure beside mochi's fastest row of its experiment (and scene) in `mochi` mode in the
/// scene's own box, at the figure's size where it says one.
pub fn compare(report: &Report, figures: &[PeerFigure]) -> Vec<Comparison> {
    figures.iter().map(|f| beside(report, f)).collect()
}

fn beside(report: &Report, f: &PeerFigure) -> Comparison {
    let fastest = |rows: &mut dyn Iterator<Item = &DemRow>| {
        rows.min_by(|a, b| a.total_ms.median.total_cmp(&b.total_ms.median))
            .cloned()
    };
    let rows = || {
        report.dem.iter().filter(|r| {
            r.experiment == f.experiment
                && r.mode == ProxyMode::Mochi
                && r.box_scale.is_none()
                && f.scene.is_none_or(|s| r.scene == s)
        })
    };
    let at_size = fastest(&mut rows().filter(|r| f.spheres.is_none_or(|n| r.n == n)));
    let any = fastest(&mut rows());
    let (row, note) = match (at_size, any) {
        (Some(row), _) => {
            let note = match f.spheres {
                None => Some(format!(
                    "the peer does not say its spheres; mochi's row has {}",
                    thousands(row.n as u64)
                )),
                Some(_) => None,
            };
            (Some(row), note)
        }
        (None, Some(row)) => {
            let note = format!(
                "not compared: mochi ran {} spheres, the peer {}",
                thousands(row.n as u64),
                thousands(f.spheres.unwrap_or_default() as u64)
            );
            return Comparison {
                peer: f.clone(),
                mochi: described(&row),
                mochi_ms_per_step: Some(row.total_ms.median),
                mochi_faster: None,
                note: Some(note),
            };
        }
        (None, None) => (None, None),
    };
    match row {
        Some(row) => {
            let note = match (row.contacts, note) {
                (0, note) => Some(
                    [note, Some("mochi's row ends without contacts".to_owned())]
                        .into_iter()
                        .flatten()
                        .collect::<Vec<_>>()
                        .join("; "),
                ),
                (_, note) => note,
            };
            Comparison {
                peer: f.clone(),
                mochi: described(&row),
                mochi_ms_per_step: Some(row.total_ms.median),
                mochi_faster: Some(f.ms_per_step / row.total_ms.median),
                note,
            }
        }
        None => Comparison {
            peer: f.clone(),
            mochi: format!(
                "not measured (experiment {}{})",
                f.experiment.number(),
                f.scene.map_or_else(String::new, |s| format!(", scene {s}"))
            ),
            mochi_ms_per_step: None,
            mochi_faster: None,
            note: None,
        },
    }
}

/// A row in words: backend, setup, spheres and [`DemRow::state`].
fn described(r: &DemRow) -> String {
    format!(
        "{} {} n={}, {}",
        r.backend.name(),
        r.setup(),
        r.n,
        r.state()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figures_parse_and_bad_ones_say_why() {
        let ok = r#"[{"experiment": "clustered", "peer": "Taichi", "ms_per_step": 0.983,
            "workload": "14 bunnies, 5000 steps at dt 1e-4", "device": "H100",
            "date": "2026-11-28"}]"#;
        let figures = parse(ok).unwrap();
        assert_eq!(figures[0].experiment, Experiment::Clustered);
        assert_eq!(figures[0].spheres, None);
        for (text, says) in [
            ("", "EOF"),
            ("{}", "expected a JSON list"),
            ("[]", "no figures"),
            (
                r#"[{"experiment": "clusterd", "peer": "T", "ms_per_step": 1, "workload": "w"}]"#,
                "unknown variant `clusterd`",
            ),
            (
                r#"[{"experiment": "dcd", "peer": "T", "ms_per_step": 1, "workload": "w"}]"#,
                "times detection",
            ),
            (
                r#"[{"experiment": "targets", "peer": "T", "ms_per_step": -1, "workload": "w"}]"#,
                "positive",
            ),
            (
                r#"[{"experiment": "targets", "peer": "T", "ms_per_step": 1, "workload": " "}]"#,
                "\"workload\" is empty",
            ),
            (
                r#"[{"experiment": "targets", "peer": "T", "ms_per_step": 1}]"#,
                "missing field `workload`",
            ),
            (
                r#"[{"experiment": "targets", "peer": "T", "ms_per_step": 1, "workload": "w",
                    "spehres": 5}]"#,
                "unknown field `spehres`",
            ),
            (
                r#"[{"experiment": "targets", "scene": "pile", "peer": "T", "ms_per_step": 1,
                    "workload": "w"}]"#,
                "pile",
            ),
        ] {
            let e = parse(text).unwrap_err();
            assert!(e.contains(says), "{text}: {e}");
        }
    }

    #[test]
    fn a_figure_is_set_beside_the_fastest_row_of_its_size() {
        let mut report = crate::bench::targets::tests::report(3000);
        let figures = parse(
            r#"[{"experiment": "targets", "scene": "polylog", "peer": "Taichi",
                 "ms_per_step": 4.061, "workload": "poured pile", "spheres": 1000000},
                {"experiment": "targets", "scene": "polylog", "peer": "Taichi",
                 "ms_per_step": 0.5, "workload": "poured pile", "spheres": 10000},
                {"experiment": "clustered", "peer": "Taichi", "ms_per_step": 0.983,
                 "workload": "14 bunnies"}]"#,
        )
        .unwrap();
        report.comparisons = compare(&report, &figures);
        let c = &report.comparisons;
        // The mlgrid row, 0.55 ms: 4.061 / 0.55.
        assert_eq!(c[0].mochi_ms_per_step, Some(0.55));
        assert!((c[0].mochi_faster.unwrap() - 4.061 / 0.55).abs() < 1e-12);
        assert!(c[0].mochi.contains("1,090,000 contacts"), "{:?}", c[0]);
        assert_eq!(c[0].note, None);
        // Another size: no ratio.
        assert_eq!(c[1].mochi_faster, None);
        assert!(
            c[1].note.as_deref().unwrap().contains("not compared"),
            "{:?}",
            c[1]
        );
        assert!(
            c[2].mochi.starts_with("not measured (experiment 8"),
            "{:?}",
            c[2]
        );
        let md = crate::bench::markdown::render(&report);
        assert!(md.contains("## Against other codes"), "{md}");
        assert!(md.contains("| 7.38× |"), "{md}");
    }
}
