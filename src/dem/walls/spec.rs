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

/// A wall's new motion ([`WallConfig::moving_on`]): each field `None` keeps the wall's own (its
/// rotation's centre where the wall's translation has carried it).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct NewMotion {
    /// Velocity \[m/s\].
    pub velocity: Option<[f64; 3]>,
    /// Angular speed about `axis` through `center` \[rad/s\].
    pub omega: Option<f64>,
    /// Axis of `omega`.
    pub axis: Option<[f64; 3]>,
    /// A point of the rotation axis now \[m\].
    pub center: Option<[f64; 3]>,
}

impl WallConfig {
    /// This wall moving as `motion` says from time `t` on, from where it is at `t`: its pose
    /// then is folded into its rest pose (`rotate` and `translate`) and its motion starts at
    /// `t`, so it goes on without a jump (and a run resumed later puts it where this one has
    /// it). The wall's fields are the valid ones of a built wall.
    pub fn moving_on(&self, t: f64, motion: &NewMotion) -> Self {
        let velocity = DVec3::from(self.velocity.unwrap_or_default());
        let omega = self.omega.unwrap_or(0.0);
        let axis = DVec3::from(self.axis.unwrap_or([0.0, 0.0, 1.0])).normalize_or(DVec3::Z);
        let centre = DVec3::from(self.center.unwrap_or_default());
        let tau = (t - self.start.unwrap_or(0.0)).max(0.0);
        // The pose at t (walls::Motion::pose_at): x = R·x_rest + (centre + v·τ − R·centre).
        let turn = DQuat::from_axis_angle(axis, omega * tau);
        let moved_centre = centre + velocity * tau;
        let offset = moved_centre - turn * centre;
        let rest = self.rotate.map_or(DQuat::IDENTITY, |r| {
            DQuat::from_axis_angle(DVec3::from(r.axis).normalize(), r.degrees.to_radians())
        });
        let (rotate_axis, angle) = (turn * rest).to_axis_angle();
        let translate = turn * DVec3::from(self.translate.unwrap_or_default()) + offset;
        WallConfig {
            rotate: (angle != 0.0).then(|| Rotation {
                axis: rotate_axis.into(),
                degrees: angle.to_degrees(),
            }),
            translate: Some(translate.into()),
            velocity: Some(motion.velocity.unwrap_or(velocity.into())),
            omega: Some(motion.omega.unwrap_or(omega)),
            axis: Some(motion.axis.unwrap_or(axis.into())),
            center: Some(motion.center.unwrap_or(moved_centre.into())),
            start: Some(t),
            ..self.clone()
        }
    }

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

#[cfg(test)]
mod tests {
    use super::*;

    /// A tetrahedron a metre across.
    fn tetrahedron() -> Mesh {
        Mesh {
            vertices: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        }
    }

    /// The wall's triangles at `t`.
    fn at(wall: &WallConfig, t: f64) -> Vec<[[f32; 3]; 3]> {
        let built = wall.build_from(0, &tetrahedron(), None).unwrap();
        built.triangles_at(&built.motion.pose_at(t))
    }

    /// The largest distance between corresponding corners.
    fn gap(a: &[[[f32; 3]; 3]], b: &[[[f32; 3]; 3]]) -> f32 {
        let corners = |t: &[[[f32; 3]; 3]]| t.iter().flatten().copied().collect::<Vec<_>>();
        let (a, b) = (corners(a), corners(b));
        a.iter()
            .zip(&b)
            .map(|(p, q)| (0..3).map(|k| (p[k] - q[k]).abs()).fold(0.0, f32::max))
            .fold(0.0, f32::max)
    }

    #[test]
    fn a_wall_given_a_new_motion_goes_on_from_where_it_is() {
        let wall = WallConfig {
            scale: 0.5,
            rotate: Some(Rotation {
                axis: [1.0, 1.0, 0.0],
                degrees: 30.0,
            }),
            translate: Some([0.2, -0.1, 0.3]),
            velocity: Some([0.1, 0.0, -0.2]),
            omega: Some(2.0),
            axis: Some([0.0, 1.0, 1.0]),
            center: Some([0.5, 0.5, 0.0]),
            start: Some(0.25),
            ..WallConfig::of("tetrahedron.obj")
        };
        let t = 1.7;
        let new = NewMotion {
            velocity: Some([0.0, 0.3, 0.0]),
            omega: Some(-1.0),
            ..NewMotion::default()
        };
        let moved = wall.moving_on(t, &new);
        // Where it was at t, and from there as told: translated at the new velocity, turned
        // about the old axis through the centre where the old motion had carried it.
        assert!(gap(&at(&moved, t), &at(&wall, t)) < 1e-6);
        assert!(
            gap(&at(&moved, 0.0), &at(&wall, t)) < 1e-6,
            "at rest before t"
        );
        let later = at(&moved, t + 0.5);
        let centre = DVec3::from([0.5, 0.5, 0.0]) + DVec3::from([0.1, 0.0, -0.2]) * (t - 0.25);
        let axis = DVec3::from([0.0, 1.0, 1.0]).normalize();
        let turn = DQuat::from_axis_angle(axis, -0.5);
        let expected: Vec<[[f32; 3]; 3]> = at(&wall, t)
            .iter()
            .map(|tri| {
                tri.map(|p| {
                    let x = DVec3::from(p.map(f64::from));
                    (turn * (x - centre) + centre + DVec3::new(0.0, 0.15, 0.0))
                        .as_vec3()
                        .to_array()
                })
            })
            .collect();
        assert!(gap(&later, &expected) < 1e-5, "{later:?} vs {expected:?}");
        // Nothing given: the same motion, on from t.
        let same = wall.moving_on(t, &NewMotion::default());
        assert!(gap(&at(&same, 2.3), &at(&wall, 2.3)) < 1e-5);
    }
}
