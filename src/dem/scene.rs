//! DEM scenes: a TOML description (every field optional, every field overridable with
//! `key=value` on the command line) that builds the particles at t = 0 and the step parameters.
//!
//! ```toml
//! scene = "slab"         # freefall, slab, poly1.2, poly12, poly120, polylog, rotating, input
//! spheres = 50000
//! seed = 1
//! steps = 5000
//! dt = 1e-4              # default: 1e-4 (freefall, slab, rotating), 5e-5 (poly*)
//! box_lo = [0, 0, 0]     # default: the scene's box
//! box_hi = [1, 1, 1]
//! gravity = [0, 0, -9.81]
//! gravity_spin = 0.0     # rad/s about y; rotating: 0.25π
//! density = 500
//! restitution = 0.5
//! stiffness = 2.0        # N/m; default: a 10-step contact for the two lightest spheres
//! mode = "mochi"         # or "nns"
//! frame_every = 250      # 0: no frames
//! csv = false            # CSV frames beside the VTK ones
//! input = "start.csv"    # scene = "input": any sphere file
//! ```

use super::model::{Material, StepParams};
use super::particles::Particles;
use crate::error::{Error, Result};
use crate::proxy::ProxyMode;
use crate::scenes::{self, Layout, Scene, SceneSpec};
use crate::spheres::SphereSet;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A DEM scene (see the module docs for the file format).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneConfig {
    /// Generator: a named scene of [`Scene`], `rotating` (freefall under rotating gravity) or
    /// `input` (the sphere file `input`).
    pub scene: String,
    /// Number of spheres (generated scenes).
    pub spheres: usize,
    /// Seed of the generator.
    pub seed: u64,
    /// Steps to run.
    pub steps: u64,
    /// Time step [s]; `None`: the scene's default.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dt: Option<f64>,
    /// Lower corner of the box [m]; `None`: the scene's box.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub box_lo: Option<[f64; 3]>,
    /// Upper corner of the box [m]; `None`: the scene's box.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub box_hi: Option<[f64; 3]>,
    /// Gravity at t = 0 [m/s²].
    pub gravity: [f64; 3],
    /// Angular velocity of gravity about the y axis [rad/s]; `None`: 0, or 0.25π for `rotating`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gravity_spin: Option<f64>,
    /// Density [kg/m³].
    pub density: f64,
    /// Restitution coefficient, in (0, 1].
    pub restitution: f64,
    /// Normal stiffness [N/m]; `None`: derived (a 10-step contact for the lightest pair).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<f64>,
    /// `mochi` (cells of 2·r_max) or `nns` (4·r_max).
    pub mode: String,
    /// Steps between frames (0: none).
    pub frame_every: u64,
    /// Also write each frame as CSV.
    pub csv: bool,
    /// Sphere file of scene `input` (CSV x,y,z,r or .npy N×4), relative to the scene file.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub input: Option<PathBuf>,
}

impl Default for SceneConfig {
    fn default() -> Self {
        Self {
            scene: "slab".into(),
            spheres: 50_000,
            seed: 1,
            steps: 5_000,
            dt: None,
            box_lo: None,
            box_hi: None,
            gravity: [0.0, 0.0, -9.81],
            gravity_spin: None,
            density: 500.0,
            restitution: 0.5,
            stiffness: None,
            mode: "mochi".into(),
            frame_every: 250,
            csv: false,
            input: None,
        }
    }
}

/// Everything a run starts from.
#[derive(Debug, Clone)]
pub struct Start {
    /// Particles at t = 0.
    pub particles: Particles,
    /// Step parameters.
    pub params: StepParams,
    /// Proxy mode of the grid.
    pub mode: ProxyMode,
}

/// Parses a `key=value` override into `table` (`value` in TOML syntax; a bare word is taken as
/// a string, so `scene=slab` works).
pub fn apply_override(table: &mut toml::Table, assignment: &str) -> Result<()> {
    let bad = |msg: String| Error::Usage(format!("--set {assignment:?}: {msg}"));
    let (key, value) = assignment
        .split_once('=')
        .ok_or_else(|| bad("expected key=value".into()))?;
    let key = key.trim();
    if key.is_empty() || !key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return Err(bad(format!("{key:?} is not a field name")));
    }
    let value = value.trim();
    let parsed: toml::Value = match format!("v = {value}").parse::<toml::Table>() {
        Ok(mut t) => t.remove("v").expect("parsed the key v"),
        Err(_) => toml::Value::String(value.to_owned()),
    };
    table.insert(key.to_owned(), parsed);
    Ok(())
}

impl SceneConfig {
    /// Reads a scene file (`None`: the defaults) and applies `overrides` (`key=value`).
    pub fn load(path: Option<&Path>, overrides: &[String]) -> Result<Self> {
        let text = match path {
            None => None,
            Some(p) => Some(std::fs::read_to_string(p).map_err(|error| Error::Io {
                path: p.to_owned(),
                error,
            })?),
        };
        Self::parse(text.as_deref(), path, overrides)
    }

    /// Parses scene TOML (`None`: the defaults) from `origin` (named in errors; relative input
    /// paths are taken from its folder) and applies `overrides` (`key=value`).
    pub fn parse(text: Option<&str>, origin: Option<&Path>, overrides: &[String]) -> Result<Self> {
        let where_ = || origin.map_or_else(|| "command line".into(), Path::to_owned);
        let mut table = match text {
            None => toml::Table::new(),
            Some(text) => text.parse::<toml::Table>().map_err(|e| Error::Parse {
                path: where_(),
                line: None,
                msg: e.to_string().trim_end().to_owned(),
            })?,
        };
        for o in overrides {
            apply_override(&mut table, o)?;
        }
        // Deserialize from text, so that errors quote the offending line: the file's own text
        // when nothing was overridden, else the merged table's.
        let merged;
        let source = match text {
            Some(t) if overrides.is_empty() => t,
            _ => {
                merged = toml::to_string(&table).expect("a TOML table serializes");
                merged.as_str()
            }
        };
        let mut config: SceneConfig = toml::from_str(source).map_err(|e| Error::Parse {
            path: where_(),
            line: None,
            msg: e.to_string().trim_end().to_owned(),
        })?;
        if let (Some(input), Some(dir)) = (&config.input, origin.and_then(Path::parent))
            && input.is_relative()
        {
            config.input = Some(dir.join(input));
        }
        Ok(config)
    }

    /// This scene as TOML (saved in checkpoints).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a scene always serializes")
    }

    fn proxy_mode(&self) -> Result<ProxyMode> {
        use clap::ValueEnum;
        ProxyMode::from_str(&self.mode, true)
            .map_err(|_| Error::Usage(format!("mode must be mochi or nns, got {:?}", self.mode)))
    }

    /// The named generator behind `scene` (`rotating` is freefall).
    fn generator(&self) -> Result<Option<Scene>> {
        use clap::ValueEnum;
        match self.scene.as_str() {
            "input" => Ok(None),
            "rotating" => Ok(Some(Scene::Freefall)),
            name => Scene::from_str(name, true).map(Some).map_err(|_| {
                Error::Usage(format!(
                    "unknown scene {name:?}: use freefall, slab, poly1.2, poly12, poly120, \
                     polylog, rotating or input"
                ))
            }),
        }
    }

    /// Builds the particles at t = 0 and the step parameters.
    pub fn build(&self) -> Result<Start> {
        let spheres = match self.generator()? {
            Some(scene) => scenes::generate(&SceneSpec {
                scene,
                n: self.spheres,
                seed: self.seed,
                layout: Layout::Lattice,
            })?,
            None => {
                let input = self.input.as_ref().ok_or_else(|| {
                    Error::Usage("scene \"input\" needs input = \"FILE\" (--input)".into())
                })?;
                crate::io::read_spheres(input)?
            }
        };
        self.start_from(Particles::at_rest(&spheres))
    }

    /// The step parameters for `particles` (at t = 0, or from a checkpoint of this scene).
    pub fn start_from(&self, particles: Particles) -> Result<Start> {
        let mode = self.proxy_mode()?;
        let generator = self.generator()?;
        let (r_min, r_max) = particles.radius_range();
        let (default_lo, default_hi) = match generator {
            Some(scene) => {
                let side = scene.box_side(particles.len(), Layout::Lattice);
                ([0.0; 3], [side; 3])
            }
            // A file: its bounds with a margin of two largest diameters.
            None => match SphereSet::new(particles.positions.clone(), particles.radii.clone())?
                .bounds()
            {
                Some((lo, hi)) => {
                    let m = 4.0 * r_max as f64;
                    (lo.map(|x| x as f64 - m), hi.map(|x| x as f64 + m))
                }
                None => ([0.0; 3], [1.0; 3]),
            },
        };
        let dt = self.dt.unwrap_or(match generator {
            Some(Scene::Poly1_2 | Scene::Poly12 | Scene::Poly120 | Scene::Polylog) => 5e-5,
            _ => 1e-4,
        });
        let spin = self.gravity_spin.unwrap_or(if self.scene == "rotating" {
            0.25 * std::f64::consts::PI
        } else {
            0.0
        });
        let material = Material {
            density: self.density,
            restitution: self.restitution,
            stiffness: self.stiffness,
        };
        let (lo, hi) = (
            self.box_lo.unwrap_or(default_lo),
            self.box_hi.unwrap_or(default_hi),
        );
        let r_min = if particles.is_empty() { 1.0 } else { r_min };
        let params = StepParams::new(&material, dt, lo, hi, self.gravity, spin, r_min)?;
        if let Some(index) = particles
            .positions
            .iter()
            .position(|c| (0..3).any(|a| !(lo[a]..=hi[a]).contains(&(c[a] as f64))))
        {
            return Err(Error::InvalidSphere {
                index,
                reason: format!(
                    "centre {:?} is outside the box {lo:?} .. {hi:?}",
                    particles.positions[index]
                ),
            });
        }
        Ok(Start {
            particles,
            params,
            mode,
        })
    }

    /// This scene with every derived value (time step, box, gravity spin, stiffness) written
    /// out as `start` resolved it, so a checkpoint resumes with exactly the same parameters.
    pub fn resolved(&self, start: &Start) -> SceneConfig {
        let p = &start.params;
        SceneConfig {
            dt: Some(p.dt as f64),
            box_lo: Some(p.box_lo.map(f64::from)),
            box_hi: Some(p.box_hi.map(f64::from)),
            gravity_spin: Some(p.gravity_spin as f64),
            stiffness: Some(p.stiffness as f64),
            ..self.clone()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_take_toml_values_and_bare_words() {
        let c = SceneConfig::load(
            None,
            &[
                "scene=poly12".into(),
                "spheres = 2000".into(),
                "gravity=[0, -9.81, 0]".into(),
                "stiffness=3.5".into(),
            ],
        )
        .unwrap();
        assert_eq!(c.scene, "poly12");
        assert_eq!(c.spheres, 2000);
        assert_eq!(c.gravity, [0.0, -9.81, 0.0]);
        assert_eq!(c.stiffness, Some(3.5));
    }

    #[test]
    fn unknown_fields_and_bad_values_are_errors() {
        let e = SceneConfig::load(None, &["sphers=10".into()]).unwrap_err();
        assert!(e.to_string().contains("sphers"), "{e}");
        let e = SceneConfig::load(None, &["spheres=-3".into()]).unwrap_err();
        assert!(
            e.to_string().contains("spheres") || e.to_string().contains("-3"),
            "{e}"
        );
        let e = SceneConfig::load(None, &["no equals sign".into()]).unwrap_err();
        assert!(e.to_string().contains("key=value"), "{e}");
        let c = SceneConfig::load(None, &["scene=teapot".into()]).unwrap();
        assert!(c.build().unwrap_err().to_string().contains("teapot"));
    }

    #[test]
    fn a_scene_round_trips_through_toml() {
        let c = SceneConfig {
            dt: Some(2e-5),
            stiffness: Some(10.0),
            ..SceneConfig::default()
        };
        let back: SceneConfig = toml::from_str(&c.to_toml()).unwrap();
        assert_eq!(back, c);
    }

    #[test]
    fn rotating_spins_gravity_a_quarter_pi_per_second() {
        let c = SceneConfig::load(None, &["scene=rotating".into(), "spheres=1000".into()]).unwrap();
        let s = c.build().unwrap();
        assert!((s.params.gravity_spin as f64 - 0.25 * std::f64::consts::PI).abs() < 1e-6);
    }
}
