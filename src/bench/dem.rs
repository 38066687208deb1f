//! Experiments 2–5: the DEM step, timed per phase.

use super::Outcome;
use super::plan::{Experiment, Plan, REBUILD_INTERVALS};
use super::report::{DemRow, HistorySize};
use super::stats::Spread;
use crate::dem::scene::{ContactKind, SceneConfig, SceneKind, Start};
use crate::dem::{Clock, Stepper};
use crate::engines::open_stepper;
use crate::engines::wgpu_compute::{GridBuild, Structure};
use crate::engines::{BackendKind, Options, RebuildPolicy};
use crate::error::{Error, Result};
use crate::scenes::{SLAB_BASE, Scene};
use std::time::Instant;

/// The start of a generated DEM scene (`freefall`, `rotating`, `slab`, `polylog`) of `n`
/// spheres: the scene's lattice layout and the paper's law (`linear`, frictionless, its default
/// time step and derived stiffness), as the paper's experiments run it.
pub fn start(scene: SceneKind, n: usize, seed: u64) -> Result<Start> {
    SceneConfig {
        scene,
        spheres: n,
        seed,
        frame_every: 0,
        contact: ContactKind::Linear,
        ..SceneConfig::default()
    }
    .build()
}

/// The start of experiment 7: the `slab` of `n` spheres under Hertz–Mindlin with the default
/// material (friction, EPSD rolling resistance, its Rayleigh time step), with the floor raised
/// to the slab's underside so that it lands within the settling steps.
pub fn friction_start(n: usize, seed: u64) -> Result<Start> {
    SceneConfig {
        scene: SceneKind::Generated(Scene::Slab),
        spheres: n,
        seed,
        frame_every: 0,
        contact: ContactKind::HertzMindlin,
        box_lo: Some([0.0, 0.0, SLAB_BASE]),
        ..SceneConfig::default()
    }
    .build()
}

/// The second start of experiment 7: the `polylog` scene of `n` spheres (radii 0.5 mm–6 cm) under
/// Hertz–Mindlin with the default material and its Rayleigh time step, to be poured.
pub fn friction_polylog_start(n: usize, seed: u64) -> Result<Start> {
    SceneConfig {
        scene: SceneKind::Generated(Scene::Polylog),
        spheres: n,
        seed,
        frame_every: 0,
        contact: ContactKind::HertzMindlin,
        ..SceneConfig::default()
    }
    .build()
}

/// Spheres of the paper's 14-bunny scene (82,337 per bunny at radius 0.005 m).
const PAPER_MESH_DROP_SPHERES: f64 = 1_151_878.0;

/// Copies of the mesh in experiment 8, as in the paper's scene.
pub const MESH_DROP_COPIES: u32 = 14;

/// The wide box of experiment 8, per side over the scene's own.
pub const WIDE_BOX_SCALE: u32 = 10;

/// Sphere radius \[m\] at which one copy of the mesh is filled to count its spheres.
const PROBE_RADIUS: f64 = 0.005;

/// The start of experiment 8: [`MESH_DROP_COPIES`] copies of `mesh` (`None`: the `mesh`
/// scene's built-in torus; the paper's is the Stanford bunny), side by side on the floor of
/// their box, filled at the radius that gives them about the paper's 1,151,878 spheres scaled
/// by `n` / 1,000,000 (the bunny at `n` = 1,000,000: radius 0.005 m, the paper's scene), under
/// the paper's law (`linear`, frictionless, its default time step).
pub fn mesh_drop_start(mesh: Option<&std::path::Path>, n: usize, seed: u64) -> Result<Start> {
    let config = |radius: f64, copies| SceneConfig {
        scene: SceneKind::Mesh,
        mesh: mesh.map(std::path::Path::to_path_buf),
        mesh_radius: radius as f32,
        mesh_copies: copies,
        seed,
        frame_every: 0,
        contact: ContactKind::Linear,
        ..SceneConfig::default()
    };
    // Spheres per copy go as 1 / radius³ (a lattice of spacing 2.2 radii).
    let one = config(PROBE_RADIUS, 1).build()?.particles.len().max(1) as f64;
    let target = PAPER_MESH_DROP_SPHERES * n as f64 / 1e6;
    let radius = PROBE_RADIUS * (MESH_DROP_COPIES as f64 * one / target).cbrt();
    // To three significant figures: the bunny at n = 1,000,000 keeps the paper's 0.005 m.
    let digits = 10f64.powi(2 - radius.log10().floor() as i32);
    config((radius * digits).round() / digits, MESH_DROP_COPIES).build()
}

/// `start` in a box `scale` times wider per side, from the same lower corner: the same spheres,
/// the same step, walls farther away.
pub fn widened(start: &Start, scale: u32) -> Start {
    let mut wide = start.clone();
    let (lo, hi) = (start.params.box_lo, start.params.box_hi);
    wide.params.box_hi = std::array::from_fn(|a| lo[a] + (hi[a] - lo[a]) * scale as f32);
    wide
}

/// One DEM measurement to make.
pub struct Case<'a> {
    /// The experiment it belongs to.
    pub experiment: Experiment,
    /// The scene.
    pub scene: SceneKind,
    /// Its start.
    pub start: &'a Start,
    /// Grid structure of `wgpu-compute`.
    pub structure: Structure,
    /// How `wgpu-compute` builds its grid.
    pub grid_build: GridBuild,
    /// The box per side over the scene's own (`None`: its own).
    pub box_scale: Option<u32>,
}

/// `start` after `steps` untimed steps on the first of the plan's backends whose DEM step opens
/// (the others' reasons in the error when none does).
pub fn settle(plan: &Plan, start: &Start, steps: u64) -> Result<Start> {
    let mut reasons = Vec::new();
    for &kind in &plan.backends {
        let options = Options {
            structure: plan.settings.structure,
            ..Options::default()
        };
        let s = start.clone();
        match open_stepper(kind, s.particles, s.params, s.mode, &options) {
            Ok(mut stepper) => {
                let mut left = steps;
                while left > 0 {
                    let batch = left.min(u32::MAX as u64) as u32;
                    stepper.advance(batch)?;
                    left -= batch as u64;
                }
                return Ok(Start {
                    particles: stepper.particles()?,
                    ..start.clone()
                });
            }
            Err(e) => reasons.push((kind.name(), e.into_reason())),
        }
    }
    Err(Error::NoBackend { reasons })
}

/// Runs `case` on backend `kind`: one row, or for experiment 4 on a step that refits, one row
/// per rebuild interval and one for `auto`.
pub fn run(
    plan: &Plan,
    kind: BackendKind,
    case: &Case,
    progress: &mut dyn FnMut(&str),
) -> Vec<Outcome<DemRow>> {
    let open = |rebuild| {
        let options = Options {
            structure: case.structure,
            grid_build: case.grid_build,
            rebuild,
        };
        let s = case.start;
        open_stepper(
            kind,
            s.particles.clone(),
            s.params.clone(),
            s.mode,
            &options,
        )
    };
    run_with(plan, kind, case, &open, progress)
}

/// [`run`] with the steppers from `open` (given the rebuild policy).
fn run_with(
    plan: &Plan,
    kind: BackendKind,
    case: &Case,
    open: &dyn Fn(RebuildPolicy) -> Result<Box<dyn Stepper>>,
    progress: &mut dyn FnMut(&str),
) -> Vec<Outcome<DemRow>> {
    let what = format!(
        "{} {} n={}",
        kind.name(),
        case.scene,
        case.start.particles.len()
    );
    let stepper = match open(RebuildPolicy::Auto) {
        Ok(s) => s,
        Err(e) => return vec![Outcome::Skipped(what, e.to_string())],
    };
    if case.experiment != Experiment::Rebuild || !stepper.refits() {
        progress(&what);
        let policy = if stepper.refits() {
            RebuildPolicy::Auto.to_string()
        } else {
            "every step".to_owned()
        };
        return vec![measure_or_skip(plan, kind, case, stepper, &policy, &what)];
    }
    drop(stepper);
    let policies = REBUILD_INTERVALS
        .into_iter()
        .map(RebuildPolicy::Every)
        .chain([RebuildPolicy::Auto]);
    policies
        .map(|policy| {
            let what = format!("{what} rebuild {policy}");
            progress(&what);
            match open(policy) {
                Ok(s) => measure_or_skip(plan, kind, case, s, &policy.to_string(), &what),
                Err(e) => Outcome::Skipped(what, e.to_string()),
            }
        })
        .collect()
}

fn measure_or_skip(
    plan: &Plan,
    kind: BackendKind,
    case: &Case,
    stepper: Box<dyn Stepper>,
    policy: &str,
    what: &str,
) -> Outcome<DemRow> {
    match measure(plan, kind, case, stepper, policy) {
        Ok(row) => Outcome::Row(row),
        Err(e) => Outcome::Skipped(what.to_owned(), e.to_string()),
    }
}

/// Warm-up advances, then `repeats` timed advances of `steps` steps each, continuing one run.
fn measure(
    plan: &Plan,
    kind: BackendKind,
    case: &Case,
    mut stepper: Box<dyn Stepper>,
    policy: &str,
) -> Result<DemRow> {
    for _ in 0..plan.settings.warmup {
        stepper.advance(plan.settings.steps)?;
    }
    let mut runs = Vec::with_capacity(plan.settings.repeats);
    let mut walls = Vec::with_capacity(plan.settings.repeats);
    for _ in 0..plan.settings.repeats {
        let t = Instant::now();
        runs.push(stepper.advance(plan.settings.steps)?);
        walls.push(t.elapsed().as_secs_f64() * 1e3 / plan.settings.steps as f64);
    }
    let last = *runs.last().expect("a plan has at least one repeat");
    // Timestamps can be missing on a GPU without them: then nothing was measured.
    let clock = if runs.iter().all(|r| r.clock == last.clock) {
        last.clock
    } else {
        Clock::None
    };
    let per_step = |f: &dyn Fn(&crate::dem::StageTimes) -> f64| {
        let values: Vec<f64> = runs.iter().map(|r| f(&r.times) / r.steps as f64).collect();
        Spread::of(&values).expect("a plan has at least one repeat")
    };
    let history = match case.start.params.friction.has_history() {
        true => Some(HistorySize::of(&stepper.particles()?.history)),
        false => None,
    };
    // `describe` is "name (device)".
    let described = stepper.describe();
    let device = described
        .strip_prefix(kind.name())
        .map(|d| d.trim().trim_start_matches('(').trim_end_matches(')'))
        .unwrap_or(&described)
        .to_owned();
    Ok(DemRow {
        experiment: case.experiment,
        backend: kind,
        device,
        scene: case.scene,
        n: case.start.particles.len(),
        mode: case.start.mode,
        structure: case.structure,
        rebuild: policy.to_owned(),
        refits: stepper.refits(),
        steps: plan.settings.steps,
        contacts: last.contacts,
        clock,
        build_ms: per_step(&|t| t.build_ms),
        dcd_ms: per_step(&|t| t.dcd_ms),
        update_ms: per_step(&|t| t.update_ms),
        total_ms: per_step(&|t| t.total_ms()),
        wall_ms: Spread::of(&walls).expect("a plan has at least one repeat"),
        speedup_vs_cpu: None,
        history,
        box_scale: case.box_scale,
        grid_build: stepper.grid_build().map(str::to_owned),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::plan::Settings;
    use crate::dem::{Advance, Particles, StageTimes};
    use crate::scenes::Scene;

    /// A step that takes 1 ms per phase and refits or not.
    struct Fake {
        refits: bool,
        particles: Particles,
    }

    impl Stepper for Fake {
        fn describe(&self) -> String {
            "cpu (fake)".into()
        }

        fn advance(&mut self, steps: u32) -> Result<Advance> {
            let ms = steps as f64;
            Ok(Advance {
                steps,
                contacts: 7,
                times: StageTimes {
                    build_ms: ms,
                    dcd_ms: ms,
                    update_ms: ms,
                },
                clock: crate::dem::Clock::Gpu,
            })
        }

        fn particles(&mut self) -> Result<Particles> {
            Ok(self.particles.clone())
        }

        fn refits(&self) -> bool {
            self.refits
        }
    }

    fn rows(refits: bool, experiment: Experiment) -> Vec<DemRow> {
        let plan = Plan {
            backends: vec![BackendKind::Cpu],
            settings: Settings {
                experiments: vec![experiment],
                spheres: 100,
                max_spheres: 1000,
                steps: 4,
                settle: 0,
                pour: 0,
                repeats: 3,
                warmup: 1,
                structure: Structure::Auto,
                seed: 1,
                mesh: None,
            },
        };
        let freefall = SceneKind::Generated(Scene::Freefall);
        let start = start(freefall, 100, 1).unwrap();
        let case = Case {
            experiment,
            scene: freefall,
            start: &start,
            structure: Structure::Auto,
            grid_build: GridBuild::Auto,
            box_scale: None,
        };
        let open = |_| -> Result<Box<dyn Stepper>> {
            Ok(Box::new(Fake {
                refits,
                particles: start.particles.clone(),
            }))
        };
        run_with(&plan, BackendKind::Cpu, &case, &open, &mut |_| {})
            .into_iter()
            .map(|o| match o {
                Outcome::Row(r) => r,
                Outcome::Skipped(what, why) => panic!("{what}: {why}"),
            })
            .collect()
    }

    #[test]
    fn steps_that_refit_are_swept_over_rebuild_intervals() {
        let swept = rows(true, Experiment::Rebuild);
        let policies: Vec<&str> = swept.iter().map(|r| r.rebuild.as_str()).collect();
        assert_eq!(policies, ["1", "5", "10", "25", "50", "100", "auto"]);
        assert!(swept.iter().all(|r| r.refits && r.total_ms.median == 3.0));
        assert_eq!(swept[0].build_ms.samples, 3);
        assert_eq!(swept[0].device, "fake");
    }

    #[test]
    fn steps_that_never_refit_get_one_row() {
        let once = rows(false, Experiment::Rebuild);
        assert_eq!(once.len(), 1);
        assert_eq!(once[0].rebuild, "every step");
        let refitting = rows(true, Experiment::Freefall);
        assert_eq!(refitting.len(), 1);
        assert_eq!(refitting[0].rebuild, "auto");
        assert_eq!(refitting[0].contacts, 7);
    }
}
