//! `mochi simulate`: runs a DEM scene with a progress bar, frames, checkpoints and a summary.

use super::args::SimulateArgs;
use super::backend_options::BackendFlags;
use super::output;
use super::render::{FrameData, FrameRenderer, png_name};
use super::view::walls_at;
use super::walls::{FlowLog, WallOutputs};
use anyhow::{Result, bail};
use indicatif::{ProgressBar, ProgressState, ProgressStyle};
use mochi::dem::scene::{Overrides, SceneFlags, SceneKind};
use mochi::dem::{
    Clock, Particles, RankShare, Snapshot, StageTimes, StepParams, Stepper, equipment,
};
use mochi::distributed::Comm;
use mochi::io::{self, Frame, FrameSeries};
use mochi::numbers::significant;
use mochi::render::{ColorBy, ColorChoice};
use mochi::run::{FIRST_PROGRESS_STEPS, FileDigest, Run, RunStart, RunState, progress_steps};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The longest a progress line shows contacts counted before, where counting them costs little
/// (a step that counts them at a cost, a run over GPU ranks, counts them at most this often,
/// and at the end).
const CONTACTS_PERIOD: Duration = Duration::from_secs(5);

/// At most this share of a run's wall time goes to counting its contacts for the progress line:
/// where a count costs more than this share of [`CONTACTS_PERIOD`], the counts come further
/// apart.
const COUNTING_SHARE: f64 = 0.05;

/// When the progress line's contacts are counted again: every [`CONTACTS_PERIOD`], or less
/// often where a count costs more than [`COUNTING_SHARE`] of the time between counts (what a
/// counted call took beyond its steps at the pace of the calls that did not count).
#[derive(Debug, Default)]
struct ContactCounts {
    /// When the last count was made.
    counted_at: Option<Instant>,
    /// Seconds a step of the last call that did not count.
    pace: Option<f64>,
    /// What the last count cost \[s\].
    cost: f64,
}

impl ContactCounts {
    /// Whether the next call counts.
    fn due(&self) -> bool {
        let period = CONTACTS_PERIOD
            .as_secs_f64()
            .max(self.cost / COUNTING_SHARE);
        self.counted_at
            .is_none_or(|t| t.elapsed().as_secs_f64() >= period)
    }

    /// A call of `steps` steps that took `took`, and counted where `counted`.
    fn called(&mut self, steps: u64, took: Duration, counted: bool) {
        let took = took.as_secs_f64();
        match counted {
            true => {
                self.counted_at = Some(Instant::now());
                if let Some(pace) = self.pace {
                    self.cost = (took - pace * steps as f64).max(0.0);
                }
            }
            false => self.pace = Some(took / steps.max(1) as f64),
        }
    }
}

/// The scene fields the named flags give.
fn flags(args: &SimulateArgs) -> Result<SceneFlags> {
    let scene = match (&args.input, &args.mesh, &args.scene) {
        (Some(_), _, _) => Some(SceneKind::Input),
        (_, Some(_), _) => Some(SceneKind::Mesh),
        (_, _, Some(name)) => Some(name.parse().map_err(anyhow::Error::msg)?),
        _ => None,
    };
    Ok(SceneFlags {
        scene,
        spheres: args.spheres,
        seed: args.seed,
        steps: args.steps,
        dt: args.dt,
        frame_every: args.frame_every,
        csv: args.csv.then_some(true),
        input: args.input.clone(),
        mesh: args.mesh.clone(),
        mode: args.mode,
    })
}

pub fn simulate(args: SimulateArgs) -> Result<()> {
    if args.print_scene {
        let (flags, overrides) = (flags(&args)?, Overrides::parse(&args.set)?);
        let run_start = match &args.resume {
            Some(path) => RunStart::resume(path, &flags, &overrides)?,
            None => RunStart::new(args.scene_file.as_deref(), &flags, &overrides)?,
        };
        print!("{}", run_start.config.to_toml());
        return Ok(());
    }
    let out = run_folder(&args);
    if let (Some(flag), 0) = (args.render.given().first(), args.render_every) {
        anyhow::bail!(
            "{flag} is a picture option, and pictures are drawn only with --render-every M: \
             add it, or leave {flag} out"
        );
    }
    let backend_flags = BackendFlags {
        structure: args.structure,
        grid_build: args.grid_build,
        rebuild: args.rebuild,
    };
    backend_flags.check(args.backend)?;
    if args.resume.is_none() && !args.overwrite {
        // Checked again once the folder is locked; here before the scene is built.
        output::refuse_earlier_run(&out)?;
    }
    let flags = flags(&args)?;
    let overrides = Overrides::parse(&args.set)?;
    let ranks = super::ranks::launched()?;
    let run_start = match (&args.resume, &ranks) {
        // A rank of several reads the contact history of its own spheres alone.
        (Some(path), Some(ranks)) => {
            let rank = (ranks.rank(), ranks.size());
            RunStart::resume_on_rank(path, &flags, &overrides, rank)?
        }
        (Some(path), None) => RunStart::resume(path, &flags, &overrides)?,
        (None, _) => RunStart::new(args.scene_file.as_deref(), &flags, &overrides)?,
    };
    let total = run_start.config.run.steps;
    let first = run_start.start.particles.step;
    if first > total {
        anyhow::bail!(
            "the checkpoint is at step {first}, past the run's {total} steps: raise --steps"
        );
    }
    let flow_logged = run_start.state.flow_logged;
    let clumps = match run_start.start.particles.clumps.describe() {
        Some(clumps) => format!(" in {clumps}"),
        None => String::new(),
    };
    let options = backend_flags.options();
    let run = match ranks {
        None => run_start.open(args.backend, &options)?,
        // One of several processes of mpirun: rank 0 runs and writes, the others follow.
        Some(ranks) => match run_start.open_on_ranks(ranks, args.backend, &options)? {
            Some(run) => run,
            None => return Ok(()),
        },
    };
    if let Some(reason) = &run.auto_reason {
        eprintln!("{reason}");
    }
    if let Some(warning) = backend_flags.warning(args.backend, run.backend) {
        eprintln!("warning: {warning}");
    }
    let overlap_warning = run.overlap_warning();
    let coincident_warning = run.coincident_warning();
    let Run {
        config,
        params: p,
        mut stepper,
        spheres: n,
        radius_range: (r_min, r_max),
        coarse_warning,
        flow_warning,
        walls,
        meshes,
        ..
    } = run;
    let mut pictures = if args.render_every == 0 {
        None
    } else {
        let sim_box = config.domain.box_lo.zip(config.domain.box_hi);
        let mut pictures = FrameRenderer::new(&args.render, sim_box)?;
        // Every picture of the run in one range where it is known from the start; `auto`
        // colours a running simulation by speed.
        match args.render.color_by {
            ColorChoice::Radius => pictures.set_range((r_min, r_max)),
            ColorChoice::Material => pictures.set_range((0.0, (p.materials.count - 1) as f32)),
            ColorChoice::Auto => pictures.set_color_by(ColorBy::Speed),
            ColorChoice::Speed | ColorChoice::Height | ColorChoice::Contacts => {}
        }
        Some(pictures)
    };
    let inputs: Vec<&Path> = match args.resume {
        Some(_) => Vec::new(),
        None => (args.scene_file.as_deref().into_iter())
            .chain(config.files())
            .collect(),
    };
    if config.run.csv && config.run.frame_pieces && config.run.frame_every > 0 {
        bail!(
            "csv = true and frame_pieces = true: a CSV frame holds the whole run, and frames \
             in pieces are never gathered; leave one of them out"
        );
    }
    let gif = args.render.gif.as_deref();
    output::check_run_outputs(&out, &inputs, gif)?;
    if let Some(gif) = gif {
        output::check_output_folder(gif, "--gif", Some(&out))?;
        if let Some(checkpoint) = &args.resume {
            output::refuse_same_file(checkpoint, gif, "--gif")?;
        }
    }
    // Everything is checked: from here on the run writes.
    let _folder = output::claim_run_folder(&out, args.resume.is_some(), args.overwrite)?;
    if let Some(pictures) = &mut pictures {
        pictures.start_gif()?;
    }
    // The index first: on a resume it is read, and may be refused, before the run writes a file.
    let resume_time = args.resume.as_ref().map(|_| first as f64 * p.dt as f64);
    let mut frames = if config.run.frame_every == 0 {
        None
    } else {
        let series = match args.resume {
            Some(_) => FrameSeries::open_for_resume(&out, first)?,
            None => FrameSeries::create(&out)?,
        };
        Some(FrameOutputs {
            walls: WallOutputs::start(&out, &walls, series.entries(), resume_time)?,
            flow: FlowLog::start(&out, stepper.flow_counts(), resume_time, flow_logged)?,
            series,
            gathered: Duration::ZERO,
        })
    };
    // One material's restitution, or the materials (each with its own).
    let material = match config.materials()?.describe() {
        Some(materials) => materials,
        None => format!("restitution {}", config.material.restitution),
    };
    eprintln!(
        "scene {} | {n} spheres{clumps} | steps {first}..{total} | {} | {material} | backend {}",
        config.scene(),
        p.describe(),
        stepper.describe()
    );

    if let Some(warning) = &overlap_warning {
        eprintln!("warning: {warning}");
    }
    if let Some(pictures) = &pictures {
        eprintln!(
            "pictures every {} steps with {}",
            args.render_every,
            pictures.describe()
        );
    }
    for warning in [coarse_warning, coincident_warning, flow_warning]
        .into_iter()
        .flatten()
    {
        eprintln!("warning: {warning}");
    }
    let scene_toml = config.to_toml();
    io::write_atomically(&out.join(io::SCENE_FILE), |w| {
        w.write_all(scene_toml.as_bytes())
    })?;
    let write_frame = |frames: &mut Option<FrameOutputs>, stepper: &mut dyn Stepper| match frames {
        Some(frames) => frames.write(stepper, &p, (config.run.csv, config.run.frame_pieces)),
        None => Ok(()),
    };
    let draw = |pictures: &mut Option<FrameRenderer>, stepper: &mut dyn Stepper| -> Result<()> {
        if let Some(pictures) = pictures {
            let Snapshot {
                particles: now,
                contacts,
            } = stepper.snapshot()?;
            let walls = walls_at(&walls, now.step as f64 * p.dt as f64);
            let frame = FrameData {
                step: Some(now.step),
                positions: &now.positions,
                radii: &now.radii,
                velocities: &now.velocities,
                materials: &now.materials,
                contacts: &contacts,
                walls: &walls,
            };
            pictures.render(&frame, &png_name(&out, now.step))?;
        }
        Ok(())
    };
    if args.resume.is_none() {
        write_frame(&mut frames, stepper.as_mut())?;
        draw(&mut pictures, stepper.as_mut())?;
    }

    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(total - first)
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{bar:30} {pos}/{len} steps | {rate} steps/s | ETA {eta} | {msg}",
        )
        .expect("a valid template")
        // Three significant digits (indicatif's own {per_sec} writes four decimals).
        .with_key(
            "rate",
            |state: &ProgressState, w: &mut dyn std::fmt::Write| {
                let _ = w.write_str(&significant(state.per_sec(), 3));
            },
        ),
    );
    let checkpoint = out.join(io::CHECKPOINT_FILE);
    let mut saved = Checkpoints {
        path: checkpoint.clone(),
        in_pieces: config.run.checkpoint_pieces,
        gathered: Duration::ZERO,
        last: None,
    };
    let started = Instant::now();
    let mut times = StageTimes::default();
    let mut clock = Clock::None;
    let mut contacts = 0;
    let mut step = first;
    let due = |every: u64, s: u64| every > 0 && s.is_multiple_of(every);
    // A run over ranks exchanges its ghosts once a round: calls of whole rounds.
    let round = stepper.steps_a_round().max(1) as u64;
    let mut progress_every = FIRST_PROGRESS_STEPS.next_multiple_of(round);
    let mut counts = ContactCounts::default();
    while step < total {
        let next_stop = [
            config.run.frame_every,
            args.checkpoint_every,
            args.render_every,
        ]
        .into_iter()
        .filter(|&e| e > 0)
        .map(|e| (step / e + 1) * e)
        .chain([step + progress_every, total])
        .min()
        .expect("a stop");
        let advanced_at = Instant::now();
        // The contacts shown are counted now and then; the last call's are counted.
        let count = next_stop == total || counts.due();
        let advance = match count {
            true => stepper.advance((next_stop - step) as u32)?,
            false => stepper.advance_uncounted((next_stop - step) as u32)?,
        };
        counts.called(next_stop - step, advanced_at.elapsed(), count);
        progress_every =
            progress_steps(next_stop - step, advanced_at.elapsed()).next_multiple_of(round);
        step = next_stop;
        times.add(&advance.times);
        clock = advance.clock;
        contacts = advance.contacts;
        if due(config.run.frame_every, step) {
            write_frame(&mut frames, stepper.as_mut())?;
        }
        if due(args.render_every, step) {
            draw(&mut pictures, stepper.as_mut())?;
        }
        if due(args.checkpoint_every, step) {
            let state = state_toml(stepper.as_ref(), &frames, &meshes);
            saved.write(stepper.as_mut(), (&scene_toml, &state))?;
        }
        bar.set_message(format!("{contacts} contacts"));
        bar.set_position(step - first);
    }
    bar.finish_and_clear();
    let wall = started.elapsed().as_secs_f64();
    let state = state_toml(stepper.as_ref(), &frames, &meshes);
    let end = saved.write(stepper.as_mut(), (&scene_toml, &state))?;
    let measured = match config.scene() {
        SceneKind::Hopper => (frames.as_ref().and_then(|f| f.flow.as_ref()))
            .and_then(|log| equipment::mass_flow_rate(log.discharge()))
            .map(|w| format!("hopper: steady mass flow rate {w:.4e} kg/s (see flow.csv)")),
        SceneKind::Drum | SceneKind::Gravel => {
            let end = match end {
                Some(end) => end,
                None => stepper.snapshot()?.particles,
            };
            equipment::free_surface_angle(&end.positions, &end.radii)
                .map(|a| format!("drum: free surface at {a:.1}° to the horizontal"))
        }
        _ => None,
    };
    summary(&SummaryLine {
        backend: stepper.describe(),
        n,
        steps: total - first,
        wall,
        times,
        clock,
        contacts,
    });
    if let Some(counts) = stepper.flow_counts() {
        println!("{}", counts.describe());
    }
    let shares = stepper.rank_shares()?;
    rank_table(&shares);
    // (A run of clumps gathers its frames and checkpoints whatever the keys say.)
    if let Some(frames) = &frames
        && !shares.is_empty()
        && !config.run.frame_pieces
        && frames.gathered.as_secs_f64() > GATHER_NOTE_SHARE * wall
    {
        eprintln!(
            "note: gathering the frames on process 0 took {:.1} s of the run's {wall:.1} s; \
             --set frame_pieces=true writes each frame in pieces, one a process, none gathered",
            frames.gathered.as_secs_f64()
        );
    }
    // The run's end checkpoint is the run's too.
    let whole = started.elapsed().as_secs_f64();
    if !shares.is_empty()
        && !saved.in_pieces
        && saved.gathered.as_secs_f64() > GATHER_NOTE_SHARE * whole
    {
        eprintln!(
            "note: gathering the checkpoints on process 0 took {:.1} s of the run's {whole:.1} s; \
             --set checkpoint_pieces=true writes each checkpoint in pieces, one a process, none \
             gathered",
            saved.gathered.as_secs_f64()
        );
    }
    if let Some(line) = measured {
        println!("{line}");
    }
    eprintln!(
        "wrote {} (series.pvd opens in ParaView), checkpoint {}",
        out.display(),
        checkpoint.display()
    );
    if let Some(gif) = pictures.map(FrameRenderer::finish).transpose()?.flatten() {
        eprintln!("wrote {}", gif.display());
    }
    Ok(())
}

/// What a run writes with every frame: the frame and the index, the walls' surfaces, index and
/// loads, and the flow log.
struct FrameOutputs {
    series: FrameSeries,
    walls: Option<WallOutputs>,
    flow: Option<FlowLog>,
    /// The time whole frames took (gathered on process 0 in a run over several).
    gathered: Duration,
}

/// The share of a run over processes that gathered frames may take before the run's end notes
/// that frames in pieces gather nothing.
const GATHER_NOTE_SHARE: f64 = 0.1;

impl FrameOutputs {
    /// Writes the frame of the particles of `stepper` (and CSV beside it where `csv`; in
    /// pieces, one a process, where `pieces` and the run is over several), with the walls and
    /// the flows then.
    fn write(
        &mut self,
        stepper: &mut dyn Stepper,
        p: &StepParams,
        (csv, pieces): (bool, bool),
    ) -> Result<()> {
        let series = &mut self.series;
        let written = match pieces {
            true => stepper.write_pieces(series.dir())?,
            false => None,
        };
        let (step, spheres) = match written {
            Some(counts) => {
                let step = stepper.step();
                let time = step as f64 * p.dt as f64;
                let history = p.friction.has_history();
                series.add_pieces(step, time, counts.len(), history)?;
                (step, counts.iter().sum::<u64>() as usize)
            }
            None => {
                let started = Instant::now();
                let Snapshot {
                    particles: now,
                    contacts,
                } = stepper.snapshot()?;
                let kept = p.friction.has_history().then_some(&contacts[..]);
                series.write(&Frame::of(&now, p.dt, kept), csv)?;
                self.gathered += started.elapsed();
                (now.step, now.len())
            }
        };
        if let Some(walls) = &mut self.walls {
            walls.write(series.entries(), step, p.dt, &stepper.wall_loads())?;
        }
        if let (Some(log), Some(counts)) = (&mut self.flow, stepper.flow_counts()) {
            log.write(step as f64 * p.dt as f64, spheres, counts)?;
        }
        Ok(())
    }
}

/// Where a run saves its checkpoints, and how.
struct Checkpoints {
    path: PathBuf,
    /// In pieces, one a process, where the run is over several.
    in_pieces: bool,
    /// The time whole checkpoints took (gathered on process 0 in a run over several).
    gathered: Duration,
    /// The step and the run's state of the last checkpoint written.
    last: Option<(u64, String)>,
}

impl Checkpoints {
    /// Writes the checkpoint of `stepper` now, of the run of `scene` with its `state` (both
    /// TOML): in pieces where asked and the run is over several processes, else whole; a whole
    /// checkpoint's particles are returned. The folders of pieces of the checkpoints before
    /// are removed once the new one is on disk. The checkpoint written last is not written
    /// again (the run's end at the step of its last checkpoint).
    fn write(
        &mut self,
        stepper: &mut dyn Stepper,
        (scene, state): (&str, &str),
    ) -> Result<Option<Particles>> {
        let step = stepper.step();
        let now = Some((step, state.to_owned()));
        if self.last == now {
            return Ok(None);
        }
        self.last = now;
        if self.in_pieces {
            let folder = io::piece_folder_for(&self.path, step);
            if let Some(pieces) = stepper.write_checkpoint_pieces(&folder)? {
                io::write_checkpoint_index(&self.path, (&folder, step), (scene, state), &pieces)?;
                io::remove_other_piece_folders(&self.path, Some(&folder))?;
                return Ok(None);
            }
        }
        let started = Instant::now();
        let now = stepper.particles()?;
        io::write_checkpoint(&self.path, &now, scene, state)?;
        self.gathered += started.elapsed();
        io::remove_other_piece_folders(&self.path, None)?;
        Ok(Some(now))
    }
}

/// The run's state besides its particles, as its checkpoints save it.
fn state_toml(
    stepper: &dyn Stepper,
    frames: &Option<FrameOutputs>,
    meshes: &[FileDigest],
) -> String {
    let flow_log = frames.as_ref().and_then(|f| f.flow.as_ref());
    RunState {
        flow: stepper.flow_counts(),
        flow_logged: flow_log.map(FlowLog::last),
        meshes: meshes.to_vec(),
    }
    .to_toml()
}

struct SummaryLine {
    backend: String,
    n: usize,
    steps: u64,
    wall: f64,
    times: StageTimes,
    clock: Clock,
    contacts: u64,
}

/// Prints the final table: throughput and the per-phase breakdown per step.
fn summary(s: &SummaryLine) {
    let per = |ms: f64| ms / s.steps.max(1) as f64;
    let clock = match s.clock {
        Clock::Gpu => "GPU timestamps",
        Clock::Wall => "wall clock",
        Clock::None => "not measured",
    };
    // A run that took no step (a resume at its last step, to rewrite its checkpoint) counted
    // no contacts and timed nothing.
    let contacts = match s.steps {
        0 => "—".to_string(),
        _ => s.contacts.to_string(),
    };
    println!("| backend | spheres | steps | wall [s] | steps/s | contacts (last step) |");
    println!("| --- | --- | --- | --- | --- | --- |");
    println!(
        "| {} | {} | {} | {:.2} | {:.1} | {contacts} |",
        s.backend,
        s.n,
        s.steps,
        s.wall,
        s.steps as f64 / s.wall.max(1e-9),
    );
    if s.steps == 0 {
        return;
    }
    println!();
    println!("| per step [ms] ({clock}) | build | DCD | update | total |");
    println!("| --- | --- | --- | --- | --- |");
    println!(
        "| | {:.4} | {:.4} | {:.4} | {:.4} |",
        per(s.times.build_ms),
        per(s.times.dcd_ms),
        per(s.times.update_ms),
        per(s.times.total_ms())
    );
}

/// Prints each rank's share of a run over ranks (nothing for a run of one process): its
/// spheres and ghosts, and its wall time a step by phase.
fn rank_table(shares: &[RankShare]) {
    if shares.is_empty() {
        return;
    }
    println!();
    println!(
        "| rank | spheres | ghosts | rounds | per step [ms] (wall clock): exchange | lay out, open | \
         step | read back | total |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    for (r, s) in shares.iter().enumerate() {
        let per = |ms: f64| ms / s.steps.max(1) as f64;
        println!(
            "| {r} | {} | {} | {} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} |",
            s.spheres,
            s.ghosts,
            s.rounds,
            per(s.exchange_ms),
            per(s.open_ms),
            per(s.step_ms),
            per(s.read_back_ms),
            s.ms_a_step()
        );
    }
}

/// Where the run writes: `--out`, else the folder of the checkpoint it resumes, else
/// `mochi-out`.
fn run_folder(args: &SimulateArgs) -> PathBuf {
    match (&args.out, &args.resume) {
        (Some(out), _) => out.clone(),
        (None, Some(checkpoint)) => match checkpoint.parent() {
            Some(folder) if !folder.as_os_str().is_empty() => folder.to_path_buf(),
            _ => PathBuf::from("."),
        },
        (None, None) => PathBuf::from("mochi-out"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_that_cost_more_than_their_share_come_further_apart() {
        let mut counts = ContactCounts::default();
        assert!(counts.due(), "the first call counts");
        // 100 steps at 1 ms each, then a count of 100 steps that took 2 s more.
        counts.called(100, Duration::from_millis(100), false);
        counts.called(100, Duration::from_millis(2100), true);
        assert!((counts.cost - 2.0).abs() < 1e-9, "cost {}", counts.cost);
        let ago = |s| Instant::now().checked_sub(Duration::from_secs(s));
        // Due after 2 s / COUNTING_SHARE = 40 s, not after CONTACTS_PERIOD.
        counts.counted_at = ago(10);
        assert!(!counts.due());
        counts.counted_at = ago(41);
        assert!(counts.due());
        // A count that costs nothing: every CONTACTS_PERIOD.
        counts.called(100, Duration::from_millis(100), true);
        assert_eq!(counts.cost, 0.0);
        counts.counted_at = ago(6);
        assert!(counts.due());
        counts.counted_at = ago(4);
        assert!(!counts.due());
    }
}
