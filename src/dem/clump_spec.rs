//! The `[[clump]]` tables of a scene file: the shapes its grains take (docs/method.md,
//! "Clumps"). Where a scene has any, each sphere its source generates becomes a clump of one of
//! them, drawn by `fraction`, scaled so that its bounding sphere is the generated sphere (clumps
//! overlap no more than their spheres did), turned at random (seeded by the source's seed) and
//! moving as the sphere did; the clump's density is its sphere's material's.
//!
//! ```toml
//! [source]
//! scene = "pour"
//! spheres = 2000            # 2000 clumps
//!
//! [[clump]]
//! shape = "tetrahedron"     # dimer, trimer, tetrahedron, rod
//! fraction = 0.7            # of the clumps (default 1; the fractions are weights)
//!
//! [[clump]]
//! name = "bean"             # a shape of its own: spheres [x, y, z, r] in its frame (any unit:
//! spheres = [[0, 0, 0, 1], [1.2, 0, 0, 0.8]] # it is scaled to each generated sphere)
//! fraction = 0.3
//! # shape = "rod" takes count = 4 (its spheres, default 4); a built-in shape takes radius =
//! #   (its spheres' at its own size, as a clump file places it: `crate::io::read_clumps`)
//! # mesh = "grain.stl": a closed mesh filled with touching spheres on a cubic lattice of
//! #   spacing = … (in the mesh's units; default a sixth of its bounding box's longest side)
//! # file = "grain.csv": its spheres from a sphere file (x,y,z,r; relative to the scene file)
//! # density = 2650: its clumps' density [kg/m³] (default: their spheres' material's)
//! # mass = 2.1e-5, inertia = [Ixx, Iyy, Izz] or [Ixx, Iyy, Izz, Ixy, Ixz, Iyz]: one clump's
//! #   mass [kg] (in place of density) and inertia tensor [kg·m²] about its centre of mass, in
//! #   place of the union's, for the shape as given in metres; a clump scaled by s has s³ times
//! #   the mass and s⁵ times the inertia
//! # material = "glass": its spheres' material (a [[materials]] name; default: the sphere's
//! #   it replaces, the inflow's, or the first for a clump file's rows)
//! ```

use super::material_spec::{MaterialConfig, material_index};
use crate::clump::{
    Clump, ClumpKind, ClumpSet, ClumpTemplate, Component, MassProperties, RigidBody,
};
use crate::error::{Error, Result};
use crate::particles::Particles;
use glam::{DMat3, DQuat, DVec3};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::PathBuf;

/// One `[[clump]]` table: a shape (built in, or spheres of its own) and how often it is drawn.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClumpConfig {
    /// What the summary calls it (default: the shape's name).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// A built-in shape: `dimer`, `trimer`, `tetrahedron` or `rod`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shape: Option<String>,
    /// Spheres of a rod (default 4).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub count: Option<usize>,
    /// The radius of a built-in shape's spheres \[m\] at its own size, as a clump file places
    /// it (default 1; a generated scene scales every shape to its spheres).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// A shape of its own: its spheres `[x, y, z, r]` in its frame (any unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spheres: Option<Vec<[f64; 4]>>,
    /// A shape of a closed mesh (OBJ, PLY or STL, relative to the scene file), filled with
    /// touching spheres (`ClumpTemplate::from_mesh`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh: Option<PathBuf>,
    /// The lattice spacing of `mesh`'s fill, in the mesh's units (default: a sixth of its
    /// bounding box's longest side).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spacing: Option<f64>,
    /// A shape of its own from a sphere file (CSV `x,y,z,r` or `.npy`, relative to the scene
    /// file): its spheres in its frame (any unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<PathBuf>,
    /// The density of its clumps \[kg/m³\] (default: their spheres' material's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub density: Option<f64>,
    /// The mass of one clump of the shape as given (its spheres read in metres) \[kg\], in
    /// place of `density`: the clumps' density is this over the union's volume.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<f64>,
    /// The inertia tensor of one clump of the shape as given \[kg·m²\], about its centre of
    /// mass in the shape's frame, in place of the union's (with `mass`): `[Ixx, Iyy, Izz]` or
    /// `[Ixx, Iyy, Izz, Ixy, Ixz, Iyz]`, the entries of I = ∫(|r|²·1 − r rᵀ) dm (so
    /// Ixy = −∫xy dm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inertia: Option<Vec<f64>>,
    /// The material of its spheres, a `[[materials]]` name (default: the sphere's it
    /// replaces, the inflow's, or the first for a clump file's rows); its density is the
    /// clumps' unless `density` or `mass` gives theirs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub material: Option<String>,
    /// How often this shape is drawn, a weight > 0 (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fraction: Option<f64>,
}

/// Built-in shapes' names, as errors list them.
pub(crate) const SHAPES: &str = "dimer, trimer, tetrahedron, rod";

impl ClumpConfig {
    /// The template this table describes, refused where it gives no shape or two, an unknown
    /// one, or spheres no template can have.
    pub fn template(&self) -> Result<ClumpTemplate> {
        let bad = |reason: String| {
            Err(Error::InvalidConfig {
                what: format!(
                    "scene table [[clump]]{}",
                    self.name
                        .as_ref()
                        .map_or(String::new(), |n| format!(" \"{n}\""))
                ),
                reason,
            })
        };
        if self.count.is_some() && self.shape.as_deref() != Some("rod") {
            return bad("count is the spheres of shape = \"rod\"".into());
        }
        if self.radius.is_some() && self.shape.is_none() {
            return bad("radius is the spheres' of a built-in shape".into());
        }
        if self.spacing.is_some() && self.mesh.is_none() {
            return bad("spacing is the fill's of a mesh".into());
        }
        let given = [
            self.shape.is_some(),
            self.spheres.is_some(),
            self.mesh.is_some(),
            self.file.is_some(),
        ];
        if given.iter().filter(|&&g| g).count() > 1 {
            return bad("gives more than one of shape, spheres, mesh and file: give one".into());
        }
        if let Some(path) = &self.file {
            let spheres = crate::io::read_particles(path)?;
            let components = (0..spheres.len())
                .map(|i| Component {
                    centre: DVec3::from_array(spheres.exact_position(i)),
                    radius: spheres.radii[i] as f64,
                })
                .collect();
            let name = self.name.clone().unwrap_or_else(|| {
                path.file_stem()
                    .map_or("clump".into(), |s| s.to_string_lossy().into_owned())
            });
            return ClumpTemplate::new(&name, components);
        }
        if let Some(path) = &self.mesh {
            let mesh = crate::mesh::load(path)?;
            let spacing = match self.spacing {
                Some(s) => s,
                None => mesh.bounds().map_or(1.0, |(lo, hi)| {
                    (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max) / 6.0
                }),
            };
            let name = self.name.clone().unwrap_or_else(|| {
                path.file_stem()
                    .map_or("mesh".into(), |s| s.to_string_lossy().into_owned())
            });
            return ClumpTemplate::from_mesh(&name, &mesh, spacing);
        }
        // At most one of shape and spheres is given (refused above).
        let template = match (&self.shape, &self.spheres) {
            (None, None) => {
                return bad(format!(
                    "needs a shape ({SHAPES}), spheres, a mesh or a file"
                ));
            }
            (Some(shape), _) => match (shape.as_str(), self.radius.unwrap_or(1.0)) {
                ("dimer", r) => ClumpTemplate::dimer(r),
                ("trimer", r) => ClumpTemplate::trimer(r),
                ("tetrahedron", r) => ClumpTemplate::tetrahedron(r),
                ("rod", r) => match self.count.unwrap_or(4) {
                    0 => return bad("a rod needs count ≥ 1".into()),
                    n => ClumpTemplate::rod(n, r),
                },
                (other, _) => return bad(format!("has shape \"{other}\", not one of {SHAPES}")),
            }?,
            (None, Some(spheres)) => {
                let components = spheres
                    .iter()
                    .map(|&[x, y, z, r]| Component {
                        centre: DVec3::new(x, y, z),
                        radius: r,
                    })
                    .collect();
                ClumpTemplate::new(self.name.as_deref().unwrap_or("clump"), components)?
            }
        };
        let name = self.name.clone().unwrap_or(template.name.clone());
        Ok(ClumpTemplate { name, ..template })
    }

    /// The mass properties of `template` (this table's shape) at unit density, with the
    /// table's `inertia` in place of the union's where it gives one, and the density its
    /// clumps have where the table sets it (`density`, or `mass` over the union's volume).
    fn mass_properties(&self, template: &ClumpTemplate) -> Result<(MassProperties, Option<f64>)> {
        let bad = |key: &str, reason: String| Error::InvalidConfig {
            what: format!("scene key clump.{key}"),
            reason,
        };
        let positive = |key: &str, value: f64, unit: &str| match value {
            v if v > 0.0 && v.is_finite() => Ok(v),
            v => Err(bad(key, format!("must be a positive {unit}, got {v}"))),
        };
        let m = template.mass_properties();
        let density = match (self.density, self.mass) {
            (Some(_), Some(_)) => {
                return Err(bad(
                    "mass",
                    "gives the density as density does: give one".into(),
                ));
            }
            (Some(d), None) => Some(positive("density", d, "density [kg/m³]")?),
            (None, Some(mass)) => Some(positive("mass", mass, "mass [kg]")? / m.volume),
            (None, None) => None,
        };
        let Some(given) = &self.inertia else {
            return Ok((m, density));
        };
        let Some(density) = density.filter(|_| self.mass.is_some()) else {
            return Err(bad(
                "inertia",
                "is a clump's of the mass given with it: give mass".into(),
            ));
        };
        let tensor = match given.as_slice() {
            &[xx, yy, zz] => DMat3::from_diagonal(DVec3::new(xx, yy, zz)),
            &[xx, yy, zz, xy, xz, yz] => DMat3::from_cols(
                DVec3::new(xx, xy, xz),
                DVec3::new(xy, yy, yz),
                DVec3::new(xz, yz, zz),
            ),
            other => {
                return Err(bad(
                    "inertia",
                    format!(
                        "takes [Ixx, Iyy, Izz] or [Ixx, Iyy, Izz, Ixy, Ixz, Iyz], got {} values",
                        other.len()
                    ),
                ));
            }
        };
        let own = m.with_inertia(tensor * (1.0 / density));
        // A rigid body's principal moments are positive and none exceeds the other two
        // together (the body's mass lies off no more than two of its axes at once).
        let [a, b, c] = own.moments.to_array();
        let rigid = given.iter().all(|v| v.is_finite()) && a > 0.0 && c <= (a + b) * (1.0 + 1e-9);
        if !rigid {
            let moments = own.moments * density;
            return Err(bad(
                "inertia",
                format!(
                    "is not a rigid body's: its principal moments {:.6e}, {:.6e}, {:.6e} kg·m² \
                     must be positive and none larger than the other two together",
                    moments.x, moments.y, moments.z
                ),
            ));
        }
        Ok((own, Some(density)))
    }

    /// The index of this table's material among the scene's `materials`, where it names one.
    fn material_index(&self, materials: &[MaterialConfig]) -> Result<Option<u8>> {
        self.material
            .as_deref()
            .map(|name| material_index(materials, name, "clump.material").map(|k| k as u8))
            .transpose()
    }

    /// This table's weight among the others.
    fn weight(&self) -> Result<f64> {
        match self.fraction.unwrap_or(1.0) {
            w if w > 0.0 && w.is_finite() => Ok(w),
            w => Err(Error::InvalidConfig {
                what: "scene key clump.fraction".into(),
                reason: format!("must be a positive weight, got {w}"),
            }),
        }
    }
}

/// The clumps of the rows of a clump file `path` (`crate::io::read_clumps`), each of the table
/// its `template` names (a table's `name`, else its shape's) at the table's own size, of the
/// table's material (else the first of `materials`, whose densities are `densities`) and
/// density: a row places and moves its template's frame, which becomes the clump's principal
/// frame at its centre of mass.
pub fn clumps_of_rows(
    path: &std::path::Path,
    rows: &[crate::io::ClumpRow],
    tables: &[ClumpConfig],
    materials: &[MaterialConfig],
    densities: &[f32],
) -> Result<Particles> {
    let templates = tables
        .iter()
        .map(ClumpConfig::template)
        .collect::<Result<Vec<_>>>()?;
    let mut set = ClumpSet::default();
    // Each template's centre and principal axes in its own frame, as its kind is made, and
    // its spheres' material.
    let mut frames = Vec::new();
    let mut kind_materials = Vec::new();
    for (t, table) in templates.iter().zip(tables) {
        let (m, density) = table.mass_properties(t)?;
        let material = table.material_index(materials)?.unwrap_or(0);
        frames.push((m.centre, DQuat::from_mat3(&m.axes)));
        let density = density.unwrap_or(densities[material as usize] as f64);
        set.kinds.push(ClumpKind::with_properties(t, &m, density));
        kind_materials.push(material);
    }
    let mut materials_of_spheres = Vec::new();
    for (k, row) in rows.iter().enumerate() {
        let Some(kind) = templates.iter().position(|t| t.name == row.template) else {
            let names: Vec<String> = templates
                .iter()
                .map(|t| format!("\"{}\"", t.name))
                .collect();
            return Err(Error::Parse {
                path: path.to_owned(),
                line: None,
                msg: format!(
                    "clump {k}: template \"{}\" is not one of the [[clump]] tables ({})",
                    row.template,
                    names.join(", ")
                ),
            });
        };
        let (centre, axes) = frames[kind];
        let arm = row.orientation * centre;
        let body = RigidBody::new(
            row.position + arm,
            row.orientation * axes,
            row.velocity + row.angular_velocity.cross(arm),
            row.angular_velocity,
            &set.kinds[kind].inertia,
        );
        set.clumps.push(Clump { kind, body });
        let n = set.kinds[kind].template.components.len();
        materials_of_spheres.extend(std::iter::repeat_n(kind_materials[kind], n));
    }
    let mut out = Particles::with_clumps(set, Particles::default())?;
    if materials_of_spheres.iter().any(|&m| m != 0) {
        out.materials = materials_of_spheres;
    }
    Ok(out)
}

/// The `gravel` scene's grains where it gives no `[[clump]]` tables: tetrahedra (0.4), trimers
/// (0.3) and rods of three spheres (0.3).
pub fn gravel() -> Vec<ClumpConfig> {
    let shape = |name: &str, count: Option<usize>, fraction: f64| ClumpConfig {
        shape: Some(name.into()),
        count,
        fraction: Some(fraction),
        ..ClumpConfig::default()
    };
    vec![
        shape("tetrahedron", None, 0.4),
        shape("trimer", None, 0.3),
        shape("rod", Some(3), 0.3),
    ]
}

/// A table's shape at unit scale, in its principal frame, with its bounding radius and what
/// the table says of its clumps.
#[derive(Debug, Clone, PartialEq)]
struct Shape {
    /// At density 1 and the template's own size.
    kind: ClumpKind,
    /// The largest |c| + r of its components (its centre the union's).
    bound: f64,
    /// How often it is drawn, a weight > 0.
    weight: f64,
    /// The table's own density, if it sets one.
    density: Option<f64>,
    /// The table's material, if it names one.
    material: Option<u8>,
}

/// What makes a sphere a clump of a scene's `[[clump]]` tables: their shapes at unit scale,
/// their weights, densities and materials (the generated spheres' clumps, and an inflow's).
#[derive(Debug, Clone, PartialEq)]
pub struct ClumpMaker {
    shapes: Vec<Shape>,
}

impl ClumpMaker {
    /// The maker of `tables`' clumps, their materials named among `materials`; refuses tables
    /// with no valid shape, weight, mass properties or material.
    pub fn new(tables: &[ClumpConfig], materials: &[MaterialConfig]) -> Result<Self> {
        let shapes = tables
            .iter()
            .map(|table| {
                let template = table.template()?;
                let (m, density) = table.mass_properties(&template)?;
                let kind = ClumpKind::with_properties(&template, &m, 1.0);
                let bound = kind
                    .template
                    .components
                    .iter()
                    .map(|c| c.centre.length() + c.radius)
                    .fold(0.0, f64::max);
                Ok(Shape {
                    kind,
                    bound,
                    weight: table.weight()?,
                    density,
                    material: table.material_index(materials)?,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self { shapes })
    }

    /// A table drawn by weight.
    fn pick(&self, rand: &mut Pcg64) -> usize {
        let total: f64 = self.shapes.iter().map(|s| s.weight).sum();
        let mut pick = rand.random::<f64>() * total;
        self.shapes
            .iter()
            .position(|s| {
                pick -= s.weight;
                pick < 0.0
            })
            .unwrap_or(self.shapes.len() - 1)
    }

    /// The material of table `shape`'s clumps in the place of a sphere of `material`: the
    /// table's, where it names one.
    fn material(&self, shape: usize, material: u8) -> u8 {
        self.shapes[shape].material.unwrap_or(material)
    }

    /// The kind of table `shape`'s clumps in a sphere of radius `r`, of `material` (its
    /// [`material`](Self::material)) whose density is `densities`' entry, unless the table
    /// sets its own.
    fn kind(&self, shape: usize, r: f32, material: u8, densities: &[f32]) -> ClumpKind {
        let s = &self.shapes[shape];
        let density = s.density.unwrap_or(densities[material as usize] as f64);
        s.kind.scaled(r as f64 / s.bound, density)
    }

    /// A clump drawn by `rand` in the place of a sphere at `at` of radius `r` moving at `v`,
    /// of `material` (the materials' densities `densities`): its kind, its body, turned at
    /// random, and its spheres' material.
    pub fn make(
        &self,
        rand: &mut Pcg64,
        (at, r, v): (DVec3, f32, DVec3),
        material: u8,
        densities: &[f32],
    ) -> (ClumpKind, RigidBody, u8) {
        let shape = self.pick(rand);
        let material = self.material(shape, material);
        let kind = self.kind(shape, r, material, densities);
        let body = RigidBody::new(at, random_turn(rand), v, DVec3::ZERO, &kind.inertia);
        (kind, body, material)
    }
}

/// A uniform random rotation (Shoemake 1992).
fn random_turn(rand: &mut Pcg64) -> DQuat {
    let (u1, u2, u3): (f64, f64, f64) = (rand.random(), rand.random(), rand.random());
    let tau = 2.0 * std::f64::consts::PI;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    DQuat::from_xyzw(
        a * (tau * u2).sin(),
        a * (tau * u2).cos(),
        b * (tau * u3).sin(),
        b * (tau * u3).cos(),
    )
    .normalize()
}

/// The random stream of the clumps made of generated spheres of seed `seed` (a stream of its
/// own, so that the spheres' generator and this one do not correlate).
pub fn clump_stream(seed: u64) -> Pcg64 {
    Pcg64::seed_from_u64(seed ^ 0x636c_756d_7073)
}

/// `spheres` (at rest or moving, each of a material whose density is `densities`' entry) made
/// clumps of `tables` (their materials named among `materials`) as the module says, turned at
/// random by `seed`; refuses tables with no valid shape.
pub fn clumps_in_place_of(
    spheres: &Particles,
    tables: &[ClumpConfig],
    materials: &[MaterialConfig],
    densities: &[f32],
    seed: u64,
) -> Result<Particles> {
    let maker = ClumpMaker::new(tables, materials)?;
    let mut rand = clump_stream(seed);
    let mut set = ClumpSet::default();
    let mut kinds: HashMap<(usize, u32, u8), usize> = HashMap::new();
    let mut materials_of_spheres = Vec::new();
    for i in 0..spheres.len() {
        let shape = maker.pick(&mut rand);
        let r = spheres.radii[i];
        let material = maker.material(shape, spheres.material(i) as u8);
        let kind = *kinds
            .entry((shape, r.to_bits(), material))
            .or_insert_with(|| {
                set.kinds.push(maker.kind(shape, r, material, densities));
                set.kinds.len() - 1
            });
        let orientation = random_turn(&mut rand);
        let v = DVec3::from_array(spheres.velocities[i].map(f64::from));
        let at = DVec3::from_array(spheres.exact_position(i));
        let inertia = &set.kinds[kind].inertia;
        let body = RigidBody::new(at, orientation, v, DVec3::ZERO, inertia);
        set.clumps.push(Clump { kind, body });
        let n = set.kinds[kind].template.components.len();
        materials_of_spheres.extend(std::iter::repeat_n(material, n));
    }
    let mut out = Particles::with_clumps(set, Particles::default())?;
    if materials_of_spheres.iter().any(|&m| m != 0) {
        out.materials = materials_of_spheres;
    }
    out.step = spheres.step;
    Ok(out)
}
