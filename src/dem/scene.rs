//! DEM scenes: a TOML description (every field optional, every field overridable with
//! `key=value` on the command line) that builds the particles at t = 0 and the step parameters.
//!
//! ```toml
//! scene = "pour"         # freefall, slab, poly1.2, poly12, poly120, polylog, pour, rotating,
//!                        # mesh, input, hopper, drum
//! spheres = 4000
//! seed = 1
//! steps = 20000
//! dt = 1e-4              # default, hertz-mindlin: 0.2 × the Rayleigh time of the smallest sphere;
//!                        # linear: 1e-4 (freefall, slab, rotating), 5e-5 (poly*), 2.5e-5 (mesh)
//! box_lo = [0, 0, 0]     # default: the scene's box
//! box_hi = [1, 1, 1]
//! gravity = [0, 0, -9.81]
//! gravity_spin = 0.0     # rad/s about y; rotating: 0.25π
//! density = 500
//! restitution = 0.5
//! contact = "hertz-mindlin" # the default; or "linear" (the paper's law, which the paper's
//!                        # experiments and `mochi bench` name)
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
//! mode = "mochi"         # or "nns"
//! frame_every = 1000     # 0: no frames
//! csv = false            # CSV frames beside the VTK ones
//! input = "start.csv"    # scene = "input": any sphere file (velocity columns optional)
//! mesh = "bunny.obj"     # scene = "mesh": OBJ, PLY or STL (default: a torus)
//! mesh_radius = 0.005    # spacing 2.2 times it
//! mesh_mixed = false     # half of the spheres at mesh_radius / 2
//! mesh_size = 0.818      # the mesh fitted into a cube of this side
//! mesh_copies = 1        # copies side by side, in layers if needed
//! grain_radius = 0.004   # hopper, drum: mean radius (radii U[0.9, 1.1] of it)
//! hopper_orifice = 0.04  # hopper: orifice diameter [m]
//! hopper_angle = 0       # hopper: bottom's angle from the horizontal [°] (0: flat)
//! hopper_open = 0.2      # hopper: time the gate under the orifice slides away [s]
//! drum_omega = 3.0       # drum: angular speed about y [rad/s]
//! drum_sides = 64        # drum: the tube's sides around (2·sides·rings triangles)
//! drum_rings = 1         # drum: the tube's rings along its length
//! box_walls = true       # false: the six walls of the box off
//! flow_every = 100       # steps between inflow/outflow events (default 1 on cpu, 100 on GPUs)
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
//! ```

use super::equipment::{Built, Equipment, EquipmentSpec};
use super::flow::{FlowSet, InflowConfig, OutflowConfig};
use super::material_spec::{self, MaterialConfig, MaterialPairConfig, material_index};
use super::model::contact::moment_of_inertia;
use super::model::time_step::{RAYLEIGH_FRACTION, rayleigh_time};
use super::model::{
    ContactLaw, Material, Materials, RollingModel, StepParams, TangentialModel, mass,
};
use super::walls::{WallConfig, WallSet};
use crate::error::{Error, Result};
use crate::numbers::widened;
use crate::particles::Particles;
use crate::proxy::ProxyMode;
use crate::scenes::{self, Layout, Scene, SceneSpec};
use crate::spheres::SphereSet;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// What the `scene` field names: a generated scene of [`Scene`], `rotating` (freefall under
/// rotating gravity), `mesh` (a filled mesh) or `input` (a sphere file). Its names
/// ([`Named`](crate::names::Named)) are read alike in TOML and on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum SceneKind {
    /// A generated scene.
    Generated(Scene),
    /// `freefall` under gravity rotating about the y axis.
    Rotating,
    /// A mesh filled with spheres.
    Mesh,
    /// The spheres of a file.
    Input,
    /// A hopper draining through its orifice (`dem::equipment`).
    Hopper,
    /// A turning drum (`dem::equipment`).
    Drum,
}

impl SceneKind {
    /// Every scene, in the order errors list them.
    pub const ALL: [SceneKind; 12] = [
        SceneKind::Generated(Scene::Freefall),
        SceneKind::Generated(Scene::Slab),
        SceneKind::Generated(Scene::Poly1_2),
        SceneKind::Generated(Scene::Poly12),
        SceneKind::Generated(Scene::Poly120),
        SceneKind::Generated(Scene::Polylog),
        SceneKind::Generated(Scene::Pour),
        SceneKind::Rotating,
        SceneKind::Mesh,
        SceneKind::Input,
        SceneKind::Hopper,
        SceneKind::Drum,
    ];

    /// Name, as in TOML and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            SceneKind::Generated(scene) => scene.name(),
            SceneKind::Rotating => "rotating",
            SceneKind::Mesh => "mesh",
            SceneKind::Input => "input",
            SceneKind::Hopper => "hopper",
            SceneKind::Drum => "drum",
        }
    }

    /// Where the spheres come from (`rotating` is freefall).
    fn source(self) -> Source {
        match self {
            SceneKind::Generated(scene) => Source::Generated(scene),
            SceneKind::Rotating => Source::Generated(Scene::Freefall),
            SceneKind::Mesh => Source::Mesh,
            SceneKind::Input => Source::Input,
            SceneKind::Hopper => Source::Equipment(Equipment::Hopper),
            SceneKind::Drum => Source::Equipment(Equipment::Drum),
        }
    }
}

/// Where a scene's spheres come from.
#[derive(Debug, Clone, Copy)]
enum Source {
    Generated(Scene),
    Mesh,
    Input,
    Equipment(Equipment),
}

impl crate::names::Named for SceneKind {
    const ALL: &'static [Self] = &Self::ALL;

    fn name(self) -> &'static str {
        SceneKind::name(self)
    }
}

#[cfg(feature = "clap")]
impl clap::ValueEnum for SceneKind {
    fn value_variants<'a>() -> &'a [Self] {
        &Self::ALL
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        use clap::builder::PossibleValue;
        Some(match self {
            SceneKind::Generated(scene) => return scene.to_possible_value(),
            SceneKind::Rotating => PossibleValue::new("rotating")
                .help("freefall under gravity rotating about y (gravity_spin 0.25π rad/s)"),
            SceneKind::Mesh => PossibleValue::new("mesh").help("a mesh (mesh = FILE) filled"),
            SceneKind::Input => PossibleValue::new("input").help("the spheres of input = FILE"),
            SceneKind::Hopper => PossibleValue::new("hopper")
                .help("a hopper with a circular orifice, filled, then opened (mesh walls and an outflow)"),
            SceneKind::Drum => PossibleValue::new("drum")
                .help("a drum about a horizontal axis, 40% filled, turning (a mesh wall: cpu, wgpu-compute, wgpu-rq)"),
        })
    }
}

impl std::str::FromStr for SceneKind {
    type Err = String;

    /// `name` in any case.
    fn from_str(name: &str) -> std::result::Result<Self, String> {
        crate::names::parse(name, "scene")
    }
}

impl TryFrom<String> for SceneKind {
    type Error = String;

    fn try_from(name: String) -> std::result::Result<Self, String> {
        name.parse()
    }
}

impl From<SceneKind> for String {
    fn from(scene: SceneKind) -> String {
        scene.name().to_owned()
    }
}

impl std::fmt::Display for SceneKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

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

/// The `contact` of a saved scene that names none: scenes were saved without it while
/// `linear` was the default, and only then.
const SAVED_CONTACT_DEFAULT: &str = "contact = \"linear\"";

/// Young's modulus of `hertz-mindlin` when the scene gives none \[Pa\]: soft, as practitioners
/// choose it (1e6–1e8 Pa rather than GPa) so that the time step, which grows with 1/√E, stays
/// affordable.
pub const DEFAULT_YOUNG_MODULUS: f64 = 1e7;
/// Poisson's ratio of `hertz-mindlin` when the scene gives none.
pub const DEFAULT_POISSON_RATIO: f64 = 0.3;
/// Friction coefficient μ of `hertz-mindlin` when the scene gives none.
pub const DEFAULT_FRICTION: f64 = 0.5;
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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneConfig {
    /// Where the spheres come from.
    pub scene: SceneKind,
    /// Number of spheres (generated scenes).
    pub spheres: usize,
    /// Seed of the generator.
    pub seed: u64,
    /// Steps to run.
    pub steps: u64,
    /// Time step \[s\]; `None`: the scene's default.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dt: Option<f64>,
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
    /// Density \[kg/m³\].
    pub density: f64,
    /// Restitution coefficient, in (0, 1] (default 0.5).
    pub restitution: f64,
    /// Normal contact law (default `hertz-mindlin`; `linear` is the paper's law). Always
    /// written, so that a saved scene keeps its law whatever the default.
    pub contact: ContactKind,
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
    /// Materials, the `[[material]]` tables (`dem::material_spec`); none: one material, the
    /// top-level keys'.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub material: Vec<MaterialConfig>,
    /// Pairs of materials with their own coefficients, the `[[material_pair]]` tables.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub material_pair: Vec<MaterialPairConfig>,
    /// The box walls' material (a `[[material]]` name); `None`: rigid walls.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub box_material: Option<String>,
    /// `mochi` (cells of 2·r_max) or `nns` (4·r_max).
    #[serde(with = "crate::names::by_name")]
    pub mode: ProxyMode,
    /// Steps between frames (0: none).
    pub frame_every: u64,
    /// Also write each frame as CSV.
    pub csv: bool,
    /// Sphere file of scene `input` (CSV x,y,z,r or .npy N×4), relative to the scene file.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub input: Option<PathBuf>,
    /// Mesh of scene `mesh` (OBJ, PLY or STL), relative to the scene file; `None`: a torus.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mesh: Option<PathBuf>,
    /// Sphere radius of scene `mesh` \[m\]; the lattice spacing is 2.2 times it.
    pub mesh_radius: f32,
    /// Scene `mesh`: half of the spheres (at random) get radius `mesh_radius / 2`.
    pub mesh_mixed: bool,
    /// Scene `mesh`: side of the cube the mesh is fitted into \[m\] (0.818 holds the paper's
    /// 82,337-sphere bunny at radius 0.005).
    pub mesh_size: f64,
    /// Scene `mesh`: copies dropped side by side (in layers when they do not fit one).
    pub mesh_copies: u32,
    /// Whether the six walls of the box hold the spheres in (default true).
    #[serde(skip_serializing_if = "is_true")]
    pub box_walls: bool,
    /// Mesh walls, the `[[wall]]` tables (`dem::walls::spec`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub wall: Vec<WallConfig>,
    /// Inflows, the `[[inflow]]` tables (`dem::flow`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub inflow: Vec<InflowConfig>,
    /// Outflows, the `[[outflow]]` tables (`dem::flow`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub outflow: Vec<OutflowConfig>,
    /// Steps between flow events (default: 1 on the cpu backend, 100 on the GPU backends;
    /// `dem::flow`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub flow_every: Option<u32>,
    /// Scenes `hopper` and `drum`: mean sphere radius \[m\] (default 0.004).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub grain_radius: Option<f64>,
    /// Scene `hopper`: orifice diameter \[m\] (default 0.04).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hopper_orifice: Option<f64>,
    /// Scene `hopper`: angle of the bottom from the horizontal \[°\] (default 0: flat).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hopper_angle: Option<f64>,
    /// Scene `hopper`: time the gate under the orifice slides away \[s\] (default 0.2).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hopper_open: Option<f64>,
    /// Scene `drum`: angular speed about y \[rad/s\] (default 3).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub drum_omega: Option<f64>,
    /// Scene `drum`: sides of its tube around (default 64).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub drum_sides: Option<u32>,
    /// Scene `drum`: rings of its tube along its length (default 1).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub drum_rings: Option<u32>,
}

fn is_true(x: &bool) -> bool {
    *x
}

impl Default for SceneConfig {
    fn default() -> Self {
        Self {
            scene: SceneKind::Generated(Scene::Pour),
            spheres: 4_000,
            seed: 1,
            steps: 20_000,
            dt: None,
            box_lo: None,
            box_hi: None,
            gravity: [0.0, 0.0, -9.81],
            gravity_spin: None,
            density: 500.0,
            restitution: 0.5,
            contact: ContactKind::HertzMindlin,
            stiffness: None,
            contact_time: None,
            young_modulus: None,
            poisson_ratio: None,
            friction: None,
            wall_friction: None,
            rolling_friction: None,
            rolling_model: None,
            tangential_model: None,
            material: Vec::new(),
            material_pair: Vec::new(),
            box_material: None,
            mode: ProxyMode::Mochi,
            frame_every: 1_000,
            csv: false,
            input: None,
            mesh: None,
            mesh_radius: 0.005,
            mesh_mixed: false,
            mesh_size: 0.818,
            mesh_copies: 1,
            box_walls: true,
            wall: Vec::new(),
            inflow: Vec::new(),
            outflow: Vec::new(),
            grain_radius: None,
            hopper_orifice: None,
            hopper_angle: None,
            hopper_open: None,
            drum_omega: None,
            drum_sides: None,
            drum_rings: None,
            flow_every: None,
        }
    }
}

/// The fields a resumed run may change: how far it runs and what it writes. Every other field
/// is part of the run's identity and stays as its checkpoint saved it.
pub const RESUMABLE: [&str; 3] = ["steps", "frame_every", "csv"];

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

/// Refuses spheres of radius `r_max` (the largest) whose mass or moment of inertia at
/// `density` overflows single precision, naming the largest radius that density allows.
fn check_heaviest(density: f64, r_max: f32) -> Result<()> {
    let m = mass(density as f32, r_max);
    if m.is_finite() && moment_of_inertia(m, r_max).is_finite() {
        return Ok(());
    }
    // 0.4·ρ·(4/3)π·r⁵ is the moment of inertia, the first to overflow for r > 1.
    let largest = (f32::MAX as f64 / (0.4 * density * 4.0 / 3.0 * std::f64::consts::PI))
        .powf(0.2)
        .min((f32::MAX as f64 / (density * 4.0 / 3.0 * std::f64::consts::PI)).cbrt());
    Err(Error::InvalidConfig {
        what: format!("spheres of radius {r_max:e} m"),
        reason: format!(
            "at density {density:e} kg/m³ their mass ({m:e} kg) or moment of inertia is beyond \
             single precision (3.4e38); the largest radius this density allows is {largest:.3e} m"
        ),
    })
}

/// The height of the box's floor: `box_lo`'s where the scene gives it, else the default's.
fn box_lo_z(box_lo: Option<[f64; 3]>, default_lo: [f64; 3]) -> f64 {
    box_lo.unwrap_or(default_lo)[2]
}

/// Scene fields set over a scene file and the flags, in order: from `--set key=value`
/// assignments ([`Overrides::parse`]) or from a table of fields ([`Overrides::from_table`], as
/// Python's scene dict is), so a value is read once, by the scene's own deserialization. A
/// dotted key reaches into the scene's tables: `inflow.0.rate=3000` sets the rate of the first
/// `[[inflow]]` table and leaves its other fields as they are.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides(Vec<(Vec<String>, toml::Value)>);

impl Overrides {
    /// From `key=value` assignments, in order (`value` in TOML syntax; a bare word is taken as
    /// a string, so `scene=slab` works; `key` a field, or a dotted path into a table or an
    /// array of tables by index).
    pub fn parse(assignments: &[impl AsRef<str>]) -> Result<Self> {
        assignments
            .iter()
            .map(|a| parse_override(a.as_ref()))
            .collect::<Result<_>>()
            .map(Overrides)
    }

    /// From a table of fields (each key a field of the scene file, each value as the file
    /// would give it).
    pub fn from_table(table: toml::Table) -> Self {
        Overrides(table.into_iter().map(|(k, v)| (vec![k], v)).collect())
    }

    /// Whether no field is set.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Sets each field in `table` (a scene's), in order: a field replaced whole, a dotted path
    /// set where it leads (tables on the way made where missing; an index of an array of tables
    /// must name one of them).
    fn apply(&self, table: &mut toml::Table) -> Result<()> {
        for (path, value) in &self.0 {
            set_at(table, path, &path.join("."), value)?;
        }
        Ok(())
    }
}

/// Sets `value` at `path` (at least one key) under `table`; `key` is the whole path, for errors.
fn set_at(table: &mut toml::Table, path: &[String], key: &str, value: &toml::Value) -> Result<()> {
    let bad = |reason: String| Error::InvalidConfig {
        what: format!("--set {key}"),
        reason,
    };
    let (first, rest) = path.split_first().expect("a key has a name");
    if rest.is_empty() {
        table.insert(first.clone(), value.clone());
        return Ok(());
    }
    let indexed = rest[0].parse::<usize>().is_ok();
    if indexed && !table.contains_key(first) {
        return Err(bad(format!("there are no {first} tables here to index")));
    }
    match table
        .entry(first.clone())
        .or_insert_with(|| toml::Value::Table(toml::Table::new()))
    {
        toml::Value::Table(inner) => set_at(inner, rest, key, value),
        toml::Value::Array(items) => {
            let (index, after) = rest.split_first().expect("rest is not empty");
            let k: usize = index.parse().map_err(|_| {
                bad(format!(
                    "{first} is a list of tables: the part after it is an index, from 0"
                ))
            })?;
            let len = items.len();
            match items.get_mut(k) {
                Some(toml::Value::Table(inner)) if !after.is_empty() => {
                    set_at(inner, after, key, value)
                }
                Some(toml::Value::Table(_)) => Err(bad(format!(
                    "{first}.{k} is a table: name the field of it to set"
                ))),
                Some(other) => Err(bad(format!("{first}.{k} is {other}, not a table"))),
                None => Err(bad(format!(
                    "there are {len} {first} tables here, {first}.0 to {first}.{}",
                    len.saturating_sub(1)
                ))),
            }
        }
        other => Err(bad(format!("{first} is {other}, not a table"))),
    }
}

/// Parses a `key=value` override (`value` in TOML syntax; a bare word is taken as a string, so
/// `scene=slab` works; `key` a field or a dotted path of fields and indices).
fn parse_override(assignment: &str) -> Result<(Vec<String>, toml::Value)> {
    let bad = |reason: String| Error::InvalidConfig {
        what: format!("--set {assignment:?}"),
        reason,
    };
    let (key, value) = assignment
        .split_once('=')
        .ok_or_else(|| bad("expected key=value".into()))?;
    let key = key.trim();
    let path: Vec<String> = key.split('.').map(str::to_owned).collect();
    let named = |part: &String| {
        !part.is_empty() && part.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
    };
    if !path.iter().all(named) || path[0].chars().all(|c| c.is_ascii_digit()) {
        return Err(bad(format!("{key:?} is not a field name")));
    }
    let value = value.trim();
    let parsed: toml::Value = match format!("v = {value}").parse::<toml::Table>() {
        Ok(mut t) => t.remove("v").expect("parsed the key v"),
        Err(_) if is_integer(value) => {
            return Err(bad(format!(
                "{value} is outside the range of a scene integer ({} ..= {})",
                i64::MIN,
                i64::MAX
            )));
        }
        Err(_) => toml::Value::String(value.to_owned()),
    };
    Ok((path, parsed))
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

/// `saved` (a scene from a checkpoint) with its contact law named: one saved without it is
/// `linear` ([`SAVED_CONTACT_DEFAULT`]), whatever today's default.
fn with_saved_contact(saved: &str) -> String {
    match saved.parse::<toml::Table>() {
        Ok(table) if !table.contains_key("contact") => format!("{SAVED_CONTACT_DEFAULT}\n{saved}"),
        _ => saved.to_owned(),
    }
}

/// Whether `text` is an integer numeral (digits after an optional sign).
fn is_integer(text: &str) -> bool {
    let digits = text.strip_prefix(['+', '-']).unwrap_or(text);
    !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())
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
        let (mut config, given) = Self::parse_table(text.as_deref(), path, flags, overrides)?;
        config.rebase(path);
        config.make_paths_absolute()?;
        let source = config.scene.source();
        let scene_option = match source {
            Source::Input => "--input/--scene",
            Source::Mesh => "--mesh/--scene",
            Source::Generated(_) | Source::Equipment(_) => "--scene",
        };
        for (key, value) in &given {
            let (used, flag) = match key.as_str() {
                "spheres" => (
                    matches!(source, Source::Generated(_) | Source::Equipment(_)),
                    "-n",
                ),
                "seed" => (!matches!(source, Source::Input), "--seed"),
                "input" => (matches!(source, Source::Input), "--input"),
                "mesh" => (matches!(source, Source::Mesh), "--mesh"),
                "grain_radius" => (matches!(source, Source::Equipment(_)), ""),
                k if k.starts_with("hopper_") => {
                    (matches!(source, Source::Equipment(Equipment::Hopper)), "")
                }
                k if k.starts_with("drum_") => {
                    (matches!(source, Source::Equipment(Equipment::Drum)), "")
                }
                k => (
                    !k.starts_with("mesh_") || matches!(source, Source::Mesh),
                    "",
                ),
            };
            let option = match flag {
                "" => format!("--set {key}"),
                flag => format!("{flag}/--set {key}"),
            };
            if !used {
                return Err(Error::InvalidConfig {
                    what: format!("{key} = {value} ({option})"),
                    reason: format!(
                        "conflicts with scene {:?} ({scene_option}): that scene does not use \
                         {key}; give one or the other",
                        config.scene.name()
                    ),
                });
            }
        }
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
        let flows = !(self.inflow.is_empty() && self.outflow.is_empty() && self.box_walls)
            || self.scene == SceneKind::Hopper;
        if given.contains_key("flow_every") && !flows {
            return Err(idle(
                "flow_every",
                "sets the steps between flow events, and this scene has no [[inflow]] or \
                 [[outflow]] tables (nor box_walls = false, whose floor drains)",
            ));
        }
        if given.contains_key("rolling_model") && self.material()?.rolling_friction == 0.0 {
            return Err(idle(
                "rolling_model",
                "chooses the law of rolling resistance, and this scene's rolling_friction is 0",
            ));
        }
        let m = self.material()?;
        if given.contains_key("tangential_model")
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
        let flags = SceneFlags::default();
        let (mut config, _) = Self::parse_table(text, origin, &flags, overrides)?;
        config.rebase(origin);
        Ok(config)
    }

    /// The scene's input and mesh paths.
    fn paths_mut(&mut self) -> impl Iterator<Item = &mut PathBuf> {
        let walls = self.wall.iter_mut().map(|w| &mut w.mesh);
        let files = [&mut self.input, &mut self.mesh].into_iter().flatten();
        files.chain(walls)
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

    /// The scene and the table of the fields the text, the flags and the overrides give.
    fn parse_table(
        text: Option<&str>,
        origin: Option<&Path>,
        flags: &SceneFlags,
        overrides: &Overrides,
    ) -> Result<(Self, toml::Table)> {
        let where_ = || origin.map_or_else(|| "command line".into(), Path::to_owned);
        let mut table = match text {
            None => toml::Table::new(),
            Some(text) => text.parse::<toml::Table>().map_err(|e| Error::Parse {
                path: where_(),
                line: None,
                msg: e.to_string().trim_end().to_owned(),
            })?,
        };
        // Fields left `None` are left out of the table.
        let flagged = toml::Table::try_from(flags).map_err(|e| Error::InvalidConfig {
            what: "scene options".into(),
            reason: format!("cannot be written in TOML: {e}"),
        })?;
        let overridden = !flagged.is_empty() || !overrides.is_empty();
        table.extend(flagged);
        overrides.apply(&mut table)?;
        // Deserialize from text, so that errors quote the offending line: the file's own text
        // when nothing was overridden, else the merged table's.
        let merged;
        let source = match text {
            Some(t) if !overridden => t,
            _ => {
                merged = toml::to_string(&table).expect("a TOML table serializes");
                merged.as_str()
            }
        };
        let config: SceneConfig = toml::from_str(source).map_err(|e| Error::Parse {
            path: where_(),
            line: None,
            msg: e.to_string().trim_end().to_owned(),
        })?;
        Ok((config, table))
    }

    /// The scene saved in the checkpoint `origin` (`saved`, its TOML) with `flags`, then
    /// `overrides`, applied. A resumed run keeps its identity: only the fields of [`RESUMABLE`]
    /// may change; any other flag or override that changes a value is refused, naming the
    /// field. Paths stay as saved.
    pub fn resume(
        saved: &str,
        origin: &Path,
        flags: &SceneFlags,
        overrides: &Overrides,
    ) -> Result<Self> {
        let none = SceneFlags::default();
        let saved = &with_saved_contact(saved);
        let (before, _) =
            Self::parse_table(Some(saved), Some(origin), &none, &Overrides::default())?;
        let (after, _) = Self::parse_table(Some(saved), Some(origin), flags, overrides)?;
        let fields = |c: &SceneConfig| toml::Table::try_from(c).expect("a scene serializes");
        let (was, now) = (fields(&before), fields(&after));
        let mut keys = was
            .keys()
            .chain(now.keys().filter(|k| !was.contains_key(*k)));
        let changed = keys.find(|k| !RESUMABLE.contains(&k.as_str()) && was.get(*k) != now.get(*k));
        if let Some(key) = changed {
            let saved = was.get(key).map_or("unset".into(), ToString::to_string);
            return Err(Error::InvalidConfig {
                what: format!("--set {key}"),
                reason: format!(
                    "a resumed run keeps the scene of its checkpoint ({key} = {saved}); only {} \
                     may change on --resume. To change {key}, start a new run from the last \
                     frame (--input OUT/frame_<step>.csv)",
                    RESUMABLE.join(", ")
                ),
            });
        }
        Ok(after)
    }

    /// This scene as TOML (saved in checkpoints).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a scene always serializes")
    }

    /// Builds the particles at t = 0 and the step parameters (a built-in scene's equipment
    /// built once, for its spheres, box, flows and walls alike).
    pub fn build(&self) -> Result<Start> {
        let equipment = self.equipment()?;
        let spheres = match self.scene.source() {
            Source::Generated(scene) => scenes::generate(&SceneSpec {
                scene,
                n: self.spheres,
                seed: self.seed,
                layout: Layout::Lattice,
            })?,
            Source::Mesh => self.mesh_spheres()?,
            Source::Equipment(_) => equipment.as_ref().expect("built").spheres.clone(),
            Source::Input => {
                let input = self.input.as_ref().ok_or_else(|| Error::InvalidConfig {
                    what: "scene \"input\"".into(),
                    reason: "needs input = \"FILE\" (--input)".into(),
                })?;
                let particles = crate::io::read_particles(input)?;
                // The file's materials index the scene's: an error names the file.
                let count = self.materials()?.list.len();
                particles.check_materials(count).map_err(|e| Error::Parse {
                    path: input.clone(),
                    line: None,
                    msg: e.to_string(),
                })?;
                return Self::inside_the_box(self.start_with(particles, None)?, 0.0);
            }
        };
        let particles = Particles::at_rest(&spheres)?;
        Self::inside_the_box(self.start_with(particles, equipment.as_ref())?, 0.0)
    }

    /// The start of a run resumed from a checkpoint of this scene: `particles` pass the checks
    /// of a fresh run's input (finite values, valid radii, the size limits) and the parameters
    /// those of a fresh run. A centre may lie outside the box, as soft walls let spheres sink
    /// into them (with a soft stiffness, by more than a radius), but by no more than the box's
    /// own extent along that axis.
    pub fn resume_from(&self, particles: Particles) -> Result<Start> {
        particles.validate()?;
        SphereSet::new(particles.positions.clone(), particles.radii.clone())?;
        Self::inside_the_box(self.start_from(particles)?, 1.0)
    }

    /// `start`, if every centre lies in its box widened by `slack` times its extent on every
    /// side (0 at t = 0; a resumed scene without box walls is not checked).
    fn inside_the_box(start: Start, slack: f32) -> Result<Start> {
        if slack > 0.0 && !start.walls.box_walls {
            // Without the box walls spheres leave the box: it only bounds the grid.
            return Ok(start);
        }
        let (lo, hi) = (start.params.box_lo, start.params.box_hi);
        let grown: [(f32, f32); 3] = std::array::from_fn(|a| {
            let margin = slack * (hi[a] - lo[a]);
            (lo[a] - margin, hi[a] + margin)
        });
        let outside = start
            .particles
            .positions
            .iter()
            .position(|c| (0..3).any(|a| !(grown[a].0..=grown[a].1).contains(&c[a])));
        if let Some(index) = outside {
            let far = match slack > 0.0 {
                true => ", farther out than the box's own size",
                false => "",
            };
            return Err(Error::InvalidSphere {
                index,
                reason: format!(
                    "centre {:?} is outside the box {lo:?} .. {hi:?}{far}",
                    start.particles.positions[index]
                ),
            });
        }
        Ok(start)
    }

    /// Copies per row and layers of the `mesh` scene, and the side of its cell per copy.
    fn mesh_layout(&self) -> Result<(u32, u32, f64)> {
        let copies = self.mesh_copies;
        if copies == 0 || copies as usize > crate::MAX_SPHERES {
            return Err(Error::InvalidConfig {
                what: "scene key mesh_copies".into(),
                reason: format!(
                    "must be from 1 to {} (each copy holds a sphere at least), got {copies}",
                    crate::MAX_SPHERES
                ),
            });
        }
        let per_row = (copies as f64).sqrt().ceil() as u32;
        // Spheres reach past the mesh by up to their radius: keep 4.4 radii between copies.
        let cell = self.mesh_size * 1.05 + 4.4 * self.mesh_radius as f64;
        let layers = (copies as u64).div_ceil(per_row as u64 * per_row as u64) as u32;
        Ok((per_row, layers, cell))
    }

    /// The `mesh` scene's box side: the unit cube, or larger to hold every copy.
    fn mesh_box_side(&self) -> Result<f64> {
        let (per_row, layers, cell) = self.mesh_layout()?;
        Ok((per_row as f64 * cell)
            .max(layers as f64 * cell + 2.2 * self.mesh_radius as f64)
            .max(1.0))
    }

    /// Fills the mesh (or the torus) and places the copies on the floor of the box, side by side.
    fn mesh_spheres(&self) -> Result<SphereSet> {
        let r = self.mesh_radius;
        if !(r.is_finite() && r > 0.0 && self.mesh_size.is_finite() && self.mesh_size > 0.0) {
            return Err(Error::InvalidConfig {
                what: "scene".into(),
                reason: format!(
                    "mesh_radius and mesh_size must be positive, got {r} and {}",
                    self.mesh_size
                ),
            });
        }
        let (per_row, _, cell) = self.mesh_layout()?;
        let mesh = match &self.mesh {
            Some(path) => crate::mesh::load(path)?,
            None => crate::mesh::torus(1.0, 0.4, 64, 32),
        };
        let size = self.mesh_size;
        let shape = mesh.fitted([0.0; 3], [size; 3]);
        let radii = if self.mesh_mixed {
            vec![(r, 1.0), (r / 2.0, 1.0)]
        } else {
            vec![(r, 1.0)]
        };
        let spec = crate::mesh::FillSpec {
            spacing: 2.2 * r as f64,
            radii,
            jitter: true,
            seed: self.seed,
        };
        let (one_c, one_r) = crate::mesh::fill(&shape, &spec)?;
        let side = self.mesh_box_side()?;
        let edge = (side - per_row as f64 * cell) / 2.0 + (cell - size) / 2.0;
        let copies = self.mesh_copies as usize;
        let total = one_c.len().saturating_mul(copies);
        if total > crate::MAX_SPHERES {
            return Err(Error::TooLarge {
                what: format!("spheres in {copies} filled copies of the mesh (mesh_copies)"),
                got: total as u64,
                limit: crate::MAX_SPHERES as u64,
            });
        }
        let mut centers = Vec::with_capacity(total);
        let mut all_radii = Vec::with_capacity(total);
        let per_row = per_row as usize;
        for k in 0..copies {
            let at = [
                k % per_row,
                (k / per_row) % per_row,
                k / (per_row * per_row),
            ];
            let offset: [f64; 3] = std::array::from_fn(|a| {
                let base = if a == 2 { 2.2 * r as f64 } else { edge };
                base + at[a] as f64 * cell
            });
            centers.extend(
                one_c
                    .iter()
                    .map(|c| std::array::from_fn(|a| (c[a] as f64 + offset[a]) as f32)),
            );
            all_radii.extend_from_slice(&one_r);
        }
        SphereSet::new(centers, all_radii)
    }

    /// The step parameters for `particles` (at t = 0, or from a checkpoint of this scene).
    pub fn start_from(&self, particles: Particles) -> Result<Start> {
        self.start_with(particles, self.equipment()?.as_ref())
    }

    /// [`Self::start_from`] with the scene's equipment built already (`None`: no built-in
    /// scene).
    fn start_with(&self, particles: Particles, equipment: Option<&Built>) -> Result<Start> {
        let (r_min, r_max) = particles.radius_range();
        let source = self.scene.source();
        let (default_lo, default_hi) = match source {
            Source::Generated(scene) => {
                let side = scene.box_side(particles.len(), Layout::Lattice);
                ([0.0; 3], [side; 3])
            }
            Source::Mesh => ([0.0; 3], [self.mesh_box_side()?; 3]),
            Source::Equipment(_) => {
                let built = equipment.expect("a built-in scene's equipment");
                (built.box_lo, built.box_hi)
            }
            // A file: its bounds with a margin of two largest diameters, as the step starts
            // them (spheres sharing a centre spread about it).
            Source::Input => {
                let mut centres = particles.positions.clone();
                if particles.coincident_pairs()? > 0 {
                    let mut spread = particles.clone();
                    spread.separate_coincident()?;
                    centres = spread.positions;
                }
                match SphereSet::new(centres, particles.radii.clone())?.bounds() {
                    Some((lo, hi)) => {
                        let m = 4.0 * r_max as f64;
                        (lo.map(|x| x as f64 - m), hi.map(|x| x as f64 + m))
                    }
                    None => ([0.0; 3], [1.0; 3]),
                }
            }
        };
        let materials = self.materials()?;
        let material = *materials.first();
        // The materials' values, before the time step is derived from them.
        materials.check()?;
        particles.check_materials(materials.list.len())?;
        let r_max = particles.radius_range().1;
        check_heaviest(materials.heaviest_density(), r_max)?;
        let floor = box_lo_z(self.box_lo, default_lo);
        let flow = self.flow(&materials, floor, equipment)?;
        // The smallest sphere, inserted ones included, sets the time step.
        let r_min = match (particles.is_empty(), flow.smallest_radius()) {
            (true, None) => 1.0,
            (true, Some(r)) => r,
            (false, None) => r_min,
            (false, Some(r)) => r_min.min(r),
        };
        let dt = match (self.dt, material.contact) {
            (Some(dt), _) => dt,
            // The Rayleigh rule where the parameters make sense (else `StepParams::new` says
            // what is wrong with them).
            // The fastest material's Rayleigh time (materials.check() passed: the parameters
            // make sense).
            (None, ContactLaw::HertzMindlin { .. }) => {
                let t_r = materials
                    .list
                    .iter()
                    .map(|m| match m.contact {
                        ContactLaw::HertzMindlin {
                            young_modulus,
                            poisson_ratio,
                        } => rayleigh_time(r_min as f64, m.density, young_modulus, poisson_ratio),
                        _ => f64::INFINITY,
                    })
                    .fold(f64::INFINITY, f64::min);
                RAYLEIGH_FRACTION * t_r
            }
            (None, _) => match source {
                Source::Generated(
                    Scene::Poly1_2 | Scene::Poly12 | Scene::Poly120 | Scene::Polylog,
                ) => 5e-5,
                Source::Mesh => 2.5e-5,
                _ => 1e-4,
            },
        };
        let spin = self
            .gravity_spin
            .unwrap_or(if self.scene == SceneKind::Rotating {
                0.25 * std::f64::consts::PI
            } else {
                0.0
            });
        let (lo, hi) = (
            self.box_lo.unwrap_or(default_lo),
            self.box_hi.unwrap_or(default_hi),
        );
        let box_material = match &self.box_material {
            Some(name) => Some(material_index(&self.material, name, "box_material")?),
            None => None,
        };
        let params = StepParams::with_materials(
            &materials,
            box_material,
            dt,
            lo,
            hi,
            self.gravity,
            spin,
            r_min,
        )?;
        flow.check(params.dt as f64, params.box_lo, params.box_hi)?;
        let walls = self.walls_with(equipment)?;
        walls.check_speed(params.dt as f64, r_min)?;
        Ok(Start {
            particles,
            params,
            mode: self.mode,
            walls,
            flow,
        })
    }

    /// The built-in scene this scene names, as it sizes it (`None`: not a built-in scene).
    fn equipment(&self) -> Result<Option<Built>> {
        let Source::Equipment(kind) = self.scene.source() else {
            return Ok(None);
        };
        EquipmentSpec {
            kind,
            n: self.spheres,
            seed: self.seed,
            grain_radius: self.grain_radius.unwrap_or(0.004),
            orifice: self.hopper_orifice.unwrap_or(0.04),
            angle: self.hopper_angle.unwrap_or(0.0),
            open: self.hopper_open.unwrap_or(0.2),
            omega: self.drum_omega.unwrap_or(3.0),
            drum_sides: self.drum_sides.unwrap_or(64),
            drum_rings: self.drum_rings.unwrap_or(1),
        }
        .build()
        .map(Some)
    }

    /// The inflows and outflows of the scene (with those of its `equipment`); without the box
    /// walls, spheres below the box's floor (at `floor`) leave too.
    fn flow(
        &self,
        materials: &Materials,
        floor: f64,
        equipment: Option<&Built>,
    ) -> Result<FlowSet> {
        let inflows = self
            .inflow
            .iter()
            .enumerate()
            .map(|(k, f)| {
                let material = match &f.material {
                    Some(name) => material_index(&self.material, name, "inflow.material")?,
                    None => 0,
                };
                f.build(k, materials.list[material].density, material as u8)
            })
            .collect::<Result<Vec<_>>>()?;
        let mut outflow = self.outflow.clone();
        if let Some(built) = equipment {
            outflow.extend(built.outflows.iter().cloned());
        }
        let outflows = outflow
            .iter()
            .enumerate()
            .map(|(k, f)| f.build(k))
            .collect::<Result<Vec<_>>>()?;
        if self.flow_every == Some(0) {
            return Err(Error::InvalidConfig {
                what: "scene".into(),
                reason: "flow_every must be at least 1 step, got 0".into(),
            });
        }
        Ok(FlowSet {
            inflows,
            outflows,
            floor: (!self.box_walls).then_some(floor as f32),
            every: self.flow_every,
            counted: Default::default(),
        })
    }

    /// The walls of the scene: the box (or not), a built-in scene's, and each `[[wall]]` read
    /// and posed, with its material.
    pub fn walls(&self) -> Result<WallSet> {
        self.walls_with(self.equipment()?.as_ref())
    }

    /// [`Self::walls`] with the scene's equipment built already (`None`: no built-in scene).
    fn walls_with(&self, equipment: Option<&Built>) -> Result<WallSet> {
        let mut meshes = Vec::new();
        let material_of = |w: &WallConfig| match &w.material {
            Some(name) => {
                material_index(&self.material, name, "wall.material").map(|m| Some(m as u32))
            }
            None => Ok(None),
        };
        if let Some(built) = equipment {
            for (config, mesh) in &built.walls {
                let material = material_of(config)?;
                meshes.push(config.build_from(meshes.len(), mesh, material)?);
            }
        }
        for w in &self.wall {
            meshes.push(w.build(meshes.len(), material_of(w)?)?);
        }
        WallSet::new(self.box_walls, meshes)
    }

    /// The materials of the scene: its `[[material]]` tables, or the one its top-level keys
    /// describe.
    pub fn materials(&self) -> Result<Materials> {
        material_spec::materials(&self.material()?, &self.material, &self.material_pair)
    }

    /// The material the scene describes, its defaults filled in; refuses keys that do not
    /// apply to its contact law (each would be silently ignored).
    pub fn material(&self) -> Result<Material> {
        let hertz = self.contact == ContactKind::HertzMindlin;
        let refuse = |key: &str, law: &str| {
            Err(Error::InvalidConfig {
                what: format!("scene key {key}"),
                reason: format!(
                    "applies to contact = \"{law}\" only, and this scene's contact is \"{}\"",
                    if hertz { "hertz-mindlin" } else { "linear" }
                ),
            })
        };
        let contact = if hertz {
            if self.stiffness.is_some() {
                return refuse("stiffness", "linear");
            }
            if self.contact_time.is_some() {
                return refuse("contact_time", "linear");
            }
            ContactLaw::HertzMindlin {
                young_modulus: self.young_modulus.unwrap_or(DEFAULT_YOUNG_MODULUS),
                poisson_ratio: self.poisson_ratio.unwrap_or(DEFAULT_POISSON_RATIO),
            }
        } else {
            if self.young_modulus.is_some() {
                return refuse("young_modulus", "hertz-mindlin");
            }
            if self.poisson_ratio.is_some() {
                return refuse("poisson_ratio", "hertz-mindlin");
            }
            match self.stiffness {
                Some(Stiffness::PerPair) => ContactLaw::LinearPerPair {
                    contact_time: self.contact_time,
                },
                _ if self.contact_time.is_some() => {
                    return Err(Error::InvalidConfig {
                        what: "scene key contact_time".into(),
                        reason: "applies to stiffness = \"per-pair\" only".into(),
                    });
                }
                _ => ContactLaw::Linear,
            }
        };
        let stiffness = match self.stiffness {
            Some(Stiffness::Fixed(k)) => Some(k),
            _ => None,
        };
        let (friction, rolling) = match hertz {
            true => (DEFAULT_FRICTION, DEFAULT_ROLLING_FRICTION),
            false => (0.0, 0.0),
        };
        Ok(Material {
            density: self.density,
            restitution: self.restitution,
            stiffness,
            contact,
            friction: self.friction.unwrap_or(friction),
            wall_friction: self.wall_friction,
            rolling_friction: self.rolling_friction.unwrap_or(rolling),
            rolling_model: self.rolling_model.unwrap_or_default(),
            tangential_model: self.tangential_model.unwrap_or_default(),
        })
    }

    /// This scene with every derived value (time step, box, gravity spin, stiffness, the
    /// material's defaults) written out as `start` resolved it, so a checkpoint resumes with
    /// exactly the same parameters.
    pub fn resolved(&self, start: &Start) -> SceneConfig {
        let p = &start.params;
        // `start` was built from this scene, so its material is valid.
        let m = self
            .material()
            .expect("the scene of a start has a valid material");
        let (young_modulus, poisson_ratio) = match m.contact {
            ContactLaw::HertzMindlin {
                young_modulus,
                poisson_ratio,
            } => (Some(young_modulus), Some(poisson_ratio)),
            _ => (None, None),
        };
        // Friction written out where it acts (a frictionless linear scene stays as it was).
        let acting = |given: Option<f64>, value: f64| match p.friction.turns() {
            true => Some(value),
            false => given,
        };
        // The step's `f32` values by their shortest decimals (box_hi = [0.8, ...], not
        // 0.800000011920929), each of which reads back as the same `f32`.
        SceneConfig {
            dt: Some(widened(p.dt)),
            box_lo: Some(p.box_lo.map(widened)),
            box_hi: Some(p.box_hi.map(widened)),
            gravity_spin: Some(widened(p.gravity_spin)),
            stiffness: match m.contact {
                ContactLaw::Linear => Some(Stiffness::Fixed(widened(p.stiffness))),
                _ => self.stiffness,
            },
            young_modulus,
            poisson_ratio,
            friction: acting(self.friction, m.friction),
            wall_friction: acting(self.wall_friction, m.wall_friction.unwrap_or(m.friction)),
            rolling_friction: acting(self.rolling_friction, m.rolling_friction),
            rolling_model: match p.friction.turns() {
                true => Some(m.rolling_model),
                false => self.rolling_model,
            },
            ..self.clone()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `assignments` as overrides, which must parse.
    fn given(assignments: &[impl AsRef<str>]) -> Overrides {
        Overrides::parse(assignments).expect("the overrides parse")
    }

    /// Significant digits of the number `token` (leading zeros, sign and exponent aside).
    fn significant_digits(token: &str) -> usize {
        let mantissa = token.split(['e', 'E']).next().unwrap_or("");
        let digits: String = mantissa.chars().filter(char::is_ascii_digit).collect();
        digits.trim_start_matches('0').trim_end_matches('0').len()
    }

    #[test]
    fn a_saved_scene_writes_f32_values_by_their_shortest_decimals_and_rebuilds_the_same_step() {
        let flags = SceneFlags::default();
        for sets in [
            &["spheres=300"][..],
            &["scene=rotating", "contact=linear", "spheres=50", "dt=2e-5"],
            &["scene=poly12", "contact=linear", "spheres=100"],
            &[
                "scene=freefall",
                "spheres=50",
                "box_lo=[-0.1, -0.3, -0.7]",
                "box_hi=[1.3, 1.7, 1.9]",
            ],
        ] {
            let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
            let config = SceneConfig::load_new(None, &flags, &given(&sets)).unwrap();
            let start = config.build().unwrap();
            let saved = config.resolved(&start).to_toml();
            // No f32 widened to 16 or 17 digits (0.800000011920929): an f32 needs at most 9.
            let numbers = saved.split(|c: char| !(c.is_ascii_alphanumeric() || "+-.".contains(c)));
            for token in numbers.filter(|t| t.starts_with(|c: char| c.is_ascii_digit() || c == '-'))
            {
                assert!(significant_digits(token) <= 9, "{token} in\n{saved}");
            }
            // Read back, the scene builds the same step and saves the same text.
            let again = SceneConfig::parse(Some(&saved), None, &Overrides::default()).unwrap();
            let rebuilt = again.build().unwrap();
            assert_eq!(rebuilt.params, start.params, "{saved}");
            assert_eq!(again.resolved(&rebuilt).to_toml(), saved);
        }
    }

    #[test]
    fn the_tangential_model_is_mindlin_unless_asked_and_mindlin_deresiewicz_is_for_hertz() {
        let flags = SceneFlags::default();
        let new = |sets: &[&str]| {
            let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
            SceneConfig::load_new(None, &flags, &given(&sets))
        };
        let default = new(&["spheres=10"]).unwrap();
        assert_eq!(default.tangential_model, None);
        let m = default.material().unwrap();
        assert_eq!(m.tangential_model, TangentialModel::Mindlin);
        let md = new(&["spheres=10", "tangential_model=mindlin-deresiewicz"]).unwrap();
        let m = md.material().unwrap();
        assert_eq!(m.tangential_model, TangentialModel::MindlinDeresiewicz);
        let start = md.build().unwrap();
        assert!(start.params.friction.keeps_load());
        // Saved with the scene, so a checkpoint resumes under it.
        let saved = toml::to_string(&md.resolved(&start)).unwrap();
        assert!(
            saved.contains("tangential_model = \"mindlin-deresiewicz\""),
            "{saved}"
        );
        // An unknown model names the two.
        let e = new(&["tangential_model=mindlin-rescale"])
            .unwrap_err()
            .to_string();
        assert!(e.contains("mindlin-deresiewicz"), "{e}");
        // The linear laws have no contact radius to follow.
        let sets = [
            "contact=linear",
            "friction=0.3",
            "tangential_model=mindlin-deresiewicz",
        ];
        let e = new(&sets)
            .and_then(|c| c.build())
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("tangential_model") && e.contains("hertz-mindlin"),
            "{e}"
        );
        // Without friction it would act on nothing.
        let sets = ["friction=0", "tangential_model=mindlin-deresiewicz"];
        let e = new(&sets).unwrap_err().to_string();
        assert!(
            e.contains("tangential_model") && e.contains("friction"),
            "{e}"
        );
    }

    #[test]
    fn overrides_take_toml_values_and_bare_words() {
        let c = SceneConfig::load(
            None,
            &given(&[
                "scene=poly12",
                "spheres = 2000",
                "gravity=[0, -9.81, 0]",
                "stiffness=3.5",
            ]),
        )
        .unwrap();
        assert_eq!(c.scene.name(), "poly12");
        assert_eq!(c.spheres, 2000);
        assert_eq!(c.gravity, [0.0, -9.81, 0.0]);
        assert_eq!(c.stiffness, Some(Stiffness::Fixed(3.5)));
    }

    #[test]
    fn unknown_fields_and_bad_values_are_errors() {
        let e = SceneConfig::load(None, &given(&["sphers=10"])).unwrap_err();
        assert!(e.to_string().contains("sphers"), "{e}");
        let e = SceneConfig::load(None, &given(&["spheres=-3"])).unwrap_err();
        assert!(
            e.to_string().contains("spheres") || e.to_string().contains("-3"),
            "{e}"
        );
        let e = Overrides::parse(&["steps=18446744073709551615"]).unwrap_err();
        assert!(e.to_string().contains("outside the range"), "{e}");
        let e = Overrides::parse(&["no equals sign"]).unwrap_err();
        assert!(e.to_string().contains("key=value"), "{e}");
        let e = SceneConfig::load(None, &given(&["scene=teapot"])).unwrap_err();
        assert!(e.to_string().contains("teapot"), "{e}");
    }

    #[test]
    fn unknown_scenes_and_modes_are_errors_listing_the_names() {
        let e = SceneConfig::parse(Some("scene = \"teapot\""), None, &Overrides::default())
            .unwrap_err();
        let e = e.to_string();
        assert!(
            e.contains(
                "unknown scene \"teapot\": use freefall, slab, poly1.2, poly12, poly120, \
                 polylog, pour, rotating, mesh, input, hopper or drum"
            ),
            "{e}"
        );
        let e = SceneConfig::load(None, &given(&["mode=fast"])).unwrap_err();
        let e = e.to_string();
        assert!(
            e.contains("unknown value \"fast\": use mochi or nns"),
            "{e}"
        );
    }

    #[test]
    fn each_scene_and_mode_has_one_name_in_toml_and_on_the_command_line() {
        use crate::names::Named;
        for scene in SceneKind::ALL {
            let c = SceneConfig::load(None, &given(&[format!("scene={}", scene.name())])).unwrap();
            assert_eq!(c.scene, scene);
            assert!(c.to_toml().contains(&format!("scene = \"{scene}\"")));
        }
        let generated = SceneKind::ALL.iter().filter_map(|s| match s {
            SceneKind::Generated(scene) => Some(*scene),
            _ => None,
        });
        assert!(generated.eq(Scene::ALL.iter().copied()));
        for &mode in ProxyMode::ALL {
            let name = mode.name();
            assert_eq!(serde_json::to_string(&mode).unwrap(), format!("\"{name}\""));
            let c = SceneConfig::load(None, &given(&[format!("mode={name}")])).unwrap();
            assert_eq!(c.mode, mode);
            assert!(c.to_toml().contains(&format!("mode = \"{name}\"")));
        }
    }

    #[test]
    fn flags_apply_over_the_file_and_set_over_the_flags() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("s.toml");
        std::fs::write(&file, "scene = \"poly12\"\nspheres = 300\nsteps = 7\n").unwrap();
        let flags = SceneFlags {
            scene: Some(SceneKind::Rotating),
            spheres: Some(200),
            mode: Some(ProxyMode::Nns),
            ..SceneFlags::default()
        };
        let c = SceneConfig::load_new(Some(&file), &flags, &given(&["spheres=100"])).unwrap();
        assert_eq!(
            (c.scene, c.spheres, c.steps, c.mode),
            (SceneKind::Rotating, 100, 7, ProxyMode::Nns)
        );
        // A flag the scene does not use is refused, naming the flag.
        let flags = SceneFlags {
            spheres: Some(200),
            mesh: Some("m.obj".into()),
            scene: Some(SceneKind::Mesh),
            ..SceneFlags::default()
        };
        let e = SceneConfig::load_new(None, &flags, &Overrides::default()).unwrap_err();
        assert!(e.to_string().contains("-n/--set spheres"), "{e}");
    }

    #[cfg(unix)]
    #[test]
    fn a_path_toml_cannot_hold_is_a_clear_error() {
        use std::os::unix::ffi::OsStrExt;
        let flags = SceneFlags {
            scene: Some(SceneKind::Input),
            input: Some(std::ffi::OsStr::from_bytes(b"bad\xff.csv").into()),
            ..SceneFlags::default()
        };
        let e = SceneConfig::load_new(None, &flags, &Overrides::default()).unwrap_err();
        assert!(
            e.to_string().contains("cannot be written in TOML: path"),
            "{e}"
        );
    }

    #[test]
    fn a_checkpoint_scene_of_this_format_reads_as_saved() {
        let saved = "scene = \"rotating\"\nspheres = 64\nseed = 3\nsteps = 10\ndt = 0.0001\n\
                     box_lo = [0.0, 0.0, 0.0]\nbox_hi = [1.0, 1.0, 1.0]\n\
                     gravity = [0.0, 0.0, -9.81]\ngravity_spin = 0.7853981852531433\n\
                     density = 500.0\nrestitution = 0.5\nstiffness = 2.0\nmode = \"nns\"\n\
                     frame_every = 5\ncsv = false\nmesh_radius = 0.005\n\
                     mesh_mixed = false\nmesh_size = 0.818\nmesh_copies = 1\n";
        let c = SceneConfig::resume(
            saved,
            Path::new("c.bin"),
            &SceneFlags::default(),
            &Overrides::default(),
        )
        .unwrap();
        assert_eq!((c.scene, c.mode), (SceneKind::Rotating, ProxyMode::Nns));
        // Saved before hertz-mindlin became the default, without a contact law: linear, and
        // written out from now on.
        assert_eq!(c.contact, ContactKind::Linear);
        let named = saved.replace(
            "restitution = 0.5\n",
            "restitution = 0.5\ncontact = \"linear\"\n",
        );
        assert_eq!(c.to_toml(), named);
        let again = SceneConfig::resume(
            &named,
            Path::new("c.bin"),
            &SceneFlags::default(),
            &Overrides::default(),
        )
        .unwrap();
        assert_eq!(again, c);
        // Names were always read in any case.
        let c = SceneConfig::parse(
            Some("scene = \"Poly1.2\"\nmode = \"NNS\""),
            None,
            &Overrides::default(),
        )
        .unwrap();
        assert_eq!(
            (c.scene, c.mode),
            (SceneKind::Generated(Scene::Poly1_2), ProxyMode::Nns)
        );
    }

    #[test]
    fn a_scene_round_trips_through_toml() {
        let c = SceneConfig {
            dt: Some(2e-5),
            stiffness: Some(Stiffness::Fixed(10.0)),
            ..SceneConfig::default()
        };
        let back: SceneConfig = toml::from_str(&c.to_toml()).unwrap();
        assert_eq!(back, c);
    }

    #[test]
    fn the_mesh_scene_fills_copies_side_by_side_without_overlaps() {
        let c = SceneConfig::load(
            None,
            &given(&[
                "scene=mesh",
                "contact=linear",
                "mesh_radius=0.02",
                "mesh_size=0.5",
                "mesh_copies=3",
                "mesh_mixed=true",
            ]),
        )
        .unwrap();
        let s = c.build().unwrap();
        let n = s.particles.len();
        assert!(n > 300 && n.is_multiple_of(3), "{n}");
        let spheres =
            SphereSet::new(s.particles.positions.clone(), s.particles.radii.clone()).unwrap();
        assert!(crate::oracle::brute_force_pairs(&spheres).is_empty());
        assert!(s.particles.radii.contains(&0.01));
        assert_eq!(s.params.dt, 2.5e-5);
        let bad = SceneConfig::load(None, &given(&["scene=mesh", "mesh=\"nope.obj\""])).unwrap();
        assert!(bad.build().unwrap_err().to_string().contains("nope.obj"));
    }

    #[test]
    fn new_scenes_are_hertz_mindlin_with_the_documented_material() {
        let c = SceneConfig::load(None, &Overrides::default()).unwrap();
        assert_eq!(c.scene, SceneKind::Generated(Scene::Pour));
        let m = c.material().unwrap();
        assert_eq!(
            m.contact,
            ContactLaw::HertzMindlin {
                young_modulus: 1e7,
                poisson_ratio: 0.3
            }
        );
        assert_eq!((m.friction, m.wall_friction), (0.5, None));
        assert_eq!(
            (m.rolling_friction, m.rolling_model),
            (0.1, RollingModel::Epsd)
        );
        // A scene file without `contact` is Hertz–Mindlin too, and says so when saved.
        let c = SceneConfig::parse(Some("scene = \"slab\""), None, &Overrides::default()).unwrap();
        assert!(
            c.to_toml().contains("contact = \"hertz-mindlin\""),
            "{}",
            c.to_toml()
        );
        let saved = SceneConfig::resume(
            &c.to_toml(),
            Path::new("c.bin"),
            &SceneFlags::default(),
            &Overrides::default(),
        )
        .unwrap();
        assert_eq!(saved.contact, ContactKind::HertzMindlin);
    }

    #[test]
    fn rotating_spins_gravity_a_quarter_pi_per_second() {
        let c = SceneConfig::load(None, &given(&["scene=rotating", "spheres=1000"])).unwrap();
        let s = c.build().unwrap();
        assert!((s.params.gravity_spin as f64 - 0.25 * std::f64::consts::PI).abs() < 1e-6);
    }

    #[test]
    fn wall_tables_read_their_meshes_and_name_the_file_of_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let obj = dir.path().join("floor.obj");
        std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        let scene = dir.path().join("scene.toml");
        let text = "scene = \"freefall\"\nspheres = 8\nbox_walls = false\n\n[[wall]]\n\
                    mesh = \"floor.obj\"\nscale = 2.0\nrotate = { axis = [1, 0, 0], degrees = 10 }\n\
                    omega = 1.5\naxis = [0, 1, 0]\n";
        let c = SceneConfig::parse(Some(text), Some(&scene), &Overrides::default()).unwrap();
        assert_eq!(c.wall[0].mesh, obj);
        let start = c.build().unwrap();
        assert!(!start.walls.box_walls);
        assert_eq!(start.walls.meshes.len(), 1);
        assert_eq!(start.walls.meshes[0].motion.omega, 1.5);
        // Saved and read back (a checkpoint's scene) the same.
        let back: SceneConfig = toml::from_str(&c.resolved(&start).to_toml()).unwrap();
        assert_eq!(back.wall, c.wall);
        assert!(!back.box_walls);
        // A file that is not there, a key no wall has, a bad scale: one error each, naming it.
        let missing = text.replace("floor.obj", "nowhere.obj");
        let e = SceneConfig::parse(Some(&missing), Some(&scene), &Overrides::default())
            .unwrap()
            .build()
            .unwrap_err()
            .to_string();
        assert!(e.contains("nowhere.obj"), "{e}");
        let e = SceneConfig::parse(
            Some(&format!("{text}colour = 1\n")),
            Some(&scene),
            &Overrides::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("colour"), "{e}");
        let e = SceneConfig::parse(
            Some(&text.replace("2.0", "-1.0")),
            Some(&scene),
            &Overrides::default(),
        )
        .unwrap()
        .build()
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("wall 0") && e.contains("floor.obj") && e.contains("scale"),
            "{e}"
        );
    }

    #[test]
    fn dotted_overrides_set_one_field_of_a_table_and_name_what_is_missing() {
        let text = "scene = \"freefall\"\nspheres = 8\n\n[[inflow]]\ncenter = [0.5, 0.5, 0.9]\n\
                    radius = 0.1\nrate = 100\nsphere_radius = 0.002\n\n[[inflow]]\n\
                    lo = [0.1, 0.1, 0.8]\nhi = [0.2, 0.2, 0.9]\nrate = 50\nsphere_radius = 0.003\n";
        let c = SceneConfig::parse(Some(text), None, &given(&["inflow.1.rate=75"])).unwrap();
        assert_eq!(
            (c.inflow[0].rate, c.inflow[1].rate),
            (Some(100.0), Some(75.0))
        );
        assert_eq!(
            c.inflow[1].sphere_radius,
            Some(0.003),
            "the table's other fields stay"
        );
        // In order, whole fields and paths alike: the later wins.
        let c = SceneConfig::parse(Some(text), None, &given(&["inflow.0.rate=7", "spheres=9"]))
            .unwrap();
        assert_eq!((c.inflow[0].rate, c.spheres), (Some(7.0), 9));
        let refused = |sets: &[&str]| {
            SceneConfig::parse(Some(text), None, &given(sets))
                .unwrap_err()
                .to_string()
        };
        let e = refused(&["inflow.2.rate=1"]);
        assert!(
            e.contains("--set inflow.2.rate") && e.contains("2 inflow tables"),
            "{e}"
        );
        assert!(e.contains("inflow.0 to inflow.1"), "{e}");
        let e = refused(&["inflow.rate=1"]);
        assert!(e.contains("the part after it is an index"), "{e}");
        let e = refused(&["inflow.0=1"]);
        assert!(e.contains("name the field of it to set"), "{e}");
        let e = refused(&["outflow.0.lo=[0, 0, 0]"]);
        assert!(e.contains("there are no outflow tables here"), "{e}");
        let e = refused(&["spheres.x=1"]);
        assert!(e.contains("spheres is 8, not a table"), "{e}");
        // A path into no table of the scene is refused by the scene's fields, as a key is.
        let e = refused(&["inflow.0.colour=1"]);
        assert!(e.contains("colour"), "{e}");
        let e = Overrides::parse(&["0.rate=1"]).unwrap_err().to_string();
        assert!(e.contains("is not a field name"), "{e}");
        let e = Overrides::parse(&["inflow..rate=1"])
            .unwrap_err()
            .to_string();
        assert!(e.contains("is not a field name"), "{e}");
    }

    #[test]
    fn inflow_and_outflow_tables_make_the_flows_and_refuse_what_is_ambiguous() {
        let text = "scene = \"freefall\"\nspheres = 8\nbox_walls = false\n\n[[inflow]]\n\
                    center = [0.5, 0.5, 0.9]\nradius = 0.1\nmass_rate = 0.01\n\
                    sphere_radius = 0.002\n\n[[outflow]]\nlo = [0, 0, 0]\nhi = [1, 1, 0.1]\n";
        let c = SceneConfig::parse(Some(text), None, &Overrides::default()).unwrap();
        let start = c.build().unwrap();
        let flow = &start.flow;
        assert_eq!((flow.inflows.len(), flow.outflows.len()), (1, 1));
        // Without the box walls, the floor of the box drains too.
        assert_eq!(flow.floor, Some(start.params.box_lo[2]));
        // 0.01 kg/s of 2 mm spheres at 500 kg/m³.
        let each = 500.0 * 4.0 / 3.0 * std::f64::consts::PI * 0.002f64.powi(3);
        assert!((flow.inflows[0].rate * each / 0.01 - 1.0).abs() < 1e-9);
        // The inserted spheres' radius sets the time step when smaller than the scene's.
        assert!(start.params.dt_limit > 0.0);
        let both = text.replace("mass_rate = 0.01", "mass_rate = 0.01\nrate = 5");
        let e = SceneConfig::parse(Some(&both), None, &Overrides::default())
            .unwrap()
            .build()
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("inflow 0") && e.contains("one of the two"),
            "{e}"
        );
        let inverted = text.replace("hi = [1, 1, 0.1]", "hi = [1, 1, -0.1]");
        let e = SceneConfig::parse(Some(&inverted), None, &Overrides::default())
            .unwrap()
            .build()
            .unwrap_err()
            .to_string();
        assert!(e.contains("outflow 0"), "{e}");
    }

    #[test]
    fn the_hopper_and_the_drum_come_with_their_walls_inside_their_box() {
        for (scene, walls, outflows) in [("hopper", 2, 1), ("drum", 1, 0)] {
            let over = [format!("scene={scene}"), "spheres=300".into()];
            let c = SceneConfig::load(None, &given(&over)).unwrap();
            let start = c.build().unwrap();
            assert_eq!(start.particles.len(), 300);
            assert_eq!(start.walls.meshes.len(), walls, "{scene}");
            assert_eq!(start.flow.outflows.len(), outflows, "{scene}");
            let set = SphereSet::new(
                start.particles.positions.clone(),
                start.particles.radii.clone(),
            )
            .unwrap();
            let pairs = crate::oracle::brute_force_pairs(&set);
            assert!(pairs.is_empty(), "{scene}: the filled spheres overlap");
            // No sphere touches a wall at t = 0.
            let poses = start.walls.poses_at(0.0);
            for (wall, pose) in start.walls.meshes.iter().zip(&poses) {
                for (c, &r) in start.particles.positions.iter().zip(&start.particles.radii) {
                    let mut touching = crate::dem::walls::Touches::default();
                    crate::dem::walls::touches(
                        &wall.triangles,
                        pose,
                        glam::Vec3::from(*c),
                        r,
                        &mut touching,
                    );
                    assert!(
                        touching.found.is_empty(),
                        "{scene}: a sphere at {c:?} touches {}",
                        wall.name
                    );
                }
            }
        }
        // A drum of few sides holds its spheres inside its polygon: each lies on the axis's side
        // of every side's plane, by its radius at least.
        for sides in 3..=6 {
            let over = ["scene=drum".into(), format!("drum_sides={sides}")];
            let start = SceneConfig::load(None, &given(&over))
                .unwrap()
                .build()
                .unwrap();
            let tube = start.walls.triangles_at(0.0);
            for (c, &r) in start.particles.positions.iter().zip(&start.particles.radii) {
                let c = glam::Vec3::from(*c);
                let axis = glam::Vec3::new(0.0, c.y, 0.0);
                for [a, b, d] in tube.iter().map(|t| t.map(glam::Vec3::from)) {
                    let n = (b - a).cross(d - a).normalize();
                    let (sphere, centre) = (n.dot(c - a), n.dot(axis - a));
                    assert!(
                        sphere * centre.signum() >= r,
                        "{sides} sides: a sphere at {c} is outside the drum"
                    );
                }
            }
        }
        // However few the spheres or wide the orifice, a hopper has room for them.
        for over in [
            ["spheres=10", "hopper_orifice=0.04"],
            ["spheres=4000", "hopper_orifice=10"],
        ] {
            let over: Vec<String> = ["scene=hopper"]
                .iter()
                .chain(&over)
                .map(|s| s.to_string())
                .collect();
            let start = SceneConfig::load(None, &given(&over)).unwrap().build();
            assert!(start.is_ok(), "{over:?}: {:?}", start.err());
        }
        let e = SceneConfig::load_new(
            None,
            &SceneFlags::default(),
            &given(&["scene=drum", "hopper_angle=30"]),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("hopper_angle"), "{e}");
    }
}

/// The `[[material]]` and `[[material_pair]]` tables as a scene reads them (`material_spec`).
#[cfg(test)]
mod material_tables {
    use crate::dem::model::{ContactLaw, StepParams};
    use crate::dem::scene::{Overrides, SceneConfig};

    fn scene(text: &str) -> crate::error::Result<SceneConfig> {
        SceneConfig::parse(Some(text), None, &Overrides::default())
    }

    const TWO: &str = r#"
        friction = 0.4
        [[material]]
        name = "glass"
        young_modulus = 6.3e10
        poisson_ratio = 0.24
        density = 2500
        restitution = 0.9
        rolling_friction = 0.01
        [[material]]
        name = "steel"
        young_modulus = 2.0e11
        poisson_ratio = 0.3
        density = 7800
        friction = 0.3
        [[material_pair]]
        materials = ["steel", "glass"]
        restitution = 0.8
    "#;

    #[test]
    fn material_tables_take_the_top_level_keys_as_defaults_and_pairs_override_the_mixing() {
        let s = scene(TWO).unwrap();
        let m = s.materials().unwrap();
        assert_eq!(m.names, ["glass", "steel"]);
        let (glass, steel) = (&m.list[0], &m.list[1]);
        assert_eq!((glass.friction, steel.friction), (0.4, 0.3));
        assert_eq!((glass.density, steel.density), (2500.0, 7800.0));
        // The scene's default restitution (0.5) where a table gives none.
        assert_eq!((glass.restitution, steel.restitution), (0.9, 0.5));
        assert!(matches!(
            steel.contact,
            ContactLaw::HertzMindlin { young_modulus, .. } if young_modulus == 2.0e11
        ));
        // Restitution: the pair's own; friction and rolling friction: the smaller.
        // (Steel's rolling friction is the scene's default, 0.1.)
        assert_eq!(m.coefficients(0, Some(1)), (0.8, 0.3, 0.01));
        assert_eq!(m.coefficients(1, Some(0)), (0.8, 0.3, 0.01));
        assert_eq!(m.coefficients(0, Some(0)), (0.9, 0.4, 0.01));
        // A rigid wall: the sphere's own, friction the scene's wall friction (here μ).
        assert_eq!(m.coefficients(1, None), (0.5, 0.3, 0.1));
    }

    #[test]
    fn the_table_mixes_the_moduli_of_both_bodies_and_the_time_step_follows_the_stiffest() {
        let s = scene(TWO).unwrap();
        let m = s.materials().unwrap();
        let p =
            StepParams::with_materials(&m, Some(1), 1e-7, [0.0; 3], [1.0; 3], [0.0; 3], 0.0, 0.001)
                .unwrap();
        let t = &p.materials;
        assert_eq!((t.count, t.laws.len(), p.box_column), (2, 6, 1));
        let c = |e: f64, nu: f64| (1.0 - nu * nu) / e;
        let mixed = 1.0 / (c(6.3e10, 0.24) + c(2.0e11, 0.3));
        assert_eq!(t.law(0, 1).e_star, mixed as f32);
        assert_eq!(t.law(1, 0), t.law(0, 1));
        assert_eq!(t.law(0, 0).e_star, (1.0 / (2.0 * c(6.3e10, 0.24))) as f32);
        assert_eq!(
            t.law(0, 2).e_star,
            (1.0 / c(6.3e10, 0.24)) as f32,
            "rigid wall"
        );
        assert_eq!((t.law(0, 1).sliding, t.law(0, 0).rolling), (0.3, 0.01));
        assert_eq!(t.densities, [2500.0, 7800.0]);
        // The shorter Rayleigh time (glass's, by 1%) sets the limit.
        let rayleigh = |e: f64, nu: f64, rho: f64| {
            crate::dem::model::time_step::rayleigh_time(0.001, rho, e, nu)
        };
        let limit = 0.5 * rayleigh(6.3e10, 0.24, 2500.0);
        assert!(rayleigh(6.3e10, 0.24, 2500.0) < rayleigh(2.0e11, 0.3, 7800.0));
        assert!(
            (p.dt_limit as f64 / limit - 1.0).abs() < 1e-6,
            "{} {limit}",
            p.dt_limit
        );
        let e = StepParams::with_materials(
            &m,
            None,
            1.01 * limit,
            [0.0; 3],
            [1.0; 3],
            [0.0; 3],
            0.0,
            0.001,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("\"glass\""), "{e}");
    }

    #[test]
    fn bad_material_tables_are_one_clear_error() {
        let err = |text: &str| {
            let s = scene(text).and_then(|s| s.build().map(|_| s));
            s.unwrap_err().to_string()
        };
        let e = err("[[material]]\nname = \"a\"\n[[material]]\nname = \"a\"\n");
        assert!(e.contains("\"a\" is given twice"), "{e}");
        let e = err("box_material = \"b\"\n[[material]]\nname = \"a\"\n");
        assert!(
            e.contains("box_material") && e.contains("\"b\"") && e.contains("\"a\""),
            "{e}"
        );
        let e = err("box_material = \"b\"\n");
        assert!(e.contains("no [[material]] tables"), "{e}");
        let e = err("[[material]]\nname = \"a\"\nrestitution = 1.5\n[[material]]\nname = \"b\"\n");
        assert!(
            e.contains("material \"a\"") && e.contains("restitution"),
            "{e}"
        );
        let e = err("contact = \"linear\"\n[[material]]\nname = \"a\"\nyoung_modulus = 1e9\n");
        assert!(e.contains("hertz-mindlin"), "{e}");
        let e = err("[[material]]\nname = \"a\"\n[[material_pair]]\nmaterials = [\"a\", \"c\"]\n");
        assert!(e.contains("\"c\""), "{e}");
        let e = err("[[material]]\nname = \"a\"\ncolour = 3\n");
        assert!(e.contains("colour"), "{e}");
        let many: String = (0..257)
            .map(|k| format!("[[material]]\nname = \"m{k}\"\n"))
            .collect();
        assert!(err(&many).contains("at most 256"));
    }
}
