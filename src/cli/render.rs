//! `mochi render` and the pictures of `mochi simulate --render-every`: frames in, PNG (and an
//! optional animated GIF) out.

use super::args::{Fit, RenderArgs, RenderCommandArgs};
use super::output::{check_output_folder, check_render_output, folder_of};
use anyhow::{Context, Result, bail};
use mochi::dem::scene::SceneConfig;
use mochi::dem::walls::WallSet;
use mochi::io::{self, SERIES_INDEX};
use mochi::render::{
    Camera, ColorBy, Gif, Legend, Picture, Renderer, Scene, parse_point, parse_size, value_range,
};
use std::path::{Path, PathBuf};

/// GIF frame delay [1/100 s].
const GIF_DELAY_CS: u16 = 10;

/// `--fit auto` frames the spheres rather than the box where the diagonal of their
/// [`core_bounds`] is less than this share of the box's.
const AUTO_FIT_SHARE: f64 = 0.5;

/// Share of the centres, on each side of each axis, that [`core_bounds`] leaves out.
const CORE_TAIL: f64 = 0.01;

/// Lower and upper corners \[m\].
type Bounds = ([f64; 3], [f64; 3]);

/// Where most spheres are: on each axis, the centres from the 1st to the 99th percentile,
/// widened by the largest radius (`None` for no spheres). A heap on a floor with a few spheres
/// rolled far away is framed by its heap.
fn core_bounds(positions: &[[f32; 3]], radii: &[f32]) -> Option<Bounds> {
    let n = positions.len();
    let r_max = radii.iter().copied().fold(0.0f32, f32::max) as f64;
    let (lo_at, hi_at) = ((CORE_TAIL * n as f64) as usize, n.checked_sub(1)?);
    let hi_at = hi_at - lo_at;
    let mut bounds = ([0.0; 3], [0.0; 3]);
    let mut axis: Vec<f32> = Vec::with_capacity(n);
    for a in 0..3 {
        axis.clear();
        axis.extend(positions.iter().map(|c| c[a]));
        let lo = *axis.select_nth_unstable_by(lo_at, f32::total_cmp).1;
        let hi = *axis.select_nth_unstable_by(hi_at, f32::total_cmp).1;
        bounds.0[a] = lo as f64 - r_max;
        bounds.1[a] = hi as f64 + r_max;
    }
    Some(bounds)
}

/// Draws frames one after another with one renderer and one set of options.
pub struct FrameRenderer {
    renderer: Renderer,
    view: View,
    color_by: ColorBy,
    range: Option<(f32, f32)>,
    legend: bool,
    /// Where `--gif` asked for the animation.
    gif_path: Option<PathBuf>,
    /// The animation, once [`FrameRenderer::start_gif`] has started it.
    gif: Option<Gif>,
}

/// Where the camera stands and what the picture is like.
struct View {
    size: (u32, u32),
    eye: Option<[f64; 3]>,
    look_at: Option<[f64; 3]>,
    fov: f64,
    samples: u32,
    shadows: bool,
    /// The simulation box, when known and the camera may frame it.
    frame_box: Option<([f64; 3], [f64; 3])>,
    /// Whether the camera frames the spheres instead where they fill little of the box.
    fit_auto: bool,
    /// The box whose bottom is drawn as the floor.
    floor: Option<([f64; 3], [f64; 3])>,
}

impl View {
    /// The picture of a frame whose spheres lie in `bounds`, most of them in `core` (see
    /// [`core_bounds`]).
    fn picture(&self, bounds: Bounds, core: Bounds) -> Picture {
        let diagonal =
            |(lo, hi): Bounds| (0..3).map(|a| (hi[a] - lo[a]).powi(2)).sum::<f64>().sqrt();
        let (lo, hi) = match self.frame_box {
            Some(b) if self.fit_auto && diagonal(core) < AUTO_FIT_SHARE * diagonal(b) => core,
            Some(b) => b,
            None => bounds,
        };
        let aspect = self.size.0 as f64 / self.size.1 as f64;
        let mut camera = Camera::framing(lo, hi, aspect, self.fov);
        if let Some(look_at) = self.look_at {
            camera.look_at = look_at;
        }
        if let Some(eye) = self.eye {
            camera.eye = eye;
        }
        Picture {
            samples: self.samples,
            shadows: self.shadows,
            floor: self.floor,
            ..Picture::new(self.size.0, self.size.1, camera)
        }
    }
}

/// One frame's spheres (parallel slices).
pub struct FrameData<'a> {
    /// Step number, shown at the top left when known.
    pub step: Option<u64>,
    /// Centres [m].
    pub positions: &'a [[f32; 3]],
    /// Radii [m].
    pub radii: &'a [f32],
    /// Velocities [m/s].
    pub velocities: &'a [[f32; 3]],
    /// Materials (empty: one material).
    pub materials: &'a [u8],
    /// The mesh walls' triangles where they are at this frame [m].
    pub walls: &'a [[[f32; 3]; 3]],
}

impl FrameRenderer {
    /// Checks the options and opens the render path (saying which one auto picked). `sim_box`
    /// is the simulation box, if known.
    pub fn new(args: &RenderArgs, sim_box: Option<([f64; 3], [f64; 3])>) -> Result<Self> {
        let range = args.range.as_deref().map(parse_range).transpose()?;
        let view = View {
            size: parse_size(&args.size)?,
            eye: args.eye.as_deref().map(parse_point).transpose()?,
            look_at: args.look_at.as_deref().map(parse_point).transpose()?,
            fov: args.fov,
            samples: args.samples,
            shadows: !args.no_shadows,
            frame_box: sim_box.filter(|_| args.fit != Fit::Spheres),
            fit_auto: args.fit == Fit::Auto,
            floor: sim_box.filter(|_| !args.no_floor),
        };
        // Catch a bad camera or sample count before any work.
        view.picture(([0.0; 3], [1.0; 3]), ([0.0; 3], [1.0; 3]))
            .validate()?;
        if let Some(gif) = &args.gif
            && (view.size.0 > u16::MAX.into() || view.size.1 > u16::MAX.into())
        {
            bail!(
                "--gif {}: a GIF is at most 65535 pixels per side, not {}",
                gif.display(),
                args.size
            );
        }
        let (renderer, reason) = Renderer::open(args.renderer)?;
        if let Some(reason) = reason {
            eprintln!("{reason}");
        }
        Ok(Self {
            renderer,
            view,
            color_by: args.color_by,
            range,
            legend: !args.no_legend,
            gif_path: args.gif.clone(),
            gif: None,
        })
    }

    /// Starts the GIF `--gif` asked for, if any: from now on every picture is added to it.
    pub fn start_gif(&mut self) -> Result<()> {
        if let Some(path) = &self.gif_path {
            io::remove_stale_temp_files(folder_of(path));
            self.gif = Some(Gif::create(path, self.view.size.0, self.view.size.1)?);
        }
        Ok(())
    }

    /// The render path, in one line.
    pub fn describe(&self) -> String {
        self.renderer.describe()
    }

    /// Uses `range` for the colours of every later frame (unless `--range` fixed one).
    pub fn set_range(&mut self, range: (f32, f32)) {
        self.range.get_or_insert(range);
    }

    /// Renders `frame` into the PNG `out` (and the GIF, if any).
    pub fn render(&mut self, frame: &FrameData, out: &Path) -> Result<()> {
        let values = self
            .color_by
            .values(frame.radii, frame.velocities, frame.materials);
        let range = self.range.unwrap_or_else(|| value_range(&values));
        let scene = Scene::new(frame.positions, frame.radii, &values, range)?;
        let spheres = scene.bounds();
        let scene = scene.with_walls(frame.walls)?;
        let bounds = scene.bounds().unwrap_or(([-1.0; 3], [1.0; 3]));
        // The equipment belongs in the picture: where there are walls, the core takes them in.
        let core = match (
            core_bounds(frame.positions, frame.radii),
            frame.walls.is_empty(),
        ) {
            (Some(core), true) => core,
            (Some(core), false) => union(core, bounds),
            (None, _) => spheres.unwrap_or(bounds),
        };
        let picture = self.view.picture(bounds, core);
        let mut image = self.renderer.render(&scene, &picture)?;
        if self.legend {
            image.draw_legend(&Legend {
                label: self.color_by.label().into(),
                min: range.0,
                max: range.1,
            });
            if let Some(step) = frame.step {
                image.draw_caption(&format!("step {step}"));
            }
        }
        image.write_png(out)?;
        if let Some(gif) = &mut self.gif {
            gif.add(&image, GIF_DELAY_CS)?;
        }
        Ok(())
    }

    /// Puts the GIF in place, if one was started and got pictures; returns its path.
    pub fn finish(self) -> Result<Option<PathBuf>> {
        match self.gif {
            Some(gif) if !gif.is_empty() => {
                let path = gif.path().to_owned();
                gif.finish()?;
                Ok(Some(path))
            }
            _ => Ok(None),
        }
    }
}

/// The box around both `a` and `b`.
fn union(a: Bounds, b: Bounds) -> Bounds {
    (
        std::array::from_fn(|k| a.0[k].min(b.0[k])),
        std::array::from_fn(|k| a.1[k].max(b.1[k])),
    )
}

/// The mesh walls of the run in `dir` (its `scene.toml`) and its time step, to draw them where
/// they are at each frame.
pub struct RunWalls {
    walls: WallSet,
    dt: f64,
}

impl RunWalls {
    /// The walls of `walls` moving with time step `dt` [s].
    pub fn new(walls: WallSet, dt: f64) -> Self {
        Self { walls, dt }
    }

    /// The walls the `scene.toml` of `dir` describes (`None` without mesh walls, or with a
    /// warning where they cannot be built, say a mesh file moved since the run).
    pub fn of_run(dir: &Path) -> Option<Self> {
        let path = dir.join(io::SCENE_FILE);
        let config = SceneConfig::load(Some(&path), &[]).ok()?;
        let built = config.walls().map_err(anyhow::Error::from);
        match built.and_then(|w| Ok((w, config.dt.context("the scene names no dt")?))) {
            Ok((walls, _)) if walls.meshes.is_empty() => None,
            Ok((walls, dt)) => Some(Self::new(walls, dt)),
            Err(e) => {
                eprintln!(
                    "warning: the walls of {} are not drawn: {e:#}",
                    path.display()
                );
                None
            }
        }
    }

    /// The triangles at step `step`.
    pub fn at(&self, step: u64) -> Vec<[[f32; 3]; 3]> {
        self.walls.triangles_at(step as f64 * self.dt)
    }
}

/// The walls of `walls` at `step` (none without walls).
fn walls_at(walls: Option<&RunWalls>, step: u64) -> Vec<[[f32; 3]; 3]> {
    walls.map(|w| w.at(step)).unwrap_or_default()
}

/// Parses `MIN,MAX` (finite, MIN ≤ MAX).
fn parse_range(text: &str) -> Result<(f32, f32)> {
    let parsed = text.split_once(',').and_then(|(a, b)| {
        let a: f32 = a.trim().parse().ok()?;
        let b: f32 = b.trim().parse().ok()?;
        (a.is_finite() && b.is_finite() && a <= b).then_some((a, b))
    });
    parsed.with_context(|| format!("range {text:?}: expected MIN,MAX with MIN <= MAX"))
}

/// The scene in the `scene.toml` of `dir`, if there is one that reads.
fn scene_of(dir: &Path) -> Option<SceneConfig> {
    let path = dir.join(io::SCENE_FILE);
    if !path.is_file() {
        return None;
    }
    SceneConfig::load(Some(&path), &[]).ok()
}

/// The simulation box in the `scene.toml` of `dir`, if there is one that says.
pub fn box_of(dir: &Path) -> Option<([f64; 3], [f64; 3])> {
    let config = scene_of(dir)?;
    Some((config.box_lo?, config.box_hi?))
}

/// The files a render of the run in `dir` reads besides its frames: the scene, and the files
/// the scene names (its sphere file, its mesh, its walls' meshes).
fn run_inputs(dir: &Path) -> Vec<PathBuf> {
    let mut inputs = vec![dir.join(io::SCENE_FILE), dir.join(SERIES_INDEX)];
    if let Some(config) = scene_of(dir) {
        let named = [config.input, config.mesh].into_iter().flatten();
        inputs.extend(named.chain(config.wall.into_iter().map(|w| w.mesh)));
    }
    inputs
}

/// Refuses outputs (`-o` and `--gif`) that would take the place of a file of the run in
/// `run_dir` or of an input of the render (`inputs`), or of each other.
fn check_render_outputs(
    run_dir: &Path,
    inputs: &[PathBuf],
    picture: Option<&Path>,
    gif: Option<&Path>,
) -> Result<()> {
    let inputs: Vec<PathBuf> = inputs.iter().cloned().chain(run_inputs(run_dir)).collect();
    if let Some(png) = picture {
        check_render_output(png, "-o", run_dir, &inputs, true)?;
    }
    if let Some(gif) = gif {
        check_render_output(gif, "--gif", run_dir, &inputs, false)?;
        if picture.is_some_and(|png| png == gif || io::same_file(png, gif)) {
            bail!(
                "--gif {} is the picture -o writes: choose another name",
                gif.display()
            );
        }
    }
    Ok(())
}

/// The PNG of the frame of `step` in `dir`.
pub fn png_name(dir: &Path, step: u64) -> PathBuf {
    dir.join(format!("frame_{step:08}.png"))
}

/// `mochi render`.
pub fn render(args: RenderCommandArgs) -> Result<()> {
    let input = &args.input;
    if let Some(gif) = &args.render.gif
        && gif.is_dir()
    {
        bail!("--gif {} is a folder: name the GIF file", gif.display());
    }
    if input.is_dir() {
        return render_folder(input, args.output.as_deref(), &args.render);
    }
    let parent = folder_of(input);
    if input.extension().is_some_and(|e| e == "pvd") {
        // A series' index stands for its folder.
        if input.file_name().is_some_and(|n| n == SERIES_INDEX) {
            return render_folder(parent, args.output.as_deref(), &args.render);
        }
        bail!(
            "{}: render draws frames: give a frame, a run's folder or its {SERIES_INDEX}",
            input.display()
        );
    }
    let out = match &args.output {
        // Into a folder: the frame's name with .png.
        Some(folder) if folder.is_dir() => {
            let name = input.with_extension("png");
            folder.join(name.file_name().unwrap_or(name.as_os_str()))
        }
        Some(file) => file.clone(),
        None => input.with_extension("png"),
    };
    let gif = args.render.gif.as_deref();
    check_render_outputs(parent, std::slice::from_ref(input), Some(&out), gif)?;
    check_output_folder(&out, "-o", None)?;
    if let Some(gif) = gif {
        check_output_folder(gif, "--gif", None)?;
    }
    let frame = io::read_frame(input)?;
    let mut renderer = FrameRenderer::new(&args.render, box_of(parent))?;
    io::remove_stale_temp_files(folder_of(&out));
    renderer.start_gif()?;
    let walls = walls_at(RunWalls::of_run(parent).as_ref(), frame.step.unwrap_or(0));
    renderer.render(
        &FrameData {
            step: frame.step,
            positions: &frame.positions,
            radii: &frame.radii,
            velocities: &frame.velocities,
            materials: &frame.materials,
            walls: &walls,
        },
        &out,
    )?;
    let walls = match walls.len() {
        0 => String::new(),
        n => format!(" with {n} wall triangles"),
    };
    println!(
        "{}: {} spheres{walls} drawn into {} with {}",
        input.display(),
        frame.radii.len(),
        out.display(),
        renderer.describe()
    );
    if let Some(gif) = renderer.finish()? {
        println!("wrote {}", gif.display());
    }
    Ok(())
}

/// Every frame of a folder, with one colour range over all of them (unless `--range` gives one).
fn render_folder(dir: &Path, out: Option<&Path>, args: &RenderArgs) -> Result<()> {
    let files = frames_in(dir)?;
    if files.is_empty() {
        bail!("{}: no frames (frame_*.vtu or frame_*.csv)", dir.display());
    }
    let out = out.unwrap_or(dir);
    if out.exists() && !out.is_dir() {
        bail!(
            "-o {}: the pictures of a folder of frames go into a folder, and this is a file",
            out.display()
        );
    }
    check_render_outputs(dir, &files, None, args.gif.as_deref())?;
    if let Some(gif) = &args.gif {
        check_render_outputs(out, &[], None, Some(gif))?;
        check_output_folder(gif, "--gif", Some(out))?;
    }
    let mut renderer = FrameRenderer::new(args, box_of(dir))?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    io::remove_stale_temp_files(out);
    renderer.start_gif()?;
    if args.range.is_none() {
        // A first pass for one colour range over the whole run (frames are read one at a time).
        let mut lo = f32::INFINITY;
        let mut hi = f32::NEG_INFINITY;
        for file in &files {
            let frame = io::read_frame(file)?;
            let (a, b) = value_range(&args.color_by.values(
                &frame.radii,
                &frame.velocities,
                &frame.materials,
            ));
            lo = lo.min(a);
            hi = hi.max(b);
        }
        if lo <= hi {
            renderer.set_range((lo, hi));
        }
    }
    let run_walls = RunWalls::of_run(dir);
    for (k, file) in files.iter().enumerate() {
        let frame = io::read_frame(file)?;
        let step = frame.step.unwrap_or(k as u64);
        let png = png_name(out, step);
        renderer.render(
            &FrameData {
                step: Some(step),
                positions: &frame.positions,
                radii: &frame.radii,
                velocities: &frame.velocities,
                materials: &frame.materials,
                walls: &walls_at(run_walls.as_ref(), step),
            },
            &png,
        )?;
        eprintln!("{} -> {}", file.display(), png.display());
    }
    println!(
        "{} frames of {} drawn into {} with {}",
        files.len(),
        dir.display(),
        out.display(),
        renderer.describe()
    );
    if let Some(gif) = renderer.finish()? {
        println!("wrote {}", gif.display());
    }
    Ok(())
}

/// The frames of a folder: those its index lists, else its `frame_*.vtu` files, else its
/// `frame_*.csv` files, in name (= step) order.
fn frames_in(dir: &Path) -> Result<Vec<PathBuf>> {
    let index = dir.join(SERIES_INDEX);
    if index.is_file() {
        let entries = io::read_series_index(&index)?;
        return Ok(entries.iter().map(|e| dir.join(e.file_name())).collect());
    }
    let listing = std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))?;
    let mut names: Vec<PathBuf> = Vec::new();
    for entry in listing {
        let path = entry
            .with_context(|| format!("reading {}", dir.display()))?
            .path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if name.starts_with("frame_") && (name.ends_with(".vtu") || name.ends_with(".csv")) {
            names.push(path);
        }
    }
    names.sort();
    let has_vtu = names
        .iter()
        .any(|p| p.extension().is_some_and(|e| e == "vtu"));
    if has_vtu {
        names.retain(|p| p.extension().is_some_and(|e| e == "vtu"));
    }
    Ok(names)
}
