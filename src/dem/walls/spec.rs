//! The `[[wall]]` tables of a scene file and the walls they make.
//!
//! ```toml
//! box_walls = false                     # the six walls of the box off (default: on)
//!
//! [[wall]]
//! mesh = "hopper.stl"                   # OBJ, PLY or STL, relative to the scene file
//! scale = 0.001                         # uniform, applied first (default 1)
//! rotate = { axis = [1, 0, 0], degrees = 90 }   # then turned about the origin (default none)
//! translate = [0.5, 0.5, 0.2]           # then moved (default none): the wall's rest pose
//! velocity = [0, 0, 0.1]                # m/s, from `start` on (default 0)
//! omega = 3.14                          # rad/s about `axis` through `center`, from `start` on
//! axis = [0, 1, 0]                      # default [0, 0, 1]
//! center = [0.5, 0.5, 0.5]              # default [0, 0, 0]; the wall's torques are about it
//! start = 0.5                           # s (default 0)
//! friction = 0.3                        # μ with this wall (default: the scene's wall_friction)
//! ```

use super::MeshWall;
use super::motion::Motion;
use super::triangles::TriangleMesh;
use crate::dem::model::MAX_FRICTION;
use crate::error::{Error, Result};
use crate::mesh::Mesh;
use crate::spheres::MAX_MAGNITUDE;
use glam::{DQuat, DVec3};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A rotation of a wall's rest pose: `degrees` about `axis` (through the origin).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rotation {
    /// Axis (any length but zero).
    pub axis: [f64; 3],
    /// Angle \[°\], right-handed about `axis`.
    pub degrees: f64,
}

/// One `[[wall]]` table (module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WallConfig {
    /// Mesh file (OBJ, PLY or STL), relative to the scene file.
    pub mesh: PathBuf,
    /// Uniform scale, applied first (default 1).
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub scale: f64,
    /// Rotation about the origin, after the scale.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotate: Option<Rotation>,
    /// Translation, last \[m\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translate: Option<[f64; 3]>,
    /// Velocity from `start` on \[m/s\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<[f64; 3]>,
    /// Angular speed about `axis` through `center` from `start` on \[rad/s\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub omega: Option<f64>,
    /// Axis of `omega` (default z).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis: Option<[f64; 3]>,
    /// A point of the rotation axis, and the point the wall's torques are about \[m\]
    /// (default the origin).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub center: Option<[f64; 3]>,
    /// Time the motion starts \[s\] (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<f64>,
    /// Sliding friction μ with this wall (default: the pair's, by the materials: the scene's
    /// `wall_friction` for a wall without a material).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<f64>,
    /// The wall's material, a `[[materials]]` name (default: none, a rigid wall).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub material: Option<String>,
}

fn one() -> f64 {
    1.0
}

fn is_one(x: &f64) -> bool {
    *x == 1.0
}

impl WallConfig {
    /// A wall of `mesh` with every other field at its default.
    pub fn of(mesh: impl Into<PathBuf>) -> Self {
        Self {
            mesh: mesh.into(),
            scale: 1.0,
            rotate: None,
            translate: None,
            velocity: None,
            omega: None,
            axis: None,
            center: None,
            start: None,
            friction: None,
            material: None,
        }
    }

    /// The wall: its mesh read and put in its rest pose. `index` names it in errors (the
    /// scene's `wall` tables from 0) and `material` is its material's index (resolved from its
    /// name by the scene).
    pub fn build(&self, index: usize, material: Option<u32>) -> Result<MeshWall> {
        let mesh = crate::mesh::load(&self.mesh)?;
        self.build_from(index, &mesh, material)
    }

    /// As [`Self::build`], from a mesh already read.
    pub fn build_from(&self, index: usize, mesh: &Mesh, material: Option<u32>) -> Result<MeshWall> {
        let bad = |reason: String| Error::InvalidConfig {
            what: format!("wall {index} ({})", self.mesh.display()),
            reason,
        };
        // Every value is used as an f32.
        let finite = |v: &[f64]| v.iter().all(|&x| (x as f32).is_finite());
        if !(self.scale.is_finite() && self.scale > 0.0) {
            return Err(bad(format!("scale must be positive, got {}", self.scale)));
        }
        let axis_of = |name: &str, a: [f64; 3]| {
            DVec3::from(a)
                .try_normalize()
                .filter(|_| finite(&a))
                .ok_or_else(|| {
                    bad(format!(
                        "{name} must be a finite, non-zero vector, got {a:?}"
                    ))
                })
        };
        let rotation = match self.rotate {
            None => DQuat::IDENTITY,
            Some(r) if r.degrees.is_finite() => {
                DQuat::from_axis_angle(axis_of("rotate.axis", r.axis)?, r.degrees.to_radians())
            }
            Some(r) => {
                return Err(bad(format!(
                    "rotate.degrees must be finite, got {}",
                    r.degrees
                )));
            }
        };
        let vectors = [
            ("translate", self.translate),
            ("velocity", self.velocity),
            ("center", self.center),
        ];
        for (name, v) in vectors {
            if let Some(v) = v.filter(|v| !finite(v)) {
                return Err(bad(format!(
                    "{name} must be finite in single precision (|x| < 3.4e38), got {v:?}"
                )));
            }
        }
        let scalars = [
            ("omega", self.omega),
            ("start", self.start),
            ("friction", self.friction),
        ];
        for (name, x) in scalars {
            if let Some(x) = x.filter(|&x| !finite(&[x])) {
                return Err(bad(format!(
                    "{name} must be finite in single precision (|x| < 3.4e38), got {x}"
                )));
            }
        }
        if let Some(mu) = self
            .friction
            .filter(|mu| !(0.0..=MAX_FRICTION).contains(mu))
        {
            return Err(bad(format!(
                "friction must be from 0 to {MAX_FRICTION:e}, got {mu}"
            )));
        }
        mesh.validate().map_err(|e| bad(e.to_string()))?;
        let translate = DVec3::from(self.translate.unwrap_or_default());
        let vertices: Vec<glam::Vec3> = mesh
            .vertices
            .iter()
            .map(|&v| (rotation * (self.scale * DVec3::from(v)) + translate).as_vec3())
            .collect();
        let beyond = |v: &&glam::Vec3| !v.is_finite() || v.abs().max_element() > MAX_MAGNITUDE;
        if let Some(v) = vertices.iter().find(beyond) {
            return Err(bad(format!(
                "a vertex at {v} lies beyond ±{MAX_MAGNITUDE:e} m once scaled, rotated and \
                 translated: the contact geometry squares lengths in single precision"
            )));
        }
        let triangles = TriangleMesh::new(&vertices, &mesh.triangles);
        if triangles.triangles().is_empty() {
            return Err(bad("every triangle has zero area".into()));
        }
        let motion = Motion {
            velocity: DVec3::from(self.velocity.unwrap_or_default()),
            omega: self.omega.unwrap_or(0.0),
            axis: axis_of("axis", self.axis.unwrap_or([0.0, 0.0, 1.0]))?,
            centre: DVec3::from(self.center.unwrap_or_default()),
            start: self.start.unwrap_or(0.0),
        };
        Ok(MeshWall {
            name: self.mesh.display().to_string(),
            triangles,
            motion,
            friction: self.friction.map(|mu| mu as f32),
            material,
        })
    }
}
