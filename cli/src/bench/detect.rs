//! Experiment 1: detection only, each radius ratio in both proxy modes.

use super::Outcome;
use super::plan::{Experiment, Plan};
use super::report::{DetectRow, pairs_digest};
use super::stats::Spread;
use mochi::Backend;
use mochi::Result;
use mochi::SphereSet;
use mochi::dem::Clock;
use mochi::dem::scene::SceneKind;
use mochi::engines::{BackendKind, Options};
use mochi::proxy::ProxyMode;
use mochi::scenes::{self, Layout, Scene, SceneSpec};
use std::time::Instant;

/// The scenes of experiment 1 (paper dataset 2): radius ratios 1.2, 12 and 120.
pub const SCENES: [Scene; 3] = [Scene::Poly1_2, Scene::Poly12, Scene::Poly120];

/// The generated sphere sets of experiment 1, in [`SCENES`] order (uniform centres, so that
/// there are pairs to find).
pub fn scenes(plan: &Plan) -> Result<Vec<(SceneSpec, SphereSet)>> {
    SCENES
        .into_iter()
        .map(|scene| {
            let spec = SceneSpec {
                scene,
                n: plan.settings.spheres,
                seed: plan.settings.seed,
                layout: Layout::Random,
            };
            Ok((spec, scenes::generate(&spec)?))
        })
        .collect()
}

/// Runs experiment 1 on backend `kind`, calling `progress` before each measurement.
pub fn run(
    plan: &Plan,
    kind: BackendKind,
    sets: &[(SceneSpec, SphereSet)],
    progress: &mut dyn FnMut(&str),
) -> Vec<Outcome<DetectRow>> {
    let options = Options {
        structure: plan.settings.structure,
        ..Options::default()
    };
    let mut backend = match kind.open_with(&options) {
        Ok(b) => b,
        Err(e) => {
            let what = format!("{} detection", kind.name());
            return vec![Outcome::Skipped(what, e.to_string())];
        }
    };
    let mut out = Vec::new();
    for (spec, spheres) in sets {
        for mode in [ProxyMode::Mochi, ProxyMode::Nns] {
            let what = format!(
                "{} {} n={} {}",
                kind.name(),
                spec.scene.name(),
                spec.n,
                mode.name()
            );
            progress(&what);
            out.push(
                match measure(plan, kind, backend.as_mut(), spec, spheres, mode) {
                    Ok(row) => Outcome::Row(row),
                    Err(e) => Outcome::Skipped(what, e.to_string()),
                },
            );
        }
    }
    out
}

/// One build + find_pairs, timed on the wall clock and, where the backend has them, on GPU
/// timestamps.
struct Sample {
    wall_build: f64,
    wall_detect: f64,
    gpu_build: Option<f64>,
    gpu_detect: Option<f64>,
}

fn once(
    backend: &mut dyn Backend,
    spheres: &SphereSet,
    mode: ProxyMode,
) -> Result<(Sample, Vec<mochi::Pair>, mochi::DetectStats)> {
    let t = Instant::now();
    backend.build(spheres.view(), mode)?;
    backend.finish()?;
    let wall_build = ms(t);
    let t = Instant::now();
    let (pairs, stats) = backend.find_pairs()?;
    let wall_detect = ms(t);
    let gpu = backend.gpu_times();
    let sample = Sample {
        wall_build,
        wall_detect,
        gpu_build: gpu.build_ms,
        gpu_detect: gpu.detect_ms,
    };
    Ok((sample, pairs, stats))
}

fn measure(
    plan: &Plan,
    kind: BackendKind,
    backend: &mut dyn Backend,
    spec: &SceneSpec,
    spheres: &SphereSet,
    mode: ProxyMode,
) -> Result<DetectRow> {
    let info = backend.info();
    if spheres.len() as u64 > info.max_spheres {
        return Err(mochi::Error::TooLarge {
            what: format!("spheres for backend {}", info.name),
            got: spheres.len() as u64,
            limit: info.max_spheres,
        });
    }
    let mut found = None;
    let mut samples = Vec::with_capacity(plan.settings.repeats);
    for run in 0..plan.settings.warmup + plan.settings.repeats {
        let (sample, pairs, stats) = once(backend, spheres, mode)?;
        found.get_or_insert((pairs, stats));
        if run >= plan.settings.warmup {
            samples.push(sample);
        }
    }
    let (pairs, stats) = found.expect("a plan has at least one repeat");
    let gpu = samples
        .iter()
        .all(|s| s.gpu_build.is_some() && s.gpu_detect.is_some());
    // (build, detect) of each repeat on the chosen clock.
    let times: Vec<(f64, f64)> = samples
        .iter()
        .map(|s| match (s.gpu_build, s.gpu_detect) {
            (Some(b), Some(d)) if gpu => (b, d),
            _ => (s.wall_build, s.wall_detect),
        })
        .collect();
    let spread = |values: Vec<f64>| Spread::of(&values).expect("a plan has at least one repeat");
    Ok(DetectRow {
        experiment: Experiment::Dcd,
        backend: kind,
        device: info.device,
        scene: SceneKind::Generated(spec.scene),
        layout: spec.layout,
        n: spheres.len(),
        mode,
        structure: plan.settings.structure,
        candidates: stats.candidates,
        candidates_per_sphere: stats.candidates as f64 / spheres.len().max(1) as f64,
        pairs: stats.pairs,
        pairs_digest: pairs_digest(&pairs),
        clock: if gpu { Clock::Gpu } else { Clock::Wall },
        build_ms: spread(times.iter().map(|t| t.0).collect()),
        detect_ms: spread(times.iter().map(|t| t.1).collect()),
        total_ms: spread(times.iter().map(|t| t.0 + t.1).collect()),
        wall_total_ms: spread(
            samples
                .iter()
                .map(|s| s.wall_build + s.wall_detect)
                .collect(),
        ),
        detect_speedup_vs_nns: None,
        speedup_vs_cpu: None,
    })
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}
