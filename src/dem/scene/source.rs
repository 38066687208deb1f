//! Where a scene's spheres come from: the `[source]` table, whose `scene` names the kind of
//! scene and whose other keys are that kind's own (a key another kind takes is refused).
//!
//! ```toml
//! [source]
//! scene = "pour"       # freefall, slab, poly1.2, poly12, poly120, polylog, pour, rotating:
//! spheres = 4000       #   spheres, seed
//! seed = 1
//! # scene = "mesh":    mesh (OBJ, PLY or STL; default a torus), radius, mixed, size, copies, seed
//! # scene = "input":   input (a sphere file)
//! # scene = "hopper":  spheres, seed, grain_radius, orifice, angle, open (`dem::equipment`)
//! # scene = "drum":    spheres, seed, grain_radius, omega, sides, rings (`dem::equipment`)
//! # scene = "agglomerate": spheres, grain_radius, speed (`dem::equipment`)
//! # scene = "gravel":  the drum's keys; its grains clumps (`dem::clump_spec::gravel`)
//! ```

use crate::dem::equipment::{Agglomerate, Drum, Hopper};
use crate::scenes::Scene;
use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::path::PathBuf;

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
    /// A ball of bonded grains dropped on the floor (`dem::equipment`).
    Agglomerate,
    /// The drum of [`Drum`](SceneKind::Drum) turning clumps of mixed shapes, one where each
    /// of its spheres was (`dem::clump_spec`).
    Gravel,
}

impl SceneKind {
    /// Every scene, in the order errors list them.
    pub const ALL: [SceneKind; 14] = [
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
        SceneKind::Agglomerate,
        SceneKind::Gravel,
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
            SceneKind::Agglomerate => "agglomerate",
            SceneKind::Gravel => "gravel",
        }
    }
}

/// `pour`, the scene of a file that names none.
impl Default for SceneKind {
    fn default() -> Self {
        SceneKind::Generated(Scene::Pour)
    }
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
            SceneKind::Agglomerate => PossibleValue::new("agglomerate")
                .help("a ball of grains bonded by liquid bridges dropped on the floor, broken or not"),
            SceneKind::Gravel => PossibleValue::new("gravel")
                .help("the drum turning clumps of tetrahedra, trimers and rods of three"),
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

/// The `[source]` of a generated scene (and `rotating`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Generated {
    /// Number of spheres.
    pub spheres: usize,
    /// Seed of the generator.
    pub seed: u64,
}

impl Default for Generated {
    fn default() -> Self {
        Generated {
            spheres: 4_000,
            seed: 1,
        }
    }
}

/// The `[source]` of scene `mesh`: a mesh filled with spheres on a jittered lattice, in copies
/// side by side on the floor of the box.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MeshFill {
    /// The mesh (OBJ, PLY or STL), relative to the scene file; `None`: a torus.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mesh: Option<PathBuf>,
    /// Sphere radius \[m\]; the lattice spacing is 2.2 times it (short form `mesh_radius`).
    pub radius: f32,
    /// Half of the spheres (at random) get radius `radius / 2` (short form `mesh_mixed`).
    pub mixed: bool,
    /// Side of the cube the mesh is fitted into \[m\] (0.818 holds the paper's 82,337-sphere
    /// bunny at radius 0.005; short form `mesh_size`).
    pub size: f64,
    /// Copies dropped side by side, in layers when they do not fit one (short form
    /// `mesh_copies`).
    pub copies: u32,
    /// Seed of the jitter.
    pub seed: u64,
}

impl Default for MeshFill {
    fn default() -> Self {
        MeshFill {
            mesh: None,
            radius: 0.005,
            mixed: false,
            size: 0.818,
            copies: 1,
            seed: 1,
        }
    }
}

/// The `[source]` of scene `input`: the spheres of a file.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InputFile {
    /// The sphere file (CSV x,y,z,r or .npy N×4, velocity columns optional), relative to the
    /// scene file.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub input: Option<PathBuf>,
}

/// Where a scene's spheres come from, with the parameters of that kind of scene.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// A generated scene of [`Scene`].
    Generated(Scene, Generated),
    /// `freefall` under gravity rotating about the y axis.
    Rotating(Generated),
    /// A mesh filled with spheres.
    Mesh(MeshFill),
    /// The spheres of a file.
    Input(InputFile),
    /// A hopper draining through its orifice.
    Hopper(Hopper),
    /// A turning drum.
    Drum(Drum),
    /// A ball of bonded grains dropped on the floor.
    Agglomerate(Agglomerate),
    /// The drum turning clumps.
    Gravel(Drum),
}

impl Default for Source {
    fn default() -> Self {
        Source::of(SceneKind::default())
    }
}

impl Source {
    /// The scene `kind` with its defaults.
    pub fn of(kind: SceneKind) -> Source {
        match kind {
            SceneKind::Generated(scene) => Source::Generated(scene, Generated::default()),
            SceneKind::Rotating => Source::Rotating(Generated::default()),
            SceneKind::Mesh => Source::Mesh(MeshFill::default()),
            SceneKind::Input => Source::Input(InputFile::default()),
            SceneKind::Hopper => Source::Hopper(Hopper::default()),
            SceneKind::Drum => Source::Drum(Drum::default()),
            SceneKind::Agglomerate => Source::Agglomerate(Agglomerate::default()),
            SceneKind::Gravel => Source::Gravel(Drum::default()),
        }
    }

    /// The scene `kind` with its defaults, but `spheres` (where it takes a number) and `seed`
    /// (where it takes one).
    pub fn sized(kind: SceneKind, spheres: usize, seed: u64) -> Source {
        let mut source = Source::of(kind);
        match &mut source {
            Source::Generated(_, g) | Source::Rotating(g) => *g = Generated { spheres, seed },
            Source::Hopper(h) => (h.spheres, h.seed) = (spheres, seed),
            Source::Drum(d) | Source::Gravel(d) => (d.spheres, d.seed) = (spheres, seed),
            Source::Agglomerate(a) => a.spheres = spheres,
            Source::Mesh(m) => m.seed = seed,
            Source::Input(_) => {}
        }
        source
    }

    /// Which kind of scene this is.
    pub fn kind(&self) -> SceneKind {
        match self {
            Source::Generated(scene, _) => SceneKind::Generated(*scene),
            Source::Rotating(_) => SceneKind::Rotating,
            Source::Mesh(_) => SceneKind::Mesh,
            Source::Input(_) => SceneKind::Input,
            Source::Hopper(_) => SceneKind::Hopper,
            Source::Drum(_) => SceneKind::Drum,
            Source::Agglomerate(_) => SceneKind::Agglomerate,
            Source::Gravel(_) => SceneKind::Gravel,
        }
    }

    /// The number of spheres the scene makes (`None`: a mesh's fill or a file decides).
    pub fn spheres(&self) -> Option<usize> {
        match self {
            Source::Generated(_, g) | Source::Rotating(g) => Some(g.spheres),
            Source::Hopper(h) => Some(h.spheres),
            Source::Drum(d) | Source::Gravel(d) => Some(d.spheres),
            Source::Agglomerate(a) => Some(a.spheres),
            Source::Mesh(_) | Source::Input(_) => None,
        }
    }

    /// The sphere or mesh file the scene reads, if any.
    pub fn file(&self) -> Option<&std::path::Path> {
        match self {
            Source::Mesh(m) => m.mesh.as_deref(),
            Source::Input(i) => i.input.as_deref(),
            _ => None,
        }
    }

    /// The sphere or mesh file the scene reads, if any.
    pub fn file_mut(&mut self) -> Option<&mut PathBuf> {
        match self {
            Source::Mesh(m) => m.mesh.as_mut(),
            Source::Input(i) => i.input.as_mut(),
            _ => None,
        }
    }

    /// The keys of the `[source]` of `kind`, `scene` aside.
    pub fn fields(kind: SceneKind) -> &'static [&'static str] {
        match kind {
            SceneKind::Generated(_) | SceneKind::Rotating => fields_of::<Generated>(),
            SceneKind::Mesh => fields_of::<MeshFill>(),
            SceneKind::Input => fields_of::<InputFile>(),
            SceneKind::Hopper => fields_of::<Hopper>(),
            SceneKind::Drum | SceneKind::Gravel => fields_of::<Drum>(),
            SceneKind::Agglomerate => fields_of::<Agglomerate>(),
        }
    }
}

/// Written as a table: `scene`, then the kind's own keys.
impl Serialize for Source {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        #[derive(Serialize)]
        struct Tagged<'a, T> {
            scene: SceneKind,
            #[serde(flatten)]
            fields: &'a T,
        }
        let scene = self.kind();
        match self {
            Source::Generated(_, g) | Source::Rotating(g) => {
                Tagged { scene, fields: g }.serialize(s)
            }
            Source::Mesh(m) => Tagged { scene, fields: m }.serialize(s),
            Source::Input(i) => Tagged { scene, fields: i }.serialize(s),
            Source::Hopper(h) => Tagged { scene, fields: h }.serialize(s),
            Source::Drum(d) | Source::Gravel(d) => Tagged { scene, fields: d }.serialize(s),
            Source::Agglomerate(a) => Tagged { scene, fields: a }.serialize(s),
        }
    }
}

/// Read from a table: `scene` (default `pour`) picks the kind, whose struct reads the other
/// keys and refuses any it does not take.
impl<'de> Deserialize<'de> for Source {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let mut table = toml::Table::deserialize(d)?;
        let kind = match table.remove("scene") {
            None => SceneKind::default(),
            Some(name) => SceneKind::deserialize(name).map_err(D::Error::custom)?,
        };
        let rest = toml::Value::Table(table);
        // The struct of `kind` reads the rest; an error names the key it is about.
        fn read<T: serde::de::DeserializeOwned, E: serde::de::Error>(
            kind: SceneKind,
            rest: toml::Value,
        ) -> Result<T, E> {
            serde_path_to_error::deserialize(rest).map_err(|e| {
                let key = e.path().to_string();
                let message = e.into_inner().message().to_owned();
                match key.as_str() {
                    "." => E::custom(format!("scene \"{kind}\": {message}")),
                    key => E::custom(format!("{key} of scene \"{kind}\": {message}")),
                }
            })
        }
        Ok(match kind {
            SceneKind::Generated(scene) => Source::Generated(scene, read(kind, rest)?),
            SceneKind::Rotating => Source::Rotating(read(kind, rest)?),
            SceneKind::Mesh => Source::Mesh(read(kind, rest)?),
            SceneKind::Input => Source::Input(read(kind, rest)?),
            SceneKind::Hopper => Source::Hopper(read(kind, rest)?),
            SceneKind::Drum => Source::Drum(read(kind, rest)?),
            SceneKind::Agglomerate => Source::Agglomerate(read(kind, rest)?),
            SceneKind::Gravel => Source::Gravel(read(kind, rest)?),
        })
    }
}

/// The field names serde's derive gives the struct `T`: a deserializer that asks for a struct
/// hands them over, and this one keeps them and stops.
fn fields_of<'de, T: Deserialize<'de>>() -> &'static [&'static str] {
    struct Fields(&'static [&'static str]);
    impl<'de> Deserializer<'de> for &mut Fields {
        type Error = serde::de::value::Error;

        fn deserialize_any<V: serde::de::Visitor<'de>>(
            self,
            _: V,
        ) -> Result<V::Value, Self::Error> {
            Err(Self::Error::custom("not a struct"))
        }

        fn deserialize_struct<V: serde::de::Visitor<'de>>(
            self,
            _: &'static str,
            fields: &'static [&'static str],
            _: V,
        ) -> Result<V::Value, Self::Error> {
            self.0 = fields;
            Err(Self::Error::custom("fields read"))
        }

        serde::forward_to_deserialize_any! {
            bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
            option unit unit_struct newtype_struct seq tuple tuple_struct map enum identifier
            ignored_any
        }
    }
    let mut fields = Fields(&[]);
    let _ = T::deserialize(&mut fields);
    fields.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_kind_reads_its_own_keys_and_refuses_another_kinds() {
        assert_eq!(Source::fields(SceneKind::Rotating), ["spheres", "seed"]);
        assert_eq!(
            Source::fields(SceneKind::Hopper),
            [
                "spheres",
                "seed",
                "grain_radius",
                "orifice",
                "angle",
                "open"
            ]
        );
        for kind in SceneKind::ALL {
            let source = Source::of(kind);
            assert_eq!(source.kind(), kind);
            let table = toml::Table::try_from(&source).unwrap();
            assert_eq!(table["scene"].as_str(), Some(kind.name()));
            let keys: Vec<&str> = table
                .keys()
                .map(String::as_str)
                .filter(|k| *k != "scene")
                .collect();
            let mut expected: Vec<&str> = Source::fields(kind).to_vec();
            // A file not given is not written.
            expected.retain(|f| !["mesh", "input"].contains(f));
            let (mut keys, mut expected) = (keys, expected);
            keys.sort();
            expected.sort();
            assert_eq!(keys, expected, "{kind}");
            let back: Source = toml::Value::Table(table).try_into().unwrap();
            assert_eq!(back, source);
        }
        let e = toml::from_str::<Source>("scene = \"mesh\"\nspheres = 3")
            .unwrap_err()
            .to_string();
        assert!(e.contains("scene \"mesh\"") && e.contains("spheres"), "{e}");
        let e = toml::from_str::<Source>("spheres = \"many\"")
            .unwrap_err()
            .to_string();
        assert!(e.contains("spheres of scene \"pour\": invalid type"), "{e}");
        let pour: Source = toml::from_str("spheres = 30").unwrap();
        assert_eq!(pour.spheres(), Some(30));
        assert_eq!(pour.kind(), SceneKind::Generated(Scene::Pour));
    }
}
