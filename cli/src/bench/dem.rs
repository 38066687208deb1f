//! Experiments 2–8: the DEM step, timed per phase.

use super::Outcome;
use super::plan::{DROP_DT, Experiment, MESH_DROP_COPIES, Plan, REBUILD_INTERVALS};
use super::report::{DemRow, HistorySize, StepRange};
use super::stats::Spread;
use mochi::dem::scene::{
    ContactKind, DomainConfig, MeshFill, RunConfig, SceneConfig, SceneKind, SceneMaterial, Source,
    Start, Stiffness,
};
use mochi::dem::{Clock, Stepper};
use mochi::engines::open_stepper;
use mochi::engines::wgpu::compute::{GridBuild, Structure};
use mochi::engines::{BackendKind, Options, RebuildPolicy};
use mochi::scenes::{SLAB_BASE, Scene};
use mochi::{Error, Result};
use std::time::Instant;

/// The start of a generated DEM scene (`freefall`, `rotating`, `slab`, `polylog`) of `n`
/// spheres: the scene's lattice layout and the paper's law (`linear`, frictionless, its default
/// time step and derived stiffness), as the paper's experiments run it.
pub fn start(scene: SceneKind, n: usize, seed: u64) -> Result<Start> {
    unframed(Source::sized(scene, n, seed), ContactKind::Linear).build()
}

/// The scene of `source` under the `contact` law's default material, writing no frames.
fn unframed(source: Source, contact: ContactKind) -> SceneConfig {
    SceneConfig {
        run: RunConfig {
            frame_every: 0,
            ..RunConfig::default()
        },
        source,
        material: SceneMaterial {
            contact,
            ..SceneMaterial::default()
        },
        ..SceneConfig::default()
    }
}

/// The start of experiment 7: the `slab` of `n` spheres under Hertz–Mindlin with the default
/// material (friction, EPSD rolling resistance, its Rayleigh time step), with the floor raised
/// to the slab's underside so that it lands within the settling steps.
pub fn friction_start(n: usize, seed: u64) -> Result<Start> {
    let slab = Source::sized(SceneKind::Generated(Scene::Slab), n, seed);
    SceneConfig {
        domain: DomainConfig {
            box_lo: Some([0.0, 0.0, SLAB_BASE]),
            ..DomainConfig::default()
        },
        ..unframed(slab, ContactKind::HertzMindlin)
    }
    .build()
}

/// The second start of experiment 7: the `polylog` scene of `n` spheres (radii 0.5 mm–6 cm) under
/// Hertz–Mindlin with the default material and its Rayleigh time step, to be poured.
pub fn friction_polylog_start(n: usize, seed: u64) -> Result<Start> {
    let polylog = Source::sized(SceneKind::Generated(Scene::Polylog), n, seed);
    unframed(polylog, ContactKind::HertzMindlin).build()
}

/// Time step of experiment 6's `polylog` pile \[s\], the poured pile's of the comparison with
/// Taichi (its contacts last 10 steps, 1 ms).
pub const PILE_DT: f64 = 1e-4;

/// The `polylog` start of experiment 6: `n` spheres (radii 0.5 mm–6 cm, log-uniform) in their
/// layers, under the linear law with the per-pair stiffness (every contact lasts 10 steps),
/// frictionless, dt [`PILE_DT`]: the law of the poured pile that the polylog claims (the
/// comparison with Taichi) are made on. The paper's one stiffness for every pair, derived for
/// the lightest pair (about 5 N/m at the scene's own dt 5e-5), would hold a 6 cm sphere's 4 N
/// on springs that give way by most of a metre: no pile.
pub fn pile_start(n: usize, seed: u64) -> Result<Start> {
    let mut scene = unframed(
        Source::sized(SceneKind::Generated(Scene::Polylog), n, seed),
        ContactKind::Linear,
    );
    scene.material.stiffness = Some(Stiffness::PerPair);
    scene.run.dt = Some(PILE_DT);
    scene.build()
}

/// Steps that pour `start` into a pile: 1.5 times the time a sphere at the top of the spheres
/// takes to fall to the floor from rest, at the start's time step (6,375 steps for
/// [`pile_start`] of 10,000 spheres, 12,522 of 1,000,000).
pub fn pour_steps(start: &Start) -> u64 {
    let p = &start.particles;
    let top = p
        .positions
        .iter()
        .zip(&p.radii)
        .map(|(c, r)| c[2] + r)
        .fold(start.params.box_lo[2], f32::max);
    let height = (top - start.params.box_lo[2]).max(0.0) as f64;
    let g = start
        .params
        .gravity
        .map(|x| x as f64 * x as f64)
        .iter()
        .sum::<f64>()
        .sqrt();
    if g <= 0.0 {
        return 0;
    }
    let fall = (2.0 * height / g).sqrt();
    (1.5 * fall / start.params.dt as f64).ceil() as u64
}

/// Spheres of the paper's 14-bunny scene (82,337 per bunny at radius 0.005 m).
const PAPER_MESH_DROP_SPHERES: f64 = 1_151_878.0;

/// Sphere radius \[m\] at which one copy of the mesh is filled to count its spheres.
const PROBE_RADIUS: f64 = 0.005;

/// The start of experiment 8: [`MESH_DROP_COPIES`] copies of `mesh` (`None`: the `mesh`
/// scene's built-in torus; the paper's is the Stanford bunny), side by side on the floor of
/// their box, filled at the radius that gives them about the paper's 1,151,878 spheres scaled
/// by `n` / 1,000,000 (the bunny at `n` = 1,000,000: radius 0.005 m, the paper's scene), under
/// the paper's law (`linear`, frictionless, its stiffness derived for a 10-step contact) at the
/// paper's time step [`DROP_DT`] (not the mesh scene's own 2.5e-5: the drop of the comparison
/// with Taichi, 0.5 s in [`DROP_STEPS`](super::plan::DROP_STEPS) steps).
pub fn mesh_drop_start(mesh: Option<&std::path::Path>, n: usize, seed: u64) -> Result<Start> {
    let config = |radius: f64, copies| {
        let fill = MeshFill {
            mesh: mesh.map(std::path::Path::to_path_buf),
            radius: radius as f32,
            copies,
            seed,
            ..MeshFill::default()
        };
        let mut scene = unframed(Source::Mesh(fill), ContactKind::Linear);
        scene.run.dt = Some(DROP_DT);
        scene
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
/// (the others' reasons in the error when none does); its `particles.step` counts them.
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
                let mut particles = stepper.particles()?;
                particles.step = start.particles.step + steps;
                return Ok(Start {
                    particles,
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
        let reopen = || open(RebuildPolicy::Auto);
        return vec![measure_or_skip(
            plan, kind, case, stepper, &policy, &what, &reopen,
        )];
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
                Ok(s) => {
                    let reopen = || open(policy);
                    measure_or_skip(plan, kind, case, s, &policy.to_string(), &what, &reopen)
                }
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
    reopen: &dyn Fn() -> Result<Box<dyn Stepper>>,
) -> Outcome<DemRow> {
    match measure(plan, kind, case, stepper, policy, reopen) {
        Ok(row) => Outcome::Row(row),
        Err(e) => Outcome::Skipped(what.to_owned(), e.to_string()),
    }
}

/// Warm-up runs, then `repeats` timed runs of [`Plan::steps_of`] steps each: one run continuing
/// the last, or in experiment 8 each from the start (the whole drop; `reopen` opens a stepper
/// at the start for every run after the first).
fn measure(
    plan: &Plan,
    kind: BackendKind,
    case: &Case,
    mut stepper: Box<dyn Stepper>,
    policy: &str,
    reopen: &dyn Fn() -> Result<Box<dyn Stepper>>,
) -> Result<DemRow> {
    let steps = plan.steps_of(case.experiment);
    let restart = case.experiment == Experiment::Clustered;
    let (warmup, repeats) = (plan.settings.warmup, plan.settings.repeats);
    let mut runs = Vec::with_capacity(repeats);
    let mut walls = Vec::with_capacity(repeats);
    for run in 0..warmup + repeats {
        if restart && run > 0 {
            // Every run from the start: the last run's state goes before the next is opened.
            drop(stepper);
            stepper = reopen()?;
        }
        let t = Instant::now();
        let advance = stepper.advance(steps)?;
        if run >= warmup {
            walls.push(t.elapsed().as_secs_f64() * 1e3 / steps as f64);
            runs.push(advance);
        }
    }
    let last = *runs.last().expect("a plan has at least one repeat");
    // Timestamps can be missing on a GPU without them: then nothing was measured.
    let clock = if runs.iter().all(|r| r.clock == last.clock) {
        last.clock
    } else {
        Clock::None
    };
    let per_step = |f: &dyn Fn(&mochi::dem::StageTimes) -> f64| {
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
    let settled = case.start.particles.step;
    let timed = if restart {
        StepRange {
            from: settled,
            to: settled + steps as u64,
            each_run: true,
        }
    } else {
        StepRange {
            from: settled + (warmup as u64) * steps as u64,
            to: settled + ((warmup + repeats) as u64) * steps as u64,
            each_run: false,
        }
    };
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
        steps,
        dt: Some(mochi::numbers::widened(case.start.params.dt)),
        settled,
        timed: Some(timed),
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
    use crate::bench::plan::DROP_STEPS;
    use crate::bench::plan::Settings;
    use mochi::dem::{Advance, ExternalLoads, Motion, Particles, StageTimes};
    use mochi::scenes::Scene;

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
                clock: mochi::dem::Clock::Gpu,
            })
        }

        fn particles(&mut self) -> Result<Particles> {
            Ok(self.particles.clone())
        }

        fn set_motion(&mut self, motion: &Motion<'_>) -> Result<()> {
            motion.apply(&mut self.particles)
        }

        fn set_gravity(&mut self, _: [f32; 3]) -> Result<()> {
            Ok(())
        }

        fn set_external_loads(&mut self, _: &ExternalLoads) -> Result<()> {
            Ok(())
        }

        fn step(&self) -> u64 {
            self.particles.step
        }

        fn refits(&self) -> bool {
            self.refits
        }
    }

    fn rows(refits: bool, experiment: Experiment) -> Vec<DemRow> {
        let freefall = SceneKind::Generated(Scene::Freefall);
        let start = start(freefall, 100, 1).unwrap();
        let opened = std::cell::Cell::new(0);
        rows_of(refits, experiment, freefall, &start, &opened)
    }

    /// The rows of `experiment` on `start` with the fake step (`opened` counts the steppers
    /// opened): 3 runs of 4 steps after 1 warm-up run.
    fn rows_of(
        refits: bool,
        experiment: Experiment,
        scene: SceneKind,
        start: &Start,
        opened: &std::cell::Cell<usize>,
    ) -> Vec<DemRow> {
        let plan = Plan {
            backends: vec![BackendKind::Cpu],
            settings: Settings {
                experiments: vec![experiment],
                spheres: 100,
                max_spheres: 1000,
                steps: 4,
                settle: 0,
                pile: None,
                pour: 0,
                repeats: 3,
                warmup: 1,
                structure: Structure::Auto,
                seed: 1,
                mesh: None,
            },
        };
        let case = Case {
            experiment,
            scene,
            start,
            structure: Structure::Auto,
            grid_build: GridBuild::Auto,
            box_scale: None,
        };
        let open = |_| -> Result<Box<dyn Stepper>> {
            opened.set(opened.get() + 1);
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
        // One run continuing the last: the warm-up's 4 steps, then 3 timed runs of 4.
        assert_eq!(refitting[0].steps, 4);
        assert_eq!(refitting[0].dt, Some(1e-4));
        assert_eq!(
            refitting[0].timed,
            Some(StepRange {
                from: 4,
                to: 16,
                each_run: false
            })
        );
    }

    #[test]
    fn the_clustered_row_times_the_whole_drop_at_dt_1e_4_every_run_from_the_start() {
        let drop = mesh_drop_start(None, 2000, 1).unwrap();
        assert_eq!(drop.params.dt, 1e-4);
        assert_eq!(drop.particles.step, 0);
        let opened = std::cell::Cell::new(0);
        let rows = rows_of(
            false,
            Experiment::Clustered,
            SceneKind::Mesh,
            &drop,
            &opened,
        );
        let row = &rows[0];
        // `--steps 4` does not apply: every run is the whole drop, from the start.
        assert_eq!((row.steps, row.dt), (DROP_STEPS, Some(DROP_DT)));
        assert_eq!((DROP_STEPS, DROP_DT), (5000, 1e-4));
        assert_eq!(
            row.timed,
            Some(StepRange {
                from: 0,
                to: 5000,
                each_run: true
            })
        );
        assert_eq!(row.total_ms.median, 3.0);
        assert_eq!(row.contacts, 7, "the contacts at the end of the drop");
        // A stepper opened at the start for the warm-up run and for each of the 3 timed runs.
        assert_eq!(opened.get(), 4);
    }

    #[test]
    fn the_pile_is_poured_for_its_fall_time() {
        let pile = pile_start(2000, 1).unwrap();
        assert_eq!(pile.params.dt, PILE_DT as f32);
        let steps = pour_steps(&pile);
        // The layers' top falls to the floor in sqrt(2 h / g); the pour lasts 1.5 times that.
        let top = pile
            .particles
            .positions
            .iter()
            .zip(&pile.particles.radii)
            .map(|(c, r)| (c[2] + r) as f64)
            .fold(0.0, f64::max);
        let fall = (2.0 * top / 9.81).sqrt();
        assert!(
            (steps as f64 * PILE_DT - 1.5 * fall).abs() < 2.0 * PILE_DT,
            "{steps} steps for a fall of {fall} s"
        );
        assert!(steps > 1000, "{steps}");
    }
}
