//! What the command line accepts.

use clap::{Args, Parser, Subcommand};
use mochi::ProxyMode;
use mochi::engines::wgpu::compute::{GridBuild, Structure};
use mochi::engines::{BackendChoice, RebuildPolicy};
use mochi::render::{ColorChoice, RenderChoice};
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
    /// Run a DEM simulation (by default the built-in `pour`: 4,000 spheres of random radii
    /// collapsing into a heap under Hertz–Mindlin) and write frames ParaView opens (VTK + .pvd).
    Simulate(Box<SimulateArgs>),
    /// Find every colliding pair in a sphere file or a generated scene, and print a summary.
    Detect(DetectArgs),
    /// Write a generated scene to a sphere file (.csv or .npy).
    Generate(GenerateArgs),
    /// Ray trace frames of a simulation (a .vtu or .csv frame, or a folder of them) into PNG
    /// pictures, on the GPU where there is one.
    Render(RenderCommandArgs),
    /// List the backends and whether each can run on this machine.
    Backends,
    /// Run the paper's experiments on every backend: a Markdown table on stdout, JSON and SVG
    /// plots in --out.
    Bench(super::bench::BenchArgs),
}

#[derive(Debug, Args)]
pub struct RenderCommandArgs {
    /// A frame (.vtu as `mochi simulate` writes, a .pvtu of pieces, or .csv/.npy spheres with
    /// or without velocities), or a folder: every frame of its series.pvd (else its
    /// frame_*.vtu files).
    pub input: PathBuf,
    /// Output: the PNG of a single frame (default: next to it, .png), or the folder of the
    /// pictures of a folder (default: the same folder), named frame_<step>.png.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub render: RenderArgs,
}

/// How pictures are drawn (shared by `render` and `simulate --render-every`).
#[derive(Debug, Clone, Args)]
pub struct RenderArgs {
    /// Render path: auto picks the fastest that runs here and says which.
    #[arg(long, value_enum, default_value_t)]
    pub renderer: RenderChoice,
    /// Picture size in pixels, WxH.
    #[arg(long, value_name = "WxH", default_value = "960x720")]
    pub size: String,
    /// Colour the spheres by radius, speed, height (of the centre) or material; auto picks one
    /// for each frame (below), for a folder one for the whole run (speed if any frame moves),
    /// and for simulate --render-every speed.
    #[arg(long, value_enum, default_value_t)]
    pub color_by: ColorChoice,
    /// Values at both ends of the colour map, MIN,MAX (default: the values' own range, speeds
    /// from 0 to their 95th percentile, the legend's top then reading ≥; over all frames when
    /// rendering a folder).
    #[arg(long, value_name = "MIN,MAX", allow_hyphen_values = true)]
    pub range: Option<String>,
    /// Camera position x,y,z [m] (default: from the front left, 33° above the horizon, or 12°
    /// where what is framed is less than half as tall as it is wide, as a heap is, so that
    /// its height shows; far enough that what is framed fills the picture).
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub eye: Option<String>,
    /// The point at the picture's centre, x,y,z [m] (default: the centre of what is framed).
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub look_at: Option<String>,
    /// Vertical field of view [degrees].
    #[arg(long, default_value_t = mochi::render::DEFAULT_FOV_DEG)]
    pub fov: f64,
    /// What the default camera frames: auto (the mesh walls drawn and every sphere, or without
    /// walls most spheres: the 1st to 99th percentile of the centres on each axis, a heap
    /// rather than the few that rolled far), every sphere and wall, or the simulation box
    /// (from scene.toml next to the frames).
    #[arg(long, value_enum, default_value_t)]
    pub fit: Fit,
    /// Rays per pixel side (1-4): 2 gives 4 rays per pixel, smoother edges.
    #[arg(long, default_value_t = 2)]
    pub samples: u32,
    /// No shadow rays.
    #[arg(long)]
    pub no_shadows: bool,
    /// No floor (drawn where the simulation box is known and a sphere comes within 4 largest
    /// radii of its bottom: a checker there).
    #[arg(long)]
    pub no_floor: bool,
    /// No colour legend and step caption.
    #[arg(long)]
    pub no_legend: bool,
    /// Also write every picture into this animated GIF.
    #[arg(long, value_name = "FILE")]
    pub gif: Option<PathBuf>,
}

impl RenderArgs {
    /// The options given other than as their defaults, as flags (`--gif` included).
    pub fn given(&self) -> Vec<&'static str> {
        use clap::{FromArgMatches, Parser};
        /// The picture options alone, to read their defaults.
        #[derive(Parser)]
        struct Defaults {
            #[command(flatten)]
            render: RenderArgs,
        }
        let d = Defaults::try_parse_from(["mochi"])
            .map(|d| d.render)
            .or_else(|_| RenderArgs::from_arg_matches(&Default::default()))
            .expect("the picture options all have defaults");
        let changed = [
            ("--renderer", self.renderer != d.renderer),
            ("--size", self.size != d.size),
            ("--color-by", self.color_by != d.color_by),
            ("--range", self.range.is_some()),
            ("--eye", self.eye.is_some()),
            ("--look-at", self.look_at.is_some()),
            ("--fov", self.fov != d.fov),
            ("--fit", self.fit != d.fit),
            ("--samples", self.samples != d.samples),
            ("--no-shadows", self.no_shadows),
            ("--no-floor", self.no_floor),
            ("--no-legend", self.no_legend),
            ("--gif", self.gif.is_some()),
        ];
        changed
            .into_iter()
            .filter(|&(_, c)| c)
            .map(|(flag, _)| flag)
            .collect()
    }
}

/// What the default camera frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Fit {
    /// The mesh walls drawn and every sphere, or without walls most spheres (the 1st to 99th
    /// percentile of the centres on each axis).
    #[default]
    Auto,
    /// The simulation box (where scene.toml gives it; else every sphere and wall).
    Box,
    /// Every sphere and mesh wall drawn.
    Spheres,
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
    /// mochi mode), auto (the default: mlgrid where the radii span a factor of 4 or more).
    #[arg(long, value_enum)]
    pub structure: Option<Structure>,
    /// How wgpu-compute builds its grid: dense (a table of every cell), sorted (the cell keys
    /// sorted, no table: the cost follows the spheres, not the box), auto (the default: sorted
    /// where the dense table would have more than 1024 cells per sphere).
    #[arg(long, value_enum)]
    pub grid_build: Option<GridBuild>,
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

/// A count the scene (TOML, whose integers are i64) can hold: 0 ..= i64::MAX.
fn toml_integer() -> clap::builder::RangedU64ValueParser {
    clap::value_parser!(u64).range(..=i64::MAX as u64)
}

#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Scene file (TOML; see `mochi::dem::scene`). Without it, the built-in default scene.
    pub scene_file: Option<PathBuf>,
    /// Print the scene as the run takes it (its tables, every derived value written out: the
    /// time step, the box, the material) and exit, running and writing nothing; the output is
    /// a scene file that runs the same.
    #[arg(long)]
    pub print_scene: bool,
    /// Scene: pour (the default: a polydisperse column collapsing into a heap), freefall, slab,
    /// poly1.2, poly12, poly120, polylog, rotating, mesh, input, hopper, drum, agglomerate,
    /// gravel.
    #[arg(long)]
    pub scene: Option<String>,
    /// Number of spheres of a generated scene.
    #[arg(short = 'n', long = "spheres", value_name = "N", value_parser = toml_integer())]
    pub spheres: Option<u64>,
    /// Seed of the scene generator.
    #[arg(long, value_parser = toml_integer())]
    pub seed: Option<u64>,
    /// Steps to run (in total, counting those before a --resume).
    #[arg(long, value_parser = toml_integer())]
    pub steps: Option<u64>,
    /// Time step [s] (default: the scene's).
    #[arg(long, allow_negative_numbers = true)]
    pub dt: Option<f64>,
    /// Start from a sphere file (CSV x,y,z,r or .npy N×4, optionally with vx,vy,vz, then
    /// wx,wy,wz, then each sphere's material, N×7, N×10 or N×11; a CSV may add a `material`
    /// column to any of these: a frame CSV restarts a run) instead of a generated scene.
    #[arg(long, conflicts_with_all = ["scene", "spheres", "seed", "mesh"])]
    pub input: Option<PathBuf>,
    /// Fill this mesh (OBJ, PLY or STL) with spheres and drop it (scene `mesh`; its radius,
    /// size and copies are the keys of [source], short forms mesh_radius, mesh_size,
    /// mesh_copies).
    #[arg(long, value_name = "FILE", conflicts_with_all = ["scene", "spheres"])]
    pub mesh: Option<PathBuf>,
    /// Write a frame every M steps (0: none).
    #[arg(long, value_name = "M", value_parser = toml_integer())]
    pub frame_every: Option<u64>,
    /// Also write every frame as CSV (x,y,z,r,vx,vy,vz,wx,wy,wz,material).
    #[arg(long)]
    pub csv: bool,
    /// Ray trace a PNG picture (OUT/frame_<step>.png) every M steps (0: none); see the
    /// picture options below.
    #[arg(long, value_name = "M", default_value_t = 0)]
    pub render_every: u64,
    #[command(flatten)]
    pub render: RenderArgs,
    /// Grid cells of 2·r_max (mochi) or 4·r_max (nns).
    #[arg(long, value_enum)]
    pub mode: Option<ProxyMode>,
    /// Set any scene field, as TABLE.KEY=VALUE in TOML syntax (repeatable), e.g. --set
    /// material.restitution=0.8 --set 'domain.gravity=[0, 0, -1.62]'; each key has a short
    /// form, e.g. --set contact=linear; a dotted key into a list of tables sets one field of
    /// one, e.g. --set inflow.0.rate=3000 (the first [[inflow]]).
    ///
    /// [material] (SI units): contact = "hertz-mindlin" (default) or "linear" (the paper's
    /// law); density [kg/m³] (500); restitution (0.5); young_modulus [Pa] (1e7: a soft E, as
    /// is normal practice in DEM, since the time step grows as 1/√E) and poisson_ratio (0.3),
    /// hertz-mindlin only; stiffness [N/m] (derived: a 10-step contact of the two lightest
    /// spheres) or "per-pair" with contact_time [s] (10·dt), linear only; friction μ (0.5
    /// hertz-mindlin, 0 linear); wall_friction (= friction); rolling_friction μ_r (0.1
    /// hertz-mindlin, 0 linear); rolling_model = "epsd" (default) or "constant-torque";
    /// tangential_model = "mindlin" (default) or "mindlin-deresiewicz" (hertz-mindlin only).
    /// [run]: steps, dt [s] (hertz-mindlin: 0.2 × the Rayleigh time of the smallest sphere),
    /// mode, frame_every, csv, frame_pieces (under mpirun: each frame one .vtu piece a process
    /// and a .pvtu naming them, none gathered), checkpoint_pieces (under mpirun: each
    /// checkpoint one piece a process and checkpoint.bin naming them, none gathered; a run of
    /// clumps gathers both),
    /// flow_every. [domain]: box_lo, box_hi [m], gravity [m/s²],
    /// gravity_spin [rad/s], box_walls, box_material. [source]: scene, then that scene's keys
    /// (spheres, seed; a mesh's mesh, radius, mixed, size, copies; input; a hopper's or a
    /// drum's). Short forms: each key's own name (mesh_radius for source.radius, hopper_orifice
    /// for source.orifice); see mochi::dem::scene.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Backend to run on; auto picks the fastest that runs here and says which.
    #[arg(long, value_enum, default_value_t)]
    pub backend: BackendChoice,
    /// Grid of the wgpu-compute backend: grid (single level), mlgrid (multi-level proxy grid,
    /// mochi mode), auto (the default: mlgrid where the radii span a factor of 4 or more).
    #[arg(long, value_enum)]
    pub structure: Option<Structure>,
    /// How wgpu-compute builds its grid: dense (a table of every cell), sorted (the cell keys
    /// sorted, no table: the cost follows the spheres, not the box), auto (the default: sorted
    /// where the dense table would have more than 1024 cells per sphere).
    #[arg(long, value_enum)]
    pub grid_build: Option<GridBuild>,
    /// When a refittable BVH (the optix step) is rebuilt: every K steps with refits between
    /// (1: every step), or auto (the default: rebuild once the refitted steps cost more than
    /// the average step since the last rebuild, the rebuild included). Grids re-bin and wgpu-rq
    /// rebuilds every step.
    #[arg(long, value_name = "K|auto")]
    pub rebuild: Option<RebuildPolicy>,
    /// Output folder for frames, checkpoints and the summary (default: mochi-out, or with
    /// --resume the checkpoint's folder). A folder that holds another run (series.pvd,
    /// scene.toml, checkpoint.bin, frame_* files, the clumps', walls' and flows' files) is refused unless
    /// --overwrite or --resume; a folder another run is writing into is refused.
    #[arg(short, long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Replace the run in --out: first remove its files (series.pvd, scene.toml,
    /// checkpoint.bin, frame_*.vtu/.csv/.png, clumps.pvd, clumps_*.vtu, walls.pvd, wall_*.vtp,
    /// walls.csv, flow.csv);
    /// other files in the folder stay.
    #[arg(long, conflicts_with = "resume")]
    pub overwrite: bool,
    /// Save a checkpoint (OUT/checkpoint.bin) every N steps (0: only at the end).
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub checkpoint_every: u64,
    /// Continue the run saved in this checkpoint (its scene; --steps may extend it).
    #[arg(long, value_name = "FILE", conflicts_with_all = ["scene_file", "scene", "spheres", "seed", "dt", "input", "mesh", "mode"])]
    pub resume: Option<PathBuf>,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}
