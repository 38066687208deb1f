//! What the command line accepts.

use clap::{Args, Parser, Subcommand};
use mochi::ProxyMode;
use mochi::backend::BackendChoice;
use mochi::backend::wgpu_compute::Structure;
use mochi::scenes::{Layout, Scene};
use std::path::PathBuf;

/// mochi: every pair of touching spheres, found with proxy spheres (Mandarapu et al., ICS '26).
#[derive(Debug, Parser)]
#[command(version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Find every colliding pair in a sphere file or a generated scene, and print a summary.
    Detect(DetectArgs),
    /// Write a generated scene to a sphere file (.csv or .npy).
    Generate(GenerateArgs),
    /// List the backends and whether each can run on this machine.
    Backends,
}

#[derive(Debug, Args)]
pub struct DetectArgs {
    /// Sphere file: CSV with header x,y,z,r, or .npy float32 N×4. Without it, a scene is
    /// generated (see --scene).
    #[arg(conflicts_with_all = ["scene", "n", "seed", "layout"])]
    pub input: Option<PathBuf>,
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Backend to run on; auto picks the fastest that runs here and says which.
    #[arg(long, value_enum, default_value_t)]
    pub backend: BackendChoice,
    /// Proxy boxes: mochi (2·r per sphere) or nns (4·r_max for all, the older reduction).
    #[arg(long, value_enum, default_value_t)]
    pub mode: ProxyMode,
    /// Write the pairs here (CSV i,j, sorted).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Grid of the wgpu-compute backend: grid (single level), mlgrid (multi-level proxy grid,
    /// mochi mode), auto (the single grid until the multi-level one measures faster).
    #[arg(long, value_enum, default_value_t)]
    pub structure: Structure,
    /// Time build and detection this many more times after the first run and report the
    /// median (the first run warms up shaders and buffers).
    #[arg(long, default_value_t = 0)]
    pub repeat: usize,
}

#[derive(Debug, Args)]
pub struct SceneArgs {
    /// Scene to generate.
    #[arg(long, value_enum, default_value_t = Scene::Poly120)]
    pub scene: Scene,
    /// Number of spheres.
    #[arg(
        short = 'n',
        long = "spheres",
        value_name = "N",
        default_value_t = 100_000
    )]
    pub n: usize,
    /// Seed of the generator (same seed, same spheres).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// lattice: jittered lattice without overlaps (default of `generate`, a DEM start state);
    /// random: uniform centres, overlaps allowed (default of `detect`).
    #[arg(long, value_enum)]
    pub layout: Option<Layout>,
}

#[derive(Debug, Args)]
pub struct GenerateArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Output file (.csv or .npy).
    #[arg(short, long)]
    pub output: PathBuf,
}
