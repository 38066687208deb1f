//! The commands.

use super::args::{Cli, Command, DetectArgs, GenerateArgs, SceneArgs};
use super::backend_options::BackendFlags;
use super::output::{check_output_folder, folder_of, refuse_same_file};
use anyhow::Result;

use mochi::engines::{self, BackendKind};
use mochi::scenes::{self, Layout, SceneSpec};
use mochi::{SphereSet, io};
use std::time::Instant;

pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Simulate(args) => super::simulate::simulate(*args),
        Command::Detect(args) => detect(args),
        Command::Generate(args) => generate(args),
        Command::Bench(args) => super::bench::bench(args),
        Command::Render(args) => super::render::render(args),
        Command::Backends => {
            list_backends();
            Ok(())
        }
    }
}

fn scene(args: &SceneArgs, default_layout: Layout) -> Result<(SphereSet, String)> {
    let spec = SceneSpec {
        scene: args.scene,
        n: args.n,
        seed: args.seed,
        layout: args.layout.unwrap_or(default_layout),
    };
    let spheres = scenes::generate(&spec)?;
    let what = format!(
        "scene {} ({} layout, seed {})",
        spec.scene.name(),
        spec.layout.name(),
        spec.seed
    );
    Ok((spheres, what))
}

fn detect(args: DetectArgs) -> Result<()> {
    if let (Some(input), Some(out)) = (&args.input, &args.output) {
        refuse_same_file(input, out, "-o")?;
    }
    if let Some(out) = &args.output {
        check_output_folder(out, "-o", None)?;
    }
    let (spheres, source) = match &args.input {
        Some(path) => (io::read_spheres(path)?, path.display().to_string()),
        None => scene(&args.scene, Layout::Random)?,
    };
    if let Some(warning) = mochi::coarse_coordinates(spheres.centers(), spheres.radii()) {
        eprintln!("warning: {source}: {warning}");
    }
    let flags = BackendFlags {
        structure: args.structure,
        grid_build: args.grid_build,
        rebuild: None,
    };
    flags.check(args.backend)?;
    let opened = engines::open(args.backend, &flags.options())?;
    if let Some(reason) = &opened.reason {
        eprintln!("{reason}");
    }
    if let Some(warning) = flags.warning(args.backend, opened.kind) {
        eprintln!("warning: {warning}");
    }
    let mut backend = opened.value;
    let info = backend.info();
    if spheres.len() as u64 > info.max_spheres {
        anyhow::bail!(
            "{} spheres exceed the {} backend's limit of {}",
            spheres.len(),
            info.name,
            info.max_spheres
        );
    }

    let t = Instant::now();
    backend.build(spheres.view(), args.mode)?;
    backend.finish()?;
    let mut build_ms = ms(t);
    let t = Instant::now();
    let (pairs, stats) = backend.find_pairs()?;
    let mut detect_ms = ms(t);
    let first_gpu = backend.gpu_times();
    let mut gpu_times = (first_gpu.build_ms, first_gpu.detect_ms);
    if args.repeat > 0 {
        let mut builds = Vec::with_capacity(args.repeat);
        let mut detects = Vec::with_capacity(args.repeat);
        let (mut gpu_builds, mut gpu_detects) = (Vec::new(), Vec::new());
        for _ in 0..args.repeat {
            let t = Instant::now();
            backend.build(spheres.view(), args.mode)?;
            backend.finish()?;
            builds.push(ms(t));
            let t = Instant::now();
            backend.find_pairs()?;
            detects.push(ms(t));
            let gpu = backend.gpu_times();
            gpu_builds.extend(gpu.build_ms);
            gpu_detects.extend(gpu.detect_ms);
        }
        build_ms = median(&mut builds);
        detect_ms = median(&mut detects);
        if gpu_builds.len() == args.repeat && gpu_detects.len() == args.repeat {
            gpu_times = (
                Some(median(&mut gpu_builds)),
                Some(median(&mut gpu_detects)),
            );
        }
    }

    let structure = backend
        .structure()
        .map(|s| format!(" | {s}"))
        .unwrap_or_default();
    let gpu_note = match gpu_times {
        (Some(b), Some(d)) => format!(" | GPU time: build {b:.3} ms, detect {d:.3} ms"),
        _ => String::new(),
    };
    if let Some(path) = &args.output {
        io::remove_stale_temp_files(folder_of(path));
        io::write_pairs(path, pairs)?;
    }
    let per_sphere = stats.candidates as f64 / spheres.len().max(1) as f64;
    println!(
        "{source}: spheres {} | pairs {} | candidates {} ({per_sphere:.2} per sphere) | \
         build {build_ms:.3} ms | detect {detect_ms:.3} ms{}{gpu_note} | backend {} ({}) | mode {}\
         {structure}",
        spheres.len(),
        stats.pairs,
        stats.candidates,
        if args.repeat > 0 {
            format!(" (median of {})", args.repeat)
        } else {
            String::new()
        },
        info.name,
        info.device,
        args.mode.name(),
    );
    Ok(())
}

fn generate(args: GenerateArgs) -> Result<()> {
    check_output_folder(&args.output, "-o", None)?;
    let (spheres, what) = scene(&args.scene, Layout::Lattice)?;
    io::remove_stale_temp_files(folder_of(&args.output));
    io::write_spheres(&args.output, &spheres)?;
    println!(
        "{what}: wrote {} spheres to {}",
        spheres.len(),
        args.output.display()
    );
    Ok(())
}

fn list_backends() {
    for kind in BackendKind::ALL {
        match kind.probe() {
            Ok(device) => println!("{:<14} available on {device}", kind.name()),
            Err(why) => println!("{:<14} unavailable: {why}", kind.name()),
        }
    }
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}
