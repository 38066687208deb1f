//! Setting a simulation run up: the scene (a new one, or the one a checkpoint saved), the
//! particles and step parameters it starts from, and the opened DEM step. `mochi simulate` and
//! the Python `mochi.Simulation` both start their runs here, so the two cannot drift apart.
//!
//! ```no_run
//! use mochi::dem::scene::{Overrides, SceneFlags};
//! use mochi::engines::{BackendChoice, Options};
//! use mochi::run::RunStart;
//!
//! let overrides = Overrides::parse(&["scene=freefall", "spheres=100"])?;
//! let start = RunStart::new(None, &SceneFlags::default(), &overrides)?;
//! let mut run = start.open("cpu".parse::<BackendChoice>().unwrap(), &Options::default())?;
//! run.stepper.advance(10)?;
//! # Ok::<(), mochi::Error>(())
//! ```

use crate::dem::contacts::ContactData;
use crate::dem::flow::FlowCounts;
use crate::dem::model::StepParams;
use crate::dem::scene::{Overrides, SceneConfig, SceneFlags, SceneKind, Start};
use crate::dem::stepper::{ExternalLoads, Motion, Stepper};
use crate::dem::walls::WallSet;
use crate::dem::walls::spec::NewMotion;
use crate::engines::DemSetup;
use crate::engines::cpu::CpuStepper;
use crate::engines::{BackendChoice, BackendKind, Opened, Options, open_scene};
use crate::error::{Error, Result};
use crate::io::{self, Frame, KeptHistory};
use crate::particles::Particles;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Wall-clock time between two returns from the DEM step that a run aims at (for progress,
/// Ctrl-C and the like): the steps between them go to the backend as one call, which a GPU
/// backend keeps busy without gaps.
pub const PROGRESS_PERIOD: Duration = Duration::from_millis(250);

/// Steps of a run's first call of the DEM step (from there [`progress_steps`] sets them).
pub const FIRST_PROGRESS_STEPS: u64 = 10;

/// Steps of the next call of the DEM step: enough for [`PROGRESS_PERIOD`] at the rate of the
/// last `steps` steps, which took `took` (counted as at least a nanosecond per step, so at most
/// 2.5e8: a backend call's `u32`), growing at most fourfold per call.
pub fn progress_steps(steps: u64, took: Duration) -> u64 {
    let per_step = took.as_secs_f64() / steps.max(1) as f64;
    let fit = (PROGRESS_PERIOD.as_secs_f64() / per_step.max(1e-9)).round() as u64;
    fit.clamp(1, 4 * steps.max(1))
}

/// A file a run reads while it runs (a wall's mesh), as it was when the run started: a resumed
/// run refuses a file that changed since.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FileDigest {
    /// The file, as the scene names it.
    pub path: PathBuf,
    /// Its length \[bytes\].
    pub bytes: u64,
    /// The CRC-32 of its bytes.
    pub crc32: u32,
}

impl FileDigest {
    /// The digest of the file `path` now.
    pub fn of(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|error| Error::Io {
            path: path.to_owned(),
            error,
        })?;
        Ok(Self {
            path: path.to_owned(),
            bytes: bytes.len() as u64,
            crc32: crc32fast::hash(&bytes),
        })
    }

    /// Refuses the file where it is no longer what this digest saw.
    fn check(&self) -> Result<()> {
        let now = Self::of(&self.path)?;
        if now != *self {
            return Err(Error::InvalidConfig {
                what: format!("wall mesh {}", self.path.display()),
                reason: format!(
                    "the file changed since the run started ({} bytes with CRC-32 {:08x} then, \
                     {} bytes with CRC-32 {:08x} now): a resumed run must meet the walls it had; \
                     restore the file, or start a new run from the last frame \
                     (--input OUT/frame_<step>.csv)",
                    self.bytes, self.crc32, now.bytes, now.crc32
                ),
            });
        }
        Ok(())
    }
}

/// A run's state besides its particles, as its checkpoints save it (TOML), so that a resumed
/// run goes on as the uninterrupted one would: what its flows did, what its flow log had
/// counted at its last row, and the files it reads.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RunState {
    /// What the flows did from the run's start (`None`: a run without flows).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub flow: Option<FlowCounts>,
    /// The flow counts at the last row of the run's flow log (`mochi simulate`'s `flow.csv`),
    /// where it keeps one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub flow_logged: Option<FlowCounts>,
    /// The wall meshes the run reads, as they were at its start.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub meshes: Vec<FileDigest>,
}

impl RunState {
    /// The state as TOML.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a run's state serializes")
    }

    /// The state a checkpoint saved (`text`, empty in older checkpoints).
    fn parse(text: &str, checkpoint: &Path) -> Result<Self> {
        toml::from_str(text).map_err(|e| Error::Parse {
            path: checkpoint.to_owned(),
            line: None,
            msg: format!("the run's state: {}", e.to_string().trim_end()),
        })
    }
}

/// A run's scene and the state it starts from, before a backend is opened.
#[derive(Debug, Clone)]
pub struct RunStart {
    /// The scene with every derived value written out (time step, box, material), as a
    /// checkpoint saves it: resuming from it gives exactly the same parameters.
    pub config: SceneConfig,
    /// The particles, step parameters and proxy mode.
    pub start: Start,
    /// The run's state besides the particles: at its start, or as its checkpoint saved it
    /// (its files checked against it).
    pub state: RunState,
    /// Where the run was resumed for one rank of several ([`Self::resume_on_rank`]): the rank,
    /// the ranks, and the contact history of the spheres it owns as it opens (`start`'s
    /// particles then come without theirs).
    own_history: Option<(usize, usize, KeptHistory)>,
}

impl RunStart {
    /// A new run: the scene file (`None`: the default scene), then `flags`, then `overrides`
    /// (as `--set` gives them, or a table), built into particles at step 0. Refuses fields the
    /// chosen scene does not use, and a time step the contact law cannot keep stable.
    pub fn new(
        scene_file: Option<&Path>,
        flags: &SceneFlags,
        overrides: &Overrides,
    ) -> Result<Self> {
        let config = SceneConfig::load_new(scene_file, flags, overrides)?;
        let start = config.build()?;
        Self::fresh(config, start)
    }

    /// A new run of `config` from `start`: the scene resolved, the wall meshes' digests taken.
    fn fresh(config: SceneConfig, start: Start) -> Result<Self> {
        let meshes = config
            .wall
            .iter()
            .map(|w| FileDigest::of(&w.mesh))
            .collect::<Result<_>>()?;
        Ok(Self {
            config: config.resolved(&start),
            start,
            state: RunState {
                meshes,
                ..RunState::default()
            },
            own_history: None,
        })
    }

    /// A new run of `particles` given in memory (scene `input` without a file), with
    /// `overrides` (the scene's other keys: its material, box, walls, …), from the particles'
    /// step. Refuses particles a sphere file could not hold and keys scene `input` does not use.
    pub fn of_particles(particles: Particles, overrides: &Overrides) -> Result<Self> {
        let flags = SceneFlags {
            scene: Some(SceneKind::Input),
            ..SceneFlags::default()
        };
        let config = SceneConfig::load_new(None, &flags, overrides)?;
        let start = config.build_from(particles)?;
        Self::fresh(config, start)
    }

    /// A run resumed from `checkpoint`: its particles, and its saved scene with `flags` and
    /// `overrides` applied (only the fields of [`crate::dem::scene::RESUMABLE`] may change).
    /// A checkpoint that cannot be read is an error of its own; a scene or particles that do
    /// not pass, or a wall mesh that changed since the run started, are an [`Error::Resuming`]
    /// naming the checkpoint. The flows go on from the checkpoint's counts.
    pub fn resume(checkpoint: &Path, flags: &SceneFlags, overrides: &Overrides) -> Result<Self> {
        let saved = io::read_checkpoint(checkpoint)?;
        Self::resumed(checkpoint, saved, (flags, overrides))
    }

    /// [`Self::resume`] for rank `rank` of `ranks` of a run opened over them
    /// ([`Self::open_on_ranks`]), reading the contact history only of the spheres the rank owns
    /// as it opens: each rank then holds the whole run's spheres until it has its own, but
    /// never the whole run's history (at hundreds of millions of frictional spheres, the
    /// larger part). Such a start opens only on that rank of that many.
    pub fn resume_on_rank(
        checkpoint: &Path,
        flags: &SceneFlags,
        overrides: &Overrides,
        (rank, ranks): (usize, usize),
    ) -> Result<Self> {
        let owned = |scene: &str, p: &Particles| {
            let config = SceneConfig::resume(scene, checkpoint, flags, overrides)?;
            let (lo, hi) = config.resumed_box()?;
            crate::distributed::owned_at_opening(p, (lo, hi), (rank, ranks))
        };
        let (saved, kept) = io::read_checkpoint_keeping_history(checkpoint, &owned)?;
        let mut run = Self::resumed(checkpoint, saved, (flags, overrides))?;
        run.own_history = Some((rank, ranks, kept));
        Ok(run)
    }

    /// The run resumed from `saved`, read from `checkpoint`, with `flags` and `overrides`.
    fn resumed(
        checkpoint: &Path,
        saved: io::Checkpoint,
        (flags, overrides): (&SceneFlags, &Overrides),
    ) -> Result<Self> {
        let state = RunState::parse(&saved.state, checkpoint)?;
        let resuming = |error| Error::Resuming {
            checkpoint: checkpoint.to_owned(),
            error: Box::new(error),
        };
        let config =
            SceneConfig::resume(&saved.scene, checkpoint, flags, overrides).map_err(resuming)?;
        for digest in &state.meshes {
            digest.check().map_err(resuming)?;
        }
        let mut start = config.resume_from(saved.particles).map_err(resuming)?;
        start.flow.counted = state.flow.unwrap_or_default();
        Ok(Self {
            config,
            start,
            state,
            own_history: None,
        })
    }

    /// Opens the DEM step of `choice` over the particles (`auto`: the registry's one rule, with
    /// the reason it passed over faster backends in [`Run::auto_reason`]). Spheres that share a
    /// centre are counted here; the backend moves them apart as it opens.
    pub fn open(self, choice: BackendChoice, options: &Options) -> Result<Run> {
        if let Some((rank, ranks, _)) = &self.own_history {
            return Err(Error::Usage(format!(
                "this run was resumed for rank {rank} of {ranks}, with that rank's contact \
                 history alone: it opens only there (RunStart::open_on_ranks)"
            )));
        }
        let facts = StartFacts::of(&self.start)?;
        let flow = self.start.flow.clone();
        let RunStart {
            config,
            start,
            state,
            own_history: _,
        } = self;
        let Opened {
            value: stepper,
            kind: backend,
            reason: auto_reason,
        } = open_scene(choice, start, options)?;
        let every = flow.every(backend != BackendKind::Cpu);
        let flow_warning = flow.rate_warning(facts.params.dt as f64, every);
        let chosen = (backend, auto_reason);
        Ok(into_run(
            (config, state),
            facts,
            stepper,
            chosen,
            flow_warning,
            options,
        ))
    }

    /// Opens the run decomposed over the ranks of `comm` (the box cut into a grid of boxes:
    /// `crate::distributed`), each rank stepping on the backend of `choice` (`auto`: the
    /// registry's one rule; a GPU backend on the GPU of the process's local rank): on rank 0
    /// the run, whose step every other rank follows; on the others `None`, once rank 0's run is
    /// over (they write nothing).
    pub fn open_on_ranks<C>(
        self,
        comm: C,
        choice: BackendChoice,
        options: &Options,
    ) -> Result<Option<Run>>
    where
        C: crate::distributed::Comm + Send + 'static,
    {
        // Only rank 0 reports the start (the others follow its run).
        let facts = match comm.rank() {
            0 => Some(StartFacts::of(&self.start)?),
            _ => None,
        };
        let RunStart {
            config,
            start,
            state,
            own_history,
        } = self;
        let (setup, flow) = DemSetup::of_start(start);
        let dt = setup.params.dt as f64;
        let rank = match own_history {
            None => crate::distributed::RankStepper::new(comm, &setup)?,
            Some((rank, ranks, kept)) => {
                if (rank, ranks) != (comm.rank(), comm.size()) {
                    return Err(Error::Usage(format!(
                        "this run was resumed for rank {rank} of {ranks}, and opened on rank {} \
                         of {}",
                        comm.rank(),
                        comm.size()
                    )));
                }
                crate::distributed::RankStepper::with_own_history(comm, &setup, &kept)?
            }
        };
        // The whole run's spheres are let go: a rank holds its own from now on.
        drop(setup);
        crate::distributed::give_back_freed_memory();
        let Opened {
            value: rank,
            kind,
            reason,
        } = (rank.rebalancing_every(crate::distributed::REBALANCE_STEPS))
            .on_backend(choice, options)?;
        let every = flow.every(kind != BackendKind::Cpu);
        let flow_warning = flow.rate_warning(dt, every);
        let rank = rank.with_flow(flow)?;
        let Some(facts) = facts else {
            crate::distributed::follow(rank)?;
            return Ok(None);
        };
        let stepper = Box::new(crate::distributed::Leader::new(rank)?);
        let scene = (config, state);
        Ok(Some(into_run(
            scene,
            facts,
            stepper,
            (kind, reason),
            flow_warning,
            options,
        )))
    }
}

/// The run of a scene and its state, stepped by `stepper` on `backend` (chosen for
/// `auto_reason`).
fn into_run(
    (config, state): (SceneConfig, RunState),
    facts: StartFacts,
    stepper: Box<dyn Stepper>,
    (backend, auto_reason): (BackendKind, Option<String>),
    flow_warning: Option<String>,
    options: &Options,
) -> Run {
    let StartFacts {
        params,
        walls,
        spheres,
        first_step,
        radius_range,
        coincident_pairs,
        coarse_warning,
    } = facts;
    Run {
        config,
        meshes: state.meshes,
        params,
        walls,
        stepper,
        backend,
        auto_reason,
        spheres,
        first_step,
        radius_range,
        coarse_warning,
        flow_warning,
        coincident_pairs,
        external: ExternalLoads::default(),
        options: *options,
    }
}

/// What a run keeps and reports of its start.
struct StartFacts {
    params: StepParams,
    walls: WallSet,
    spheres: usize,
    first_step: u64,
    radius_range: (f32, f32),
    /// Pairs of spheres that share their centre (the backend moves them apart as it opens).
    coincident_pairs: u64,
    coarse_warning: Option<String>,
}

impl StartFacts {
    fn of(start: &Start) -> Result<Self> {
        let particles = &start.particles;
        Ok(Self {
            params: start.params.clone(),
            walls: start.walls.clone(),
            spheres: particles.len(),
            first_step: particles.step,
            radius_range: particles.radius_range(),
            coincident_pairs: particles.coincident_pairs()?,
            coarse_warning: crate::coarse_coordinates(&particles.positions, &particles.radii),
        })
    }
}

/// An opened run: its scene, its step parameters and the backend's DEM step.
pub struct Run {
    /// The resolved scene (see [`RunStart::config`]).
    pub config: SceneConfig,
    /// The step parameters.
    pub params: StepParams,
    /// The walls: the box's (or none) and the mesh walls, in their rest pose.
    pub walls: WallSet,
    /// The backend's DEM step, holding the particles.
    pub stepper: Box<dyn Stepper>,
    /// The backend it runs on.
    pub backend: BackendKind,
    /// Why `auto` passed over the faster backends (`None` for a named backend).
    pub auto_reason: Option<String>,
    /// Number of spheres.
    pub spheres: usize,
    /// The step the run starts from (0, or the checkpoint's).
    pub first_step: u64,
    /// The smallest and largest radius.
    pub radius_range: (f32, f32),
    /// The warning of [`crate::coarse_coordinates`] for the starting centres, if any.
    pub coarse_warning: Option<String>,
    /// The warning of [`crate::dem::flow::FlowSet::rate_warning`] for this run's flows and
    /// backend, if any.
    pub flow_warning: Option<String>,
    /// Pairs of spheres that shared their centre at the start.
    pub coincident_pairs: u64,
    /// The wall meshes the run reads, as they were at its start ([`RunState::meshes`]).
    pub meshes: Vec<FileDigest>,
    /// The loads the steps apply besides contacts and gravity ([`Run::set_external_loads`]).
    external: ExternalLoads,
    /// The backends' settings the run was opened with (and is opened again with).
    options: Options,
}

impl Run {
    /// The warning about spheres that shared their centre at the start, if any did.
    pub fn coincident_warning(&self) -> Option<String> {
        (self.coincident_pairs > 0).then(|| {
            format!(
                "{} pairs of spheres share their centre: each sphere after the first of such a \
                 group starts at the next point of a cubic lattice about the centre, nearest \
                 first, a diameter of the group's largest sphere apart, so that none of them \
                 overlaps another",
                self.coincident_pairs
            )
        })
    }

    /// The warning of [`StepParams::overlap_warning`] for this run's radii, if any.
    pub fn overlap_warning(&self) -> Option<String> {
        let (r_min, r_max) = self.radius_range;
        self.params.overlap_warning(r_min, r_max)
    }

    /// Sets the spheres' motion before the next step ([`Stepper::set_motion`]), refusing a
    /// position outside the box by more than the box's own extent along an axis (as a resumed
    /// run's are; no bound without the box's walls, where the box only bounds the grid).
    pub fn set_motion(&mut self, motion: &Motion<'_>) -> Result<()> {
        // A position that is not finite is named as such, not measured against the box.
        if let Some(positions) = motion.positions
            && let Some(index) = positions
                .iter()
                .position(|x| x.iter().any(|v| !v.is_finite()))
        {
            return Err(Error::InvalidSphere {
                index,
                reason: format!("its position {:?} is not finite", positions[index]),
            });
        }
        if let (Some(positions), true) = (motion.positions, self.walls.box_walls) {
            let (lo, hi) = (self.params.box_lo, self.params.box_hi);
            let outside = positions.iter().position(|x| {
                (0..3).any(|a| {
                    let margin = (hi[a] - lo[a]) as f64;
                    !(lo[a] as f64 - margin..=hi[a] as f64 + margin).contains(&x[a])
                })
            });
            if let Some(index) = outside {
                return Err(Error::InvalidSphere {
                    index,
                    reason: format!(
                        "position {:?} is outside the box {lo:?} .. {hi:?} by more than the \
                         box's own size",
                        positions[index]
                    ),
                });
            }
        }
        self.stepper.set_motion(motion)
    }

    /// Applies `loads` every step from the next on, until changed ([`Stepper::set_external_loads`]).
    pub fn set_external_loads(&mut self, loads: ExternalLoads) -> Result<()> {
        self.stepper.set_external_loads(&loads)?;
        self.external = loads;
        Ok(())
    }

    /// The external loads the steps apply (none until given).
    pub fn external_loads(&self) -> &ExternalLoads {
        &self.external
    }

    /// The contacts of the state now, as the next step resolves them, on any backend: the
    /// state read back and evaluated by the cpu step's law, which every backend's law is
    /// checked against (its sums are then the forces the next step applies, to the rounding
    /// of the backend's own order of summation).
    pub fn contact_data(&mut self) -> Result<ContactData> {
        let setup = DemSetup {
            particles: self.stepper.particles()?,
            params: self.params.clone(),
            mode: self.config.run.mode,
            walls: self.walls.clone(),
        };
        CpuStepper::open(setup)?.contact_data()
    }

    /// Sets gravity now \[m/s²\] from the next step on (under a turning gravity, the
    /// gravity at t = 0 that turns into it now), in the step and in the scene checkpoints save
    /// ([`StepParams::with_gravity`] checks it first).
    pub fn set_gravity(&mut self, gravity: [f64; 3]) -> Result<()> {
        let p = &self.params;
        // Back to t = 0: gravity_at turns by gravity_spin · t about y.
        let angle = p.gravity_spin as f64 * self.time();
        let (s, c) = angle.sin_cos();
        let [gx, gy, gz] = gravity;
        let at_start = [gx * c - gz * s, gy, gz * c + gx * s];
        let params = p.with_gravity(at_start, self.radius_range.0)?;
        self.stepper.set_gravity(params.gravity)?;
        self.params = params;
        self.config.domain.gravity = at_start;
        Ok(())
    }

    /// The time now \[s\]: the step's count times the time step.
    fn time(&self) -> f64 {
        self.stepper.step() as f64 * self.params.dt as f64
    }

    /// Changes scene keys between steps ([`SceneConfig::changed`] says which may change: the
    /// materials, gravity, the time step, the walls' friction and material). The step is
    /// opened again on its backend from the state now (the contact history, gravity and
    /// external loads kept), at the cost of opening a run; a time step the contact law cannot
    /// keep stable is refused, and the run is then as it was. The time is the step count times
    /// the time step: a new time step makes the step count the time now over it, rounded (the
    /// clock, and what follows it, walls and a turning gravity, moves by less than half a step).
    /// A run of clumps keeps its materials' densities (its clumps' masses are made of them).
    pub fn change(&mut self, overrides: &Overrides) -> Result<()> {
        let config = self.config.changed(overrides)?;
        self.reopen(config)
    }

    /// Moves the scene's mesh wall `index` (its index in [`Run::walls`], as `wall_loads`
    /// lists them) as `motion` says from now on, from where it is now
    /// ([`moving_on`](crate::dem::walls::WallConfig::moving_on)); the step is opened again as [`change`](Self::change)
    /// opens it. The walls a built-in scene makes (a hopper's, a drum's) move as their scene
    /// says: they are refused.
    pub fn set_wall_motion(&mut self, index: usize, motion: &NewMotion) -> Result<()> {
        let walls = self.walls.meshes.len();
        let made = walls - self.config.wall.len();
        if index >= walls || index < made {
            let reason = match index < walls {
                true => format!(
                    "it is {}, which moves as its scene says",
                    self.walls.meshes[index].name
                ),
                false => format!("the run has {walls} mesh walls"),
            };
            return Err(Error::Usage(format!(
                "cannot set the motion of wall {index}: {reason}"
            )));
        }
        let mut config = self.config.clone();
        let wall = &mut config.wall[index - made];
        *wall = wall.moving_on(self.time(), motion);
        self.reopen(config)
    }

    /// Opens the step again on its backend with `config` (a changed scene of this run) from
    /// the state now, keeping the flows' counts, gravity and the external loads; changes
    /// nothing where it fails.
    fn reopen(&mut self, config: SceneConfig) -> Result<()> {
        let mut particles = self.stepper.particles()?;
        if let Some(dt) = config.run.dt.filter(|&dt| dt as f32 != self.params.dt) {
            particles.step = (self.time() / dt).round() as u64;
        }
        let mut start = config.resume_from(particles)?;
        let densities = &start.params.materials.densities;
        if !start.particles.clumps.clumps.is_empty()
            && *densities != self.params.materials.densities
        {
            return Err(Error::Usage(
                "a run of clumps keeps the masses its clumps were made with: a material's \
                 density changes with clumps only in a new run (set it in the scene)"
                    .into(),
            ));
        }
        if let Some(counted) = self.stepper.flow_counts() {
            start.flow.counted = counted;
        }
        let (params, walls) = (start.params.clone(), start.walls.clone());
        let choice = BackendChoice::Named(self.backend);
        let mut stepper = open_scene(choice, start, &self.options)?.value;
        stepper.set_external_loads(&self.external)?;
        (self.stepper, self.params, self.walls, self.config) = (stepper, params, walls, config);
        Ok(())
    }

    /// The resolved scene as TOML, as checkpoints save it.
    pub fn scene_toml(&self) -> String {
        self.config.to_toml()
    }

    /// The run's state now as TOML, as checkpoints save it (`flow_logged`: the flow counts
    /// at the last row of a flow log the caller keeps).
    pub fn state_toml(&self, flow_logged: Option<FlowCounts>) -> String {
        RunState {
            flow: self.stepper.flow_counts(),
            flow_logged,
            meshes: self.meshes.clone(),
        }
        .to_toml()
    }

    /// `particles` (of this run) as a frame: its time from the step and the time step, and
    /// each sphere's `contacts` where the run keeps a contact history
    /// ([`Snapshot::contacts`](crate::dem::Snapshot::contacts)).
    pub fn frame<'a>(&self, particles: &'a Particles, contacts: &'a [u32]) -> Frame<'a> {
        let kept = self.params.friction.has_history().then_some(contacts);
        Frame::of(particles, self.params.dt, kept)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn progress_updates_come_about_every_period_and_grow_at_most_fourfold() {
        // 10 steps in 1 ms: a quarter second holds 2,500, but the next call grows only to 40.
        assert_eq!(progress_steps(10, Duration::from_millis(1)), 40);
        // 1,000 steps in a second: 250 fit.
        assert_eq!(progress_steps(1000, Duration::from_secs(1)), 250);
        // A step slower than the period: one step per update.
        assert_eq!(progress_steps(3, Duration::from_secs(3)), 1);
        // No measurable time: bounded by the growth, then by a nanosecond per step.
        assert_eq!(progress_steps(10, Duration::ZERO), 40);
        assert_eq!(progress_steps(1 << 31, Duration::ZERO), 250_000_000);
    }
}
