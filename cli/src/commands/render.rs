//! `mochi render` and the pictures of `mochi simulate --render-every`: frames in, PNG (and an
//! optional animated GIF) out.

use super::args::{RenderArgs, RenderCommandArgs};
use super::output::{check_output_folder, check_render_output, folder_of};
use super::view::{Bounds, View, WallAt, union, walls_at};
use anyhow::{Context, Result, bail};
use mochi::dem::scene::{Overrides, SceneConfig};
use mochi::dem::walls::WallSet;
use mochi::io::{self, SERIES_INDEX};
use mochi::render::{
    ColorBy, ColorChoice, Gif, Legend, Renderer, Scene, SphereValues, parse_point, parse_size,
};
use std::path::{Path, PathBuf};

/// GIF frame delay [1/100 s].
const GIF_DELAY_CS: u16 = 10;

/// Draws frames one after another with one renderer and one set of options.
pub struct FrameRenderer {
    renderer: Renderer,
    view: View,
    color_by: ColorChoice,
    range: Option<(f32, f32)>,
    legend: bool,
    /// Where `--gif` asked for the animation.
    gif_path: Option<PathBuf>,
    /// The animation, once [`FrameRenderer::start_gif`] has started it.
    gif: Option<Gif>,
}

/// What a first pass over a run's frames learns, for all its pictures to share: what `auto`
/// colours by (speed if any frame moves, else the last frame's choice), each quantity's range
/// over the run, the region that holds every frame's, and whether any frame reaches the floor.
#[derive(Default)]
pub struct Survey {
    color_by: Option<ColorBy>,
    ranges: Vec<(ColorBy, (f32, f32))>,
    region: Option<Bounds>,
    floor: bool,
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
    /// Contacts each sphere holds (empty: the frame has none).
    pub contacts: &'a [u32],
    /// The mesh walls where they are at this frame.
    pub walls: &'a [WallAt],
}

impl FrameData<'_> {
    /// What its spheres may be coloured by.
    fn values(&self) -> SphereValues<'_> {
        SphereValues {
            positions: self.positions,
            radii: self.radii,
            velocities: self.velocities,
            materials: self.materials,
            contacts: self.contacts,
        }
    }
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
            fit: args.fit,
            sim_box,
            floor_box: sim_box.filter(|_| !args.no_floor),
            run: None,
        };
        // Catch a bad camera or sample count before any work.
        view.picture(&view.frame(&[], &[], &[])).validate()?;
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

    /// Colours every later frame by `color_by`, whatever `--color-by auto` would pick for it.
    pub fn set_color_by(&mut self, color_by: ColorBy) {
        self.color_by = color_by.into();
    }

    /// Adds `frame` to `survey`.
    pub fn survey(&self, frame: &FrameData, survey: &mut Survey) {
        let walls_move = frame.walls.iter().any(WallAt::moves);
        let picked = self
            .color_by
            .resolve(frame.radii, frame.velocities, walls_move);
        if survey.color_by != Some(ColorBy::Speed) {
            survey.color_by = Some(picked);
        }
        for color_by in ColorBy::ALL {
            let values = color_by.values(&frame.values());
            if values.is_empty() {
                continue;
            }
            let (lo, hi) = color_by.range(&values);
            match survey.ranges.iter_mut().find(|(c, _)| *c == color_by) {
                Some((_, range)) => *range = (range.0.min(lo), range.1.max(hi)),
                None => survey.ranges.push((color_by, (lo, hi))),
            }
        }
        let framed = self.view.frame(frame.positions, frame.radii, frame.walls);
        survey.region = Some(match survey.region {
            Some(region) => union(region, framed.region),
            None => framed.region,
        });
        survey.floor |= framed.reaches_floor;
    }

    /// Draws every later frame as `survey` says: its colouring, range (unless `--range` fixed
    /// one), region and floor.
    pub fn settle(&mut self, survey: Survey) {
        if let Some(color_by) = survey.color_by {
            self.set_color_by(color_by);
            if let Some(&(_, range)) = survey.ranges.iter().find(|(c, _)| *c == color_by) {
                self.set_range(range);
            }
        }
        if let Some(region) = survey.region {
            self.view.run = Some((region, survey.floor));
        }
    }

    /// Renders `frame` into the PNG `out` (and the GIF, if any); returns the number of wall
    /// triangles drawn.
    pub fn render(&mut self, frame: &FrameData, out: &Path) -> Result<usize> {
        let walls_move = frame.walls.iter().any(WallAt::moves);
        let color_by = self
            .color_by
            .resolve(frame.radii, frame.velocities, walls_move);
        let values = color_by.values(&frame.values());
        let range = self.range.unwrap_or_else(|| color_by.range(&values));
        let framed = self.view.frame(frame.positions, frame.radii, frame.walls);
        let scene = Scene::new(frame.positions, frame.radii, &values, range)?;
        let scene = scene.with_walls(&framed.walls)?;
        let picture = self.view.picture(&framed);
        let mut image = self.renderer.render(&scene, &picture)?;
        if self.legend {
            image.draw_legend(&Legend {
                label: color_by.label().into(),
                min: range.0,
                max: range.1,
                above: values.iter().any(|&v| v > range.1),
            });
            if let Some(step) = frame.step {
                image.draw_caption(&format!("step {step}"));
            }
        }
        image.write_png(out)?;
        if let Some(gif) = &mut self.gif {
            gif.add(&image, GIF_DELAY_CS)?;
        }
        Ok(framed.walls.len())
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
        let config = SceneConfig::load(Some(&path), &Overrides::default()).ok()?;
        let built = config.walls().map_err(anyhow::Error::from);
        match built.and_then(|w| Ok((w, config.run.dt.context("the scene names no dt")?))) {
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

    /// The walls at step `step`.
    pub fn at(&self, step: u64) -> Vec<WallAt> {
        walls_at(&self.walls, step as f64 * self.dt)
    }
}

/// The walls of a run at `step` (none without walls).
fn run_walls_at(walls: Option<&RunWalls>, step: u64) -> Vec<WallAt> {
    walls.map(|w| w.at(step)).unwrap_or_default()
}

/// What a frame read from a file draws at `step`, with the walls where they are then.
fn read_frame_data<'a>(
    frame: &'a io::OwnedFrame,
    step: Option<u64>,
    walls: &'a [WallAt],
) -> FrameData<'a> {
    FrameData {
        step,
        positions: &frame.positions,
        radii: &frame.radii,
        velocities: &frame.velocities,
        materials: &frame.materials,
        contacts: &frame.contacts,
        walls,
    }
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
    SceneConfig::load(Some(&path), &Overrides::default()).ok()
}

/// The simulation box in the `scene.toml` of `dir`, if there is one that says.
pub fn box_of(dir: &Path) -> Option<([f64; 3], [f64; 3])> {
    let config = scene_of(dir)?;
    Some((config.domain.box_lo?, config.domain.box_hi?))
}

/// The files a render of the run in `dir` reads besides its frames: the scene, and the files
/// the scene names (its sphere file, its mesh, its walls' meshes).
fn run_inputs(dir: &Path) -> Vec<PathBuf> {
    let mut inputs = vec![dir.join(io::SCENE_FILE), dir.join(SERIES_INDEX)];
    if let Some(config) = scene_of(dir) {
        inputs.extend(config.files().map(Path::to_path_buf));
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
    let walls = run_walls_at(RunWalls::of_run(parent).as_ref(), frame.step.unwrap_or(0));
    let drawn = renderer.render(&read_frame_data(&frame, frame.step, &walls), &out)?;
    let walls = match drawn {
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

/// Every frame of a folder, all with one colouring and colour range (unless `--range` gives
/// one), one camera and the floor or not ([`Survey`]).
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
    let run_walls = RunWalls::of_run(dir);
    // A first pass, frames read one at a time, for what every picture of the run shares.
    let mut survey = Survey::default();
    for (k, file) in files.iter().enumerate() {
        let frame = io::read_frame(file)?;
        let step = frame.step.unwrap_or(k as u64);
        let walls = run_walls_at(run_walls.as_ref(), step);
        renderer.survey(&read_frame_data(&frame, Some(step), &walls), &mut survey);
    }
    renderer.settle(survey);
    for (k, file) in files.iter().enumerate() {
        let frame = io::read_frame(file)?;
        let step = frame.step.unwrap_or(k as u64);
        let png = png_name(out, step);
        let walls = run_walls_at(run_walls.as_ref(), step);
        renderer.render(&read_frame_data(&frame, Some(step), &walls), &png)?;
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
