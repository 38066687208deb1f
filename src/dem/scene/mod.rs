//! DEM scenes: a TOML description that builds the particles at t = 0 and the step parameters.
//! Every field is optional and can be set on the command line (`--set table.key=value`, or a
//! short form `--set key=value`).
//!
//! ```toml
//! [run]
//! steps = 20000
//! dt = 1e-4              # default, hertz-mindlin: 0.2 × the Rayleigh time of the smallest sphere;
//!                        # linear: 1e-4 (freefall, slab, rotating), 5e-5 (poly*), 2.5e-5 (mesh)
//! mode = "mochi"         # or "nns"
//! frame_every = 1000     # 0: no frames
//! csv = false            # CSV frames beside the VTK ones
//! frame_pieces = false   # over several processes: each frame one .vtu piece a process and
//!                        # a .pvtu naming them, none gathered (not with csv)
//! checkpoint_pieces = false # over several processes: each checkpoint one piece a process
//!                        # and an index naming them, none gathered
//! flow_every = 100       # steps between inflow/outflow events (default 1 on cpu, 100 on GPUs)
//!
//! [source]               # where the spheres come from (`source`: each scene's own keys)
//! scene = "pour"         # freefall, slab, poly1.2, poly12, poly120, polylog, pour, rotating,
//!                        # mesh, input, hopper, drum, agglomerate, gravel
//! spheres = 4000
//! seed = 1
//! particle = "tetrahedron" # every grain a clump of one shape, or a mixture: particles =
//!                        # [{ clump = "bean", fraction = 0.3 }, …] (see `particle_mix`)
//!
//! [domain]
//! box_lo = [0, 0, 0]     # default: the scene's box
//! box_hi = [1, 1, 1]
//! gravity = [0, 0, -9.81]
//! gravity_spin = 0.0     # rad/s about y; rotating: 0.25π
//! box_walls = true       # false: the six walls of the box off
//! box_material = "steel" # the box walls' material (a [[materials]] name; default: rigid)
//!
//! [material]             # the scene's material, and the defaults of its [[materials]]
//! contact = "hertz-mindlin" # the default; or "linear" (the paper's law, which the paper's
//!                        # experiments and `mochi bench` name)
//! density = 500
//! restitution = 0.5
//! young_modulus = 1e7    # Pa, hertz-mindlin (default 1e7: a soft E, as is normal practice in DEM,
//!                        # since the time step grows as 1/√E; the bulk behaves much the same)
//! poisson_ratio = 0.3    # hertz-mindlin, in (−1, 0.5) (default 0.3)
//! stiffness = 2.0        # linear: N/m, default a 10-step contact for the two lightest spheres;
//!                        # or "per-pair": k = m*·(π² + ln² e)/contact_time² for each contact
//! contact_time = 1e-3    # s, with stiffness = "per-pair" (default: 10·dt)
//! friction = 0.5         # μ; default 0.5 (hertz-mindlin), 0 (linear)
//! wall_friction = 0.5    # μ with the walls; default: friction
//! rolling_friction = 0.1 # μ_r; default 0.1 (hertz-mindlin), 0 (linear)
//! rolling_model = "epsd" # or "constant-torque" (default epsd)
//! tangential_model = "mindlin" # or "mindlin-deresiewicz" (hertz-mindlin only; default mindlin)
//! cohesion = "jkr"       # JKR adhesion (hertz-mindlin only), "capillary" (liquid bridges) or
//!                        # "sjkr" (LIGGGHTS' simplified JKR); default: dry
//! surface_energy = 0.05  # jkr: J/m², the work of adhesion Γ: spheres pull off at 1.5·π·Γ·R*
//! liquid_volume = 1e-12  # capillary: m³ of liquid in each bridge
//! surface_tension = 0.072 # capillary: N/m (default: water's)
//! contact_angle = 0      # capillary: degrees, from 0 up to 90 (default 0)
//! liquid_viscosity = 1e-3 # capillary: Pa·s, the bridges' lubrication force (default 0: none)
//! # cohesion = "sjkr", cohesion_energy_density = 1e5: LIGGGHTS' simplified JKR (J/m³)
//!
//! [[materials]]          # several materials (see `dem::material_spec`)
//! name = "steel"
//! [[material_pairs]]
//! materials = ["steel", "steel"]
//! [[wall]]               # mesh walls, any number (see `dem::walls::spec`)
//! mesh = "hopper.stl"
//! [[inflow]]             # spheres inserted at a rate (see `dem::flow`)
//! lo = [0.4, 0.4, 0.9]
//! hi = [0.6, 0.6, 0.95]
//! rate = 2000
//! sphere_radius = 0.004
//! [[outflow]]            # spheres removed (and, without box walls, below the box)
//! lo = [0, 0, 0]
//! hi = [1, 1, 0.05]
//! [[clump]]              # grains of clumps of spheres (see `dem::clump_spec`)
//! shape = "tetrahedron"
//! ```
//!
//! Each key of the four tables has a short form, a flat key (`steps`, `spheres`, `friction`;
//! `mesh_radius` for `source.radius`, `hopper_orifice` for `source.orifice`: `short_forms`),
//! which files written before the tables keep using.

mod overrides;
mod particle_mix;
mod short_forms;
mod source;
mod start;
#[cfg(test)]
mod tests;

pub use overrides::Overrides;
pub use source::{Generated, InputFile, MeshFill, SceneKind, Source};

use super::clump_spec::ClumpConfig;
use super::flow::{InflowConfig, OutflowConfig};
use super::material_spec::{MaterialConfig, MaterialPairConfig};
use super::model::{RollingModel, StepParams, TangentialModel};
use super::walls::{WallConfig, WallSet};
use crate::dem::flow::FlowSet;
use crate::error::{Error, Result};
use crate::particles::Particles;
use crate::proxy::ProxyMode;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The normal contact law of a scene (`contact = ...`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ContactKind {
    /// Linear spring–dashpot (the paper's model: its experiments and `mochi bench` name it).
    Linear,
    /// Hertz–Mindlin with Tsuji damping, friction and rolling resistance (the default).
    #[default]
    HertzMindlin,
}

/// Young's modulus of `hertz-mindlin` when the scene gives none \[Pa\]: soft, as practitioners
/// choose it (1e6–1e8 Pa rather than GPa) so that the time step, which grows with 1/√E, stays
/// affordable.
pub const DEFAULT_YOUNG_MODULUS: f64 = 1e7;
/// Poisson's ratio of `hertz-mindlin` when the scene gives none.
pub const DEFAULT_POISSON_RATIO: f64 = 0.3;
/// Friction coefficient μ of `hertz-mindlin` when the scene gives none.
pub const DEFAULT_FRICTION: f64 = 0.5;
/// Surface tension of a capillary scene's liquid when it gives none: water's at 20 °C \[N/m\].
pub const WATER_SURFACE_TENSION: f64 = 0.072;
/// Rolling friction coefficient μ_r of `hertz-mindlin` when the scene gives none.
pub const DEFAULT_ROLLING_FRICTION: f64 = 0.1;

/// The `stiffness` of a `linear` scene: a number in N/m, or `"per-pair"`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "StiffnessText", into = "StiffnessText")]
pub enum Stiffness {
    /// One stiffness for every contact \[N/m\].
    Fixed(f64),
    /// k = m*·(π² + ln² e)/t_c² for each contact, t_c = `contact_time`.
    PerPair,
}

/// How [`Stiffness`] is written in TOML.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(untagged)]
enum StiffnessText {
    Number(f64),
    Word(String),
}

impl TryFrom<StiffnessText> for Stiffness {
    type Error = String;

    fn try_from(text: StiffnessText) -> std::result::Result<Self, String> {
        match text {
            StiffnessText::Number(k) => Ok(Stiffness::Fixed(k)),
            StiffnessText::Word(w) if w == "per-pair" => Ok(Stiffness::PerPair),
            StiffnessText::Word(w) => Err(format!(
                "stiffness must be a number (N/m) or \"per-pair\", got {w:?}"
            )),
        }
    }
}

impl From<Stiffness> for StiffnessText {
    fn from(k: Stiffness) -> Self {
        match k {
            Stiffness::Fixed(k) => StiffnessText::Number(k),
            Stiffness::PerPair => StiffnessText::Word("per-pair".into()),
        }
    }
}

/// The scene fields named command-line options give (`None`: not given). They apply over the
/// scene file, and `--set` overrides apply over them.
#[derive(Debug, Clone, Default, Serialize)]
pub struct SceneFlags {
    /// `--scene`, `--input` (scene `input`) or `--mesh` (scene `mesh`).
    pub scene: Option<SceneKind>,
    /// `-n`.
    pub spheres: Option<u64>,
    /// `--seed`.
    pub seed: Option<u64>,
    /// `--steps`.
    pub steps: Option<u64>,
    /// `--dt`.
    pub dt: Option<f64>,
    /// `--frame-every`.
    pub frame_every: Option<u64>,
    /// `--csv` (given only as `true`).
    pub csv: Option<bool>,
    /// `--input`.
    pub input: Option<PathBuf>,
    /// `--mesh`.
    pub mesh: Option<PathBuf>,
    /// `--mode`.
    pub mode: Option<ProxyMode>,
}

/// A DEM scene (see the module docs for the file format).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneConfig {
    /// How the run goes: steps, time step, output.
    pub run: RunConfig,
    /// Where the spheres come from.
    pub source: Source,
    /// The box, its walls and gravity.
    pub domain: DomainConfig,
    /// The scene's material (the one material, or the defaults of `materials`).
    pub material: SceneMaterial,
    /// Materials, the `[[materials]]` tables (`dem::material_spec`); none: one material,
    /// `material`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub materials: Vec<MaterialConfig>,
    /// Pairs of materials with their own coefficients, the `[[material_pairs]]` tables.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub material_pairs: Vec<MaterialPairConfig>,
    /// Mesh walls, the `[[wall]]` tables (`dem::walls::spec`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub wall: Vec<WallConfig>,
    /// Inflows, the `[[inflow]]` tables (`dem::flow`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub inflow: Vec<InflowConfig>,
    /// Outflows, the `[[outflow]]` tables (`dem::flow`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub outflow: Vec<OutflowConfig>,
    /// The shapes of the grains, the `[[clump]]` tables (`dem::clump_spec`): where there are
    /// any, the generated spheres become clumps of them.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub clump: Vec<ClumpConfig>,
}

/// The `[run]` table: how far a run goes, its time step and what it writes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RunConfig {
    /// Steps to run.
    pub steps: u64,
    /// Time step \[s\]; `None`: the scene's default.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dt: Option<f64>,
    /// `mochi` (cells of 2·r_max) or `nns` (4·r_max).
    #[serde(with = "crate::names::by_name")]
    pub mode: ProxyMode,
    /// Steps between frames (0: none).
    pub frame_every: u64,
    /// Also write each frame as CSV.
    pub csv: bool,
    /// In a run over several processes, write each frame in pieces, each process the piece of
    /// its own spheres, named by a `.pvtu` (instead of gathering every sphere on process 0 for
    /// one `.vtu`). Not with `csv`.
    pub frame_pieces: bool,
    /// In a run over several processes, write each checkpoint in pieces, each process the
    /// piece of its own spheres with their contact history, named by the index written in the
    /// checkpoint's place (instead of gathering every sphere on process 0 for one file); a run
    /// resumes from it on any number of processes.
    pub checkpoint_pieces: bool,
    /// Steps between flow events (default: 1 on the cpu backend, 100 on the GPU backends;
    /// `dem::flow`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub flow_every: Option<u32>,
}

impl Default for RunConfig {
    fn default() -> Self {
        RunConfig {
            steps: 20_000,
            dt: None,
            mode: ProxyMode::Mochi,
            frame_every: 1_000,
            csv: false,
            frame_pieces: false,
            checkpoint_pieces: false,
            flow_every: None,
        }
    }
}

/// The `[domain]` table: the box, its walls and gravity.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DomainConfig {
    /// Lower corner of the box \[m\]; `None`: the scene's box.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub box_lo: Option<[f64; 3]>,
    /// Upper corner of the box \[m\]; `None`: the scene's box.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub box_hi: Option<[f64; 3]>,
    /// Gravity at t = 0 \[m/s²\].
    pub gravity: [f64; 3],
    /// Angular velocity of gravity about the y axis \[rad/s\]; `None`: 0, or 0.25π for `rotating`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gravity_spin: Option<f64>,
    /// Whether the six walls of the box hold the spheres in (default true).
    #[serde(skip_serializing_if = "is_true")]
    pub box_walls: bool,
    /// The box walls' material (a `[[materials]]` name); `None`: rigid walls.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub box_material: Option<String>,
}

impl Default for DomainConfig {
    fn default() -> Self {
        DomainConfig {
            box_lo: None,
            box_hi: None,
            gravity: [0.0, 0.0, -9.81],
            gravity_spin: None,
            box_walls: true,
            box_material: None,
        }
    }
}

fn is_true(x: &bool) -> bool {
    *x
}

/// The `[material]` table: the scene's contact law and material, or, with `[[materials]]`
/// tables, the defaults of their missing keys.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneMaterial {
    /// Normal contact law (default `hertz-mindlin`; `linear` is the paper's law). Always
    /// written, so that a saved scene keeps its law whatever the default.
    pub contact: ContactKind,
    /// Density \[kg/m³\].
    pub density: f64,
    /// Restitution coefficient, in (0, 1] (default 0.5).
    pub restitution: f64,
    /// `linear`: stiffness \[N/m\] or `"per-pair"`; `None`: derived (a 10-step contact for
    /// the lightest pair).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<Stiffness>,
    /// Contact duration of `stiffness = "per-pair"` \[s\]; `None`: 10 time steps.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contact_time: Option<f64>,
    /// Young's modulus of `hertz-mindlin` \[Pa\]; `None`: [`DEFAULT_YOUNG_MODULUS`] (1e7).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub young_modulus: Option<f64>,
    /// Poisson's ratio of `hertz-mindlin`, in (−1, 0.5); `None`: [`DEFAULT_POISSON_RATIO`]
    /// (0.3).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub poisson_ratio: Option<f64>,
    /// Sliding friction coefficient μ, ≥ 0; `None`: 0 (`linear`) or [`DEFAULT_FRICTION`]
    /// (0.5, `hertz-mindlin`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub friction: Option<f64>,
    /// Sliding friction coefficient with the walls, ≥ 0; `None`: `friction`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wall_friction: Option<f64>,
    /// Rolling friction coefficient μ_r, ≥ 0; `None`: 0 (`linear`) or
    /// [`DEFAULT_ROLLING_FRICTION`] (0.1, `hertz-mindlin`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rolling_friction: Option<f64>,
    /// Rolling resistance model, `epsd` or `constant-torque`; `None`: `epsd`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rolling_model: Option<RollingModel>,
    /// Tangential model, `mindlin` (Mindlin's no-slip spring) or `mindlin-deresiewicz` (load
    /// history dependent stiffness; `hertz-mindlin` only); `None`: `mindlin`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tangential_model: Option<TangentialModel>,
    /// Cohesion between the spheres and with the box's walls: `jkr` (`hertz-mindlin` only,
    /// with `surface_energy`); `None`: dry.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cohesion: Option<CohesionKind>,
    /// Work of adhesion Γ of two surfaces of the material \[J/m²\] (`cohesion = "jkr"`: two
    /// spheres pull off at 1.5·π·Γ·R*).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub surface_energy: Option<f64>,
    /// Liquid volume of each bridge \[m³\] (`cohesion = "capillary"`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub liquid_volume: Option<f64>,
    /// Surface tension of the liquid \[N/m\] (`cohesion = "capillary"`; default 0.072, water).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub surface_tension: Option<f64>,
    /// Contact angle of the liquid on the solid \[°\], from 0 up to 90 (`cohesion =
    /// "capillary"`; default 0, fully wetting).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contact_angle: Option<f64>,
    /// Dynamic viscosity of the liquid \[Pa·s\] (`cohesion = "capillary"`; default 0: the
    /// bridges pull but do not resist motion).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub liquid_viscosity: Option<f64>,
    /// Cohesion energy density k \[J/m³\] (`cohesion = "sjkr"`: touching bodies attract with
    /// k times their contact area, as LIGGGHTS' `cohesion sjkr`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cohesion_energy_density: Option<f64>,
}

/// The cohesion of a scene (`cohesion = ...`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CohesionKind {
    /// Johnson, Kendall and Roberts (1971): Hertz's contact with a surface energy, a neck that
    /// holds past touching and breaks at a pull-off distance.
    Jkr,
    /// Pendular liquid bridges (Willett et al. 2000): formed where bodies touch, pulling them
    /// together until they part by the rupture distance (Lian et al. 1993).
    Capillary,
    /// LIGGGHTS' simplified JKR (`cohesion sjkr`): touching bodies attract with an energy
    /// density times their contact area, for calibration parity with LIGGGHTS.
    Sjkr,
}

impl Default for SceneMaterial {
    fn default() -> Self {
        SceneMaterial {
            contact: ContactKind::HertzMindlin,
            density: 500.0,
            restitution: 0.5,
            stiffness: None,
            contact_time: None,
            young_modulus: None,
            poisson_ratio: None,
            friction: None,
            wall_friction: None,
            rolling_friction: None,
            rolling_model: None,
            tangential_model: None,
            cohesion: None,
            surface_energy: None,
            liquid_volume: None,
            surface_tension: None,
            contact_angle: None,
            liquid_viscosity: None,
            cohesion_energy_density: None,
        }
    }
}

/// The fields a resumed run may change: how far it runs and what it writes. Every other field
/// is part of the run's identity and stays as its checkpoint saved it.
pub const RESUMABLE: [&str; 5] = [
    "run.steps",
    "run.frame_every",
    "run.csv",
    "run.frame_pieces",
    "run.checkpoint_pieces",
];

/// Everything a run starts from.
#[derive(Debug, Clone)]
pub struct Start {
    /// Particles at t = 0.
    pub particles: Particles,
    /// Step parameters.
    pub params: StepParams,
    /// Proxy mode of the grid.
    pub mode: ProxyMode,
    /// The walls: the box's (or none) and the mesh walls.
    pub walls: WallSet,
    /// The spheres' ways in and out.
    pub flow: FlowSet,
}

/// The text of a scene file (`None`: no file).
fn read_scene_file(path: Option<&Path>) -> Result<Option<String>> {
    path.map(|p| {
        std::fs::read_to_string(p).map_err(|error| Error::Io {
            path: p.to_owned(),
            error,
        })
    })
    .transpose()
}

/// Where a scene comes from, for errors: its file, or the command line.
fn origin_of(origin: Option<&Path>) -> PathBuf {
    origin.map_or_else(|| "command line".into(), Path::to_owned)
}

/// The table of scene TOML `text` from `origin`, as written (short forms and all).
fn table_of(text: Option<&str>, origin: Option<&Path>) -> Result<toml::Table> {
    text.map_or(Ok(toml::Table::new()), |text| {
        text.parse::<toml::Table>().map_err(|e| Error::Parse {
            path: origin_of(origin),
            line: None,
            msg: e.to_string().trim_end().to_owned(),
        })
    })
}

/// `scene` (a scene's table, in the full form) with `flags`, then `overrides`, set over it.
fn set_over(
    mut scene: toml::Table,
    flags: &SceneFlags,
    overrides: &Overrides,
) -> Result<toml::Table> {
    // Fields left `None` are left out of the table.
    let flagged = toml::Table::try_from(flags).map_err(|e| Error::InvalidConfig {
        what: "scene options".into(),
        reason: format!("cannot be written in TOML: {e}"),
    })?;
    Overrides::from_table(flagged).apply(&mut scene)?;
    overrides.apply(&mut scene)?;
    Ok(scene)
}

/// The value at `table.key` of `scene`, if given.
fn given_at<'a>(scene: &'a toml::Table, table: &str, key: &str) -> Option<&'a toml::Value> {
    scene.get(table)?.as_table()?.get(key)
}

/// Each value of `table` by its dotted path (a table's by its own keys; a list whole).
fn leaves(table: &toml::Table) -> std::collections::BTreeMap<String, &toml::Value> {
    let mut out = std::collections::BTreeMap::new();
    for (key, value) in table {
        match value {
            toml::Value::Table(inner) => {
                out.extend(
                    leaves(inner)
                        .into_iter()
                        .map(|(k, v)| (format!("{key}.{k}"), v)),
                );
            }
            value => {
                out.insert(key.clone(), value);
            }
        }
    }
    out
}

/// Refuses keys of `[source]` in `given` (a new scene's fields, in the full form) that its
/// scene does not take but another does, such as `spheres` with scene `mesh`: each would be
/// silently ignored. The error names the short form and the option that gave it. (A key no
/// scene takes is refused by the scene's deserialization.)
fn refuse_keys_of_another_scene(given: &toml::Table) -> Result<()> {
    let Some(source) = given.get("source").and_then(toml::Value::as_table) else {
        return Ok(());
    };
    let kind = match source.get("scene") {
        None => SceneKind::default(),
        Some(name) => match name.as_str().map(str::parse::<SceneKind>) {
            Some(Ok(kind)) => kind,
            // The scene's deserialization names what is wrong with it.
            _ => return Ok(()),
        },
    };
    let takes = Source::fields(kind);
    let elsewhere = |key: &str| {
        SceneKind::ALL
            .iter()
            .any(|k| Source::fields(*k).contains(&key))
    };
    let Some((key, value)) = source
        .iter()
        .find(|(k, _)| *k != "scene" && !takes.contains(&k.as_str()) && elsewhere(k))
    else {
        return Ok(());
    };
    let short = short_forms::short_form("source", key).unwrap_or(key);
    let option = match short {
        "spheres" => "-n/--set spheres".to_owned(),
        "seed" | "input" | "mesh" => format!("--{short}/--set {short}"),
        _ => format!("--set {short}"),
    };
    let scene_option = match kind {
        SceneKind::Input => "--input/--scene",
        SceneKind::Mesh => "--mesh/--scene",
        _ => "--scene",
    };
    Err(Error::InvalidConfig {
        what: format!("{short} = {value} ({option})"),
        reason: format!(
            "conflicts with scene {:?} ({scene_option}): that scene does not use {short}; give \
             one or the other",
            kind.name()
        ),
    })
}

impl SceneConfig {
    /// Reads a scene file (`None`: the defaults) and applies `overrides`.
    pub fn load(path: Option<&Path>, overrides: &Overrides) -> Result<Self> {
        Self::parse(read_scene_file(path)?.as_deref(), path, overrides)
    }

    /// Reads the scene of a new run: the file (`None`: the defaults), then `flags`, then
    /// `overrides`, refusing fields given (in the file, by a flag or by an override) that the
    /// chosen scene does not use, such as `spheres` or `input` with a `mesh` scene: each would
    /// be silently ignored.
    pub fn load_new(
        path: Option<&Path>,
        flags: &SceneFlags,
        overrides: &Overrides,
    ) -> Result<Self> {
        let text = read_scene_file(path)?;
        let file = short_forms::nest(table_of(text.as_deref(), path)?)?;
        let given = set_over(file, flags, overrides)?;
        refuse_keys_of_another_scene(&given)?;
        let mut config = Self::read(&given, text.as_deref(), path)?;
        config.rebase(path);
        config.make_paths_absolute()?;
        config.refuse_idle_keys(&given)?;
        Ok(config)
    }

    /// Refuses keys of `given` (the fields a new scene gives) that would have no effect in this
    /// scene: `flow_every` without any flow, `rolling_model` without rolling friction.
    fn refuse_idle_keys(&self, given: &toml::Table) -> Result<()> {
        let idle = |key: &str, reason: &str| Error::InvalidConfig {
            what: format!("scene key {key}"),
            reason: format!("{reason}: leave it out, or add what it acts on"),
        };
        let flows = !(self.inflow.is_empty() && self.outflow.is_empty() && self.domain.box_walls)
            || matches!(self.source, Source::Hopper(_));
        if given_at(given, "run", "flow_every").is_some() && !flows {
            return Err(idle(
                "flow_every",
                "sets the steps between flow events, and this scene has no [[inflow]] or \
                 [[outflow]] tables (nor box_walls = false, whose floor drains)",
            ));
        }
        let m = self.material()?;
        if given_at(given, "material", "rolling_model").is_some() && m.rolling_friction == 0.0 {
            return Err(idle(
                "rolling_model",
                "chooses the law of rolling resistance, and this scene's rolling_friction is 0",
            ));
        }
        if given_at(given, "material", "tangential_model").is_some()
            && m.friction == 0.0
            && m.wall_friction.unwrap_or(m.friction) == 0.0
        {
            return Err(idle(
                "tangential_model",
                "chooses the law of the tangential force, and this scene's friction and \
                 wall_friction are 0",
            ));
        }
        Ok(())
    }

    /// Parses scene TOML (`None`: the defaults) from `origin` (named in errors; relative input
    /// paths are taken from its folder) and applies `overrides`.
    pub fn parse(text: Option<&str>, origin: Option<&Path>, overrides: &Overrides) -> Result<Self> {
        let file = short_forms::nest(table_of(text, origin)?)?;
        let scene = set_over(file, &SceneFlags::default(), overrides)?;
        let mut config = Self::read(&scene, text, origin)?;
        config.rebase(origin);
        Ok(config)
    }

    /// The scene of `table` (in the full form), read from `text` when that is what it holds
    /// (so that errors quote the file's own line), else from the table itself (short forms,
    /// flags or overrides changed it: an error names the key, and its short form).
    fn read(table: &toml::Table, text: Option<&str>, origin: Option<&Path>) -> Result<Self> {
        let table = &particle_mix::into_clump_tables(table.clone())?;
        let refused = |msg: String| Error::Parse {
            path: origin_of(origin),
            line: None,
            msg,
        };
        if let Some(text) = text.filter(|t| t.parse::<toml::Table>().is_ok_and(|t| &t == table)) {
            return toml::from_str(text).map_err(|e| refused(e.to_string().trim_end().to_owned()));
        }
        serde_path_to_error::deserialize(toml::Value::Table(table.clone())).map_err(|e| {
            let key = e.path().to_string().replace('[', ".").replace(']', "");
            let message = e.into_inner().message().trim_end().to_owned();
            let short = key
                .split_once('.')
                .and_then(|(table, field)| short_forms::short_form(table, field))
                .map_or(String::new(), |s| format!(" ({s})"));
            refused(match key.as_str() {
                "." => message,
                // `[source]`'s own struct names its key: `spheres of scene "pour": …`.
                "source" => {
                    let (field, rest) = message.split_once(' ').unwrap_or((&message, ""));
                    let short = short_forms::short_form("source", field)
                        .map_or(String::new(), |s| format!(" ({s})"));
                    format!("scene key source.{field}{short} {rest}")
                }
                key => format!("scene key {key}{short}: {message}"),
            })
        })
    }

    /// The files the scene reads: its sphere file or mesh, its walls' meshes and its clumps'.
    pub fn files(&self) -> impl Iterator<Item = &Path> {
        let walls = self.wall.iter().map(|w| w.mesh.as_path());
        let clumps = self.clump.iter().flat_map(|c| [&c.mesh, &c.file]);
        let clumps = clumps.filter_map(|path| path.as_deref());
        self.source.file().into_iter().chain(walls).chain(clumps)
    }

    /// The scene's input and mesh paths.
    fn paths_mut(&mut self) -> impl Iterator<Item = &mut PathBuf> {
        let walls = self.wall.iter_mut().map(|w| &mut w.mesh);
        let clumps = self
            .clump
            .iter_mut()
            .flat_map(|c| [&mut c.mesh, &mut c.file]);
        let clumps = clumps.filter_map(|path| path.as_mut());
        self.source
            .file_mut()
            .into_iter()
            .chain(walls)
            .chain(clumps)
    }

    /// Takes relative input and mesh paths from the folder of `origin`.
    fn rebase(&mut self, origin: Option<&Path>) {
        if let Some(dir) = origin.and_then(Path::parent) {
            for path in self.paths_mut().filter(|p| p.is_relative()) {
                *path = dir.join(&*path);
            }
        }
    }

    /// Makes every input and mesh path absolute (from the current folder), so that the scene
    /// saved in a run's folder and its checkpoints names the same files from anywhere.
    fn make_paths_absolute(&mut self) -> Result<()> {
        for path in self.paths_mut().filter(|p| p.is_relative()) {
            *path = std::path::absolute(&*path).map_err(|error| Error::Io {
                path: path.clone(),
                error,
            })?;
        }
        Ok(())
    }

    /// The scene saved in the checkpoint `origin` (`saved`, its TOML, in the full form or the
    /// flat one of older checkpoints) with `flags`, then `overrides`, applied. A resumed run
    /// keeps its identity: only the fields of [`RESUMABLE`] may change; any other flag or
    /// override that changes a value is refused, naming the field. Paths stay as saved.
    pub fn resume(
        saved: &str,
        origin: &Path,
        flags: &SceneFlags,
        overrides: &Overrides,
    ) -> Result<Self> {
        let scene = short_forms::saved_scene(table_of(Some(saved), Some(origin))?)?;
        let before = Self::read(&scene, None, Some(origin))?;
        let after = Self::read(&set_over(scene, flags, overrides)?, None, Some(origin))?;
        let fields = |c: &SceneConfig| toml::Table::try_from(c).expect("a scene serializes");
        let (was, now) = (fields(&before), fields(&after));
        let (was, now) = (leaves(&was), leaves(&now));
        let mut keys = was
            .keys()
            .chain(now.keys().filter(|k| !was.contains_key(*k)));
        let changed = keys.find(|k| !RESUMABLE.contains(&k.as_str()) && was.get(*k) != now.get(*k));
        if let Some(key) = changed {
            let saved = was.get(key).map_or("unset".into(), ToString::to_string);
            let short = key
                .split_once('.')
                .and_then(|(table, field)| short_forms::short_form(table, field));
            return Err(Error::InvalidConfig {
                what: format!("--set {}", short.unwrap_or(key)),
                reason: format!(
                    "a resumed run keeps the scene of its checkpoint ({key} = {saved}); only \
                     steps, frame_every, csv, frame_pieces and checkpoint_pieces ({}) may change on --resume. To change {key}, \
                     start a new run from the last frame (--input OUT/frame_<step>.csv)",
                    RESUMABLE.join(", ")
                ),
            });
        }
        Ok(after)
    }

    /// This scene (a run's) with `overrides` applied between the steps of its run: the
    /// material keys (`material.*`, `[[material_pairs]]`, `[[materials]]` with their names in
    /// their order), gravity now, each `[[wall]]`'s `friction` and `material`, the time step,
    /// and what [`RESUMABLE`] names. Any other change is refused, naming the key: the spheres,
    /// the box, the walls' geometry and the flows are the run's.
    pub fn changed(&self, overrides: &Overrides) -> Result<Self> {
        let fields = |c: &SceneConfig| toml::Table::try_from(c).expect("a scene serializes");
        let table = set_over(fields(self), &SceneFlags::default(), overrides)?;
        let after = Self::read(&table, None, None)?;
        let (was, now) = (fields(self), fields(&after));
        let (was, now) = (leaves(&was), leaves(&now));
        let names = |c: &SceneConfig| {
            c.materials
                .iter()
                .map(|m| m.name.clone())
                .collect::<Vec<_>>()
        };
        let geometry = |c: &SceneConfig| {
            let fixed = |w: &WallConfig| WallConfig {
                friction: None,
                material: None,
                ..w.clone()
            };
            c.wall.iter().map(fixed).collect::<Vec<_>>()
        };
        let may_change = |key: &str| match key {
            "materials" => names(self) == names(&after),
            "wall" => geometry(self) == geometry(&after),
            "material_pairs" | "domain.gravity" | "run.dt" => true,
            key => key.starts_with("material.") || RESUMABLE.contains(&key),
        };
        let mut keys = was
            .keys()
            .chain(now.keys().filter(|k| !was.contains_key(*k)));
        if let Some(key) = keys.find(|k| was.get(*k) != now.get(*k) && !may_change(k)) {
            let short = key
                .split_once('.')
                .and_then(|(table, field)| short_forms::short_form(table, field));
            let named = short.map_or(key.clone(), |s| format!("{key} ({s})"));
            return Err(Error::InvalidConfig {
                what: format!("scene key {named}"),
                reason: "cannot change between steps: a run's spheres, box, walls' geometry \
                         and flows are set at its start (the materials, gravity, the time step \
                         and the walls' friction and material may change, the materials' names \
                         and order kept); start a new run from the state now to change it"
                    .into(),
            });
        }
        Ok(after)
    }

    /// This scene as TOML (saved in checkpoints).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a scene always serializes")
    }

    /// Which kind of scene this is.
    pub fn scene(&self) -> SceneKind {
        self.source.kind()
    }
}
