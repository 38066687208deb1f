//! `mochi bench`: runs the paper's experiments, prints Markdown, writes JSON and SVG plots.

use crate::bench::plan::{BackendSelection, Experiment, Plan, Scale, Settings};
use crate::bench::{self, compare, markdown, plot};
use anyhow::{Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use mochi::engines::wgpu::compute::Structure;
use mochi::io;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Sizes: small (10k spheres, scaling 1k-10k, 20 steps), medium (100k, 1k-100k, 100 steps),
    /// paper (1M, 1k-1M, 200 steps).
    #[arg(long, value_enum, default_value_t)]
    pub scale: Scale,
    /// Spheres of every experiment but scaling (default: the scale's).
    #[arg(short = 'n', long, value_name = "N")]
    pub spheres: Option<usize>,
    /// Largest sphere count of the scaling experiment (default: the scale's).
    #[arg(long, value_name = "N")]
    pub max_spheres: Option<usize>,
    /// Backends: all (every one that runs here), auto (those `--backend auto` would consider:
    /// no software adapters, no OptiX without RT cores), or a list such as cpu,wgpu-compute.
    #[arg(long, default_value = "all")]
    pub backends: BackendSelection,
    /// Experiments, by number or name: 1 dcd, 2 freefall, 3 rotating, 4 rebuild, 5 scaling,
    /// 6 targets (landed slab, poured polylog pile with grid vs mlgrid, each judged only on a
    /// state with contacts), 7 friction (the Hertz–Mindlin step on the settled slab, with its
    /// contact history, and with --pour the poured polylog pile), 8 clustered (14 filled meshes
    /// dropped at dt 1e-4, every step of the 5,000-step drop timed, in their box and in a box
    /// 10× wider, with the grid build wgpu-compute chose).
    #[arg(long, value_delimiter = ',', value_parser = Experiment::parse, default_value = "1,2,3,4,5,6,7,8")]
    pub experiments: Vec<Experiment>,
    /// Timed runs per measurement (their median and spread are reported).
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// Untimed runs before the timed ones.
    #[arg(long, default_value_t = 1)]
    pub warmup: usize,
    /// Timed DEM steps per run (default: the scale's; experiment 8 always times its whole drop,
    /// 5,000 steps).
    #[arg(long)]
    pub steps: Option<u32>,
    /// Untimed steps that let the slab of experiments 6 and 7 land before it is timed (once per
    /// experiment, on the first backend that runs its step; every backend then starts from the
    /// landed state).
    #[arg(long, default_value_t = 3000)]
    pub settle: u32,
    /// Untimed steps that pour experiment 6's `polylog` pile (linear, per-pair stiffness, dt
    /// 1e-4) before it is timed (default: 1.5 times its top spheres' fall time, 6,375 steps
    /// at 10,000 spheres, 12,522 at 1M).
    #[arg(long, value_name = "STEPS")]
    pub pile: Option<u64>,
    /// Untimed steps that pour the `polylog` pile under Hertz–Mindlin (the default material,
    /// its Rayleigh step: about 300,000 bring the 1M pile down) before experiment 7 times it
    /// beside the slab; 0: the slab alone.
    #[arg(long, default_value_t = 0)]
    pub pour: u64,
    /// Grid of the wgpu-compute backend: auto, grid or mlgrid.
    #[arg(long, value_enum, default_value_t)]
    pub structure: Structure,
    /// Seed of the generated scenes.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Mesh of experiment 8 (OBJ, PLY or STL; the paper's is the Stanford bunny), instead of
    /// the built-in torus.
    #[arg(long, value_name = "FILE")]
    pub mesh: Option<PathBuf>,
    /// A JSON list of other codes' figures ({"experiment", "peer", "ms_per_step", "workload"},
    /// optionally "scene", "spheres", "contacts", "device", "date", "commit") to print beside
    /// mochi's rows of the same experiment, with the ratio.
    #[arg(long, value_name = "FILE")]
    pub compare: Option<PathBuf>,
    /// Folder for bench.json, bench.md and the SVG plots.
    #[arg(short, long, default_value = "mochi-bench")]
    pub out: PathBuf,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}

pub fn bench(args: BenchArgs) -> Result<()> {
    let (backends, status) = args.backends.resolve()?;
    let spheres = args.spheres.unwrap_or(args.scale.spheres());
    let mut experiments = args.experiments.clone();
    experiments.sort();
    experiments.dedup();
    let plan = Plan {
        backends,
        settings: Settings {
            experiments,
            spheres,
            max_spheres: args.max_spheres.unwrap_or(args.scale.spheres()),
            steps: args.steps.unwrap_or(args.scale.steps()),
            settle: args.settle,
            pile: args.pile,
            pour: args.pour,
            repeats: args.repeats,
            warmup: args.warmup,
            structure: args.structure,
            seed: args.seed,
            mesh: args.mesh.clone(),
        },
    };
    plan.validate()?;
    // Read before the run, so that a bad file fails at once.
    let peers = match &args.compare {
        Some(path) => compare::read(path)?,
        None => Vec::new(),
    };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;

    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(plan.units())
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} | {elapsed} | {msg}")
            .expect("a valid template"),
    );
    let mut progress = |what: &str| {
        bar.set_message(what.to_owned());
        bar.inc(1);
    };
    let mut report = bench::run(&plan, status, command_line(), &mut progress)?;
    report.comparisons = compare::compare(&report, &peers);
    bar.finish_and_clear();

    let text = markdown::render(&report);
    print!("{text}");
    let json = serde_json::to_string_pretty(&report).context("serializing the report")?;
    let mut written = vec!["bench.json".to_owned(), "bench.md".to_owned()];
    io::write_atomically(&args.out.join("bench.json"), |w| {
        w.write_all(json.as_bytes())
    })?;
    io::write_atomically(&args.out.join("bench.md"), |w| w.write_all(text.as_bytes()))?;
    for (name, svg) in plot::draw(&report)? {
        io::write_atomically(&args.out.join(&name), |w| w.write_all(svg.as_bytes()))?;
        written.push(name);
    }
    eprintln!("wrote {} in {}", written.join(", "), args.out.display());
    Ok(())
}

/// The command line as typed, arguments with spaces quoted.
fn command_line() -> String {
    std::env::args()
        .map(|a| {
            if a.is_empty() || a.contains(char::is_whitespace) {
                format!("{a:?}")
            } else {
                a
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}
