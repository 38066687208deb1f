//! `mochi bench`: the paper's experiments (docs/method.md, "The paper's workloads") on every backend, measured the same way
//! every time.
//!
//! 1. detection only, `mochi` vs `nns` mode at radius ratios 1.2, 12 and 120 ([`detect`]);
//! 2. the DEM step on dataset 1 falling freely, build / DCD / update per step;
//! 3. the same under rotating gravity;
//! 4. the DEM step against the rebuild interval of steps that refit (others are reported once,
//!    "every step");
//! 5. the DEM step from 1,000 spheres up, ×10 each time;
//! 6. the DEM steps the performance targets name: the landed `slab`, and the poured `polylog`
//!    pile ([`dem::pile_start`]) with the single and the multi-level grid side by side ([`dem`]
//!    runs 2–8; [`targets`] checks them, each on a state with contacts only);
//! 7. the Hertz–Mindlin step (friction with contact history, rotation, EPSD rolling
//!    resistance) on the landed `slab`, with its contacts and the bytes per sphere of its
//!    history ([`report::HistorySize`]); a backend whose step does not run it yet reports why;
//! 8. the clustered scenes: 14 filled meshes dropped ([`dem::mesh_drop_start`]) at the
//!    paper's dt 1e-4, every step of the 5,000-step drop timed from the start, in their box and
//!    in one 10× wider per side; `wgpu-compute` with its dense and its sorted grid build side
//!    by side.
//!
//! [`Experiment::workload`](plan::Experiment::workload) states each experiment's workload
//! exactly, and every DEM row its time step, the steps before the timed ones and the steps timed.
//!
//! Every measurement runs `warmup` untimed times, then `repeats` timed times, and reports the
//! median and spread ([`stats::Spread`]) on GPU timestamps where the backend has them, else on
//! the wall clock, and says which ([`mochi::dem::Clock`]). A [`report::Report`] holds the rows;
//! [`markdown`] prints it and [`plot`] draws it as SVG.

pub mod compare;
pub mod dem;
pub mod detect;
pub mod markdown;
pub mod plan;
pub mod plot;
pub mod report;
pub mod stats;
pub mod targets;

use mochi::Result;
use mochi::dem::scene::{SceneKind, Start};
use mochi::engines::BackendKind;
use mochi::engines::wgpu::compute::{GridBuild, Structure};
use mochi::proxy::ProxyMode;
use mochi::scenes::Scene;
use plan::{BackendStatus, Experiment, Plan};
use report::{Machine, Report, SCHEMA_VERSION, Skipped, utc_now};

/// The scene of experiment 6 measured with the single and the multi-level grid.
const POLYLOG: SceneKind = SceneKind::Generated(Scene::Polylog);

/// A measurement made, or why it could not be.
pub enum Outcome<T> {
    /// The row.
    Row(T),
    /// What was to be measured, and why it was not.
    Skipped(String, String),
}

/// Runs `plan`, calling `progress` before each measurement; `backends` (from
/// [`plan::BackendSelection::resolve`]) and `command` go into the report as they are.
pub fn run(
    plan: &Plan,
    backends: Vec<BackendStatus>,
    command: String,
    progress: &mut dyn FnMut(&str),
) -> Result<Report> {
    plan.validate()?;
    // The pile's pouring steps as they will be run, so that the report says them.
    let mut resolved = plan.clone();
    if plan.settings.experiments.contains(&Experiment::Targets) && plan.settings.pile.is_none() {
        let layers = dem::pile_start(plan.settings.spheres, plan.settings.seed)?;
        resolved.settings.pile = Some(dem::pour_steps(&layers));
    }
    let plan = &resolved;
    let mut report = Report {
        schema_version: SCHEMA_VERSION,
        mochi_version: env!("CARGO_PKG_VERSION").to_owned(),
        date: utc_now(),
        command,
        machine: Machine::here(),
        settings: plan.settings.clone(),
        backends,
        detect: Vec::new(),
        dem: Vec::new(),
        skipped: Vec::new(),
        targets: Vec::new(),
        comparisons: Vec::new(),
    };
    for &experiment in &plan.settings.experiments {
        let mut skip = |backend: BackendKind, what: String, reason: String| {
            report.skipped.push(Skipped {
                experiment,
                backend,
                what,
                reason,
            })
        };
        match experiment {
            Experiment::Dcd => {
                let sets = detect::scenes(plan)?;
                for &kind in &plan.backends {
                    for outcome in detect::run(plan, kind, &sets, progress) {
                        match outcome {
                            Outcome::Row(row) => report.detect.push(row),
                            Outcome::Skipped(what, why) => skip(kind, what, why),
                        }
                    }
                }
            }
            _ => {
                for (scene, start, box_scale) in dem_starts(plan, experiment, progress)? {
                    for &kind in &plan.backends {
                        for structure in structures(plan, experiment, scene, &start, kind) {
                            for grid_build in grid_builds(experiment, kind) {
                                let case = dem::Case {
                                    experiment,
                                    scene,
                                    start: &start,
                                    structure,
                                    grid_build,
                                    box_scale,
                                };
                                for outcome in dem::run(plan, kind, &case, progress) {
                                    match outcome {
                                        Outcome::Row(row) => report.dem.push(row),
                                        Outcome::Skipped(what, why) => skip(kind, what, why),
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    report.fill_speedups();
    report.targets = targets::check(&report);
    Ok(report)
}

/// The scenes of DEM experiment `experiment`, with their starts and their boxes per side over
/// the scene's own (`None`: its own).
fn dem_starts(
    plan: &Plan,
    experiment: Experiment,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<(SceneKind, Start, Option<u32>)>> {
    if experiment == Experiment::Clustered {
        progress("filling the meshes");
        let n = plan.settings.spheres;
        let seed = plan.settings.seed;
        let own = dem::mesh_drop_start(plan.settings.mesh.as_deref(), n, seed)?;
        let wide = dem::widened(&own, plan::WIDE_BOX_SCALE);
        return Ok(vec![
            (SceneKind::Mesh, own, None),
            (SceneKind::Mesh, wide, Some(plan::WIDE_BOX_SCALE)),
        ]);
    }
    let starts = own_box_starts(plan, experiment, progress)?;
    Ok(starts.into_iter().map(|(k, s)| (k, s, None)).collect())
}

/// [`dem_starts`] of the experiments whose scenes keep their own boxes.
fn own_box_starts(
    plan: &Plan,
    experiment: Experiment,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<(SceneKind, Start)>> {
    let n = plan.settings.spheres;
    let seed = plan.settings.seed;
    let freefall = SceneKind::Generated(Scene::Freefall);
    Ok(match experiment {
        Experiment::Targets => {
            let slab_scene = SceneKind::Generated(Scene::Slab);
            let mut slab = dem::start(slab_scene, n, seed)?;
            if plan.settings.settle > 0 {
                progress(&format!(
                    "letting the slab land ({} steps)",
                    plan.settings.settle
                ));
                slab = dem::settle(plan, &slab, plan.settings.settle as u64)?;
            }
            // The pile the polylog claims are made on: poured, with its contacts (a target is
            // judged only on a state with contacts).
            let layers = dem::pile_start(n, seed)?;
            let pour = plan
                .settings
                .pile
                .unwrap_or_else(|| dem::pour_steps(&layers));
            progress(&format!("pouring the polylog pile ({pour} steps)"));
            let polylog = match pour {
                0 => layers,
                _ => dem::settle(plan, &layers, pour)?,
            };
            // nns mode too: the DCD phase at radius ratio 120 in both modes, on the same pile.
            let nns = Start {
                mode: ProxyMode::Nns,
                ..polylog.clone()
            };
            vec![(slab_scene, slab), (POLYLOG, polylog), (POLYLOG, nns)]
        }
        Experiment::Friction => {
            let slab = SceneKind::Generated(Scene::Slab);
            let mut pile = dem::friction_start(n, seed)?;
            if plan.settings.settle > 0 {
                progress(&format!(
                    "letting the frictional slab land ({} steps)",
                    plan.settings.settle
                ));
                pile = dem::settle(plan, &pile, plan.settings.settle as u64)?;
            }
            let mut starts = vec![(slab, pile)];
            if plan.settings.pour > 0 {
                progress(&format!(
                    "pouring the polylog pile under Hertz–Mindlin ({} steps)",
                    plan.settings.pour
                ));
                let poured = dem::friction_polylog_start(n, seed)?;
                starts.push((POLYLOG, dem::settle(plan, &poured, plan.settings.pour)?));
            }
            starts
        }
        Experiment::Scaling => plan
            .scaling_sizes()
            .into_iter()
            .map(|n| Ok((freefall, dem::start(freefall, n, seed)?)))
            .collect::<Result<_>>()?,
        Experiment::Rotating => {
            let rotating = SceneKind::Rotating;
            vec![(rotating, dem::start(rotating, n, seed)?)]
        }
        _ => vec![(freefall, dem::start(freefall, n, seed)?)],
    })
}

/// The `wgpu-compute` grid builds to measure with: in experiment 8 the dense and the sorted
/// build side by side, else `auto`.
fn grid_builds(experiment: Experiment, kind: BackendKind) -> Vec<GridBuild> {
    if experiment == Experiment::Clustered && kind == BackendKind::WgpuCompute {
        vec![GridBuild::Dense, GridBuild::Sorted]
    } else {
        vec![GridBuild::Auto]
    }
}

/// The `wgpu-compute` structures to measure `scene` with: for `polylog` in `mochi` mode in
/// experiment 6 the single and the multi-level grid side by side, else the plan's (other
/// backends have one structure, and `nns` mode has only the single grid).
fn structures(
    plan: &Plan,
    experiment: Experiment,
    scene: SceneKind,
    start: &Start,
    kind: BackendKind,
) -> Vec<Structure> {
    if experiment == Experiment::Targets
        && scene == POLYLOG
        && start.mode == ProxyMode::Mochi
        && kind == BackendKind::WgpuCompute
    {
        vec![Structure::Grid, Structure::Mlgrid]
    } else {
        vec![plan.settings.structure]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mochi::names::by_name;

    #[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
    struct Row {
        #[serde(with = "by_name")]
        backend: BackendKind,
    }

    #[test]
    fn backends_are_written_and_read_by_their_names() {
        for backend in BackendKind::ALL {
            let json = serde_json::to_string(&Row { backend }).unwrap();
            assert_eq!(json, format!("{{\"backend\":\"{}\"}}", backend.name()));
            assert_eq!(serde_json::from_str::<Row>(&json).unwrap(), Row { backend });
        }
        let e = serde_json::from_str::<Row>(r#"{"backend":"gpu"}"#).unwrap_err();
        let e = e.to_string();
        assert!(
            e.contains("\"gpu\"") && e.contains("optix, wgpu-rq, wgpu-compute or cpu"),
            "{e}"
        );
    }
}
