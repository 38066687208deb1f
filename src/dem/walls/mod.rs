//! Walls besides the box: triangle meshes in a pose that moves. Geometry only: which
//! points of which wall a sphere touches, and how fast the wall moves there; the force of each
//! contact is the model's ([`crate::dem::model::contact::surface_contact`], the box walls' law
//! with the wall's velocity), and each engine applies it in its step.
//!
//! - [`spec`]: the `[[wall]]` tables of a scene file, and the walls they make;
//! - [`triangles`]: a wall's triangles in its rest pose with a hierarchy for the queries, and
//!   the closest point of a triangle;
//! - [`motion`]: the prescribed motion and the pose at a time;
//! - [`touch`]: the contacts of a sphere with one mesh, each resolved once.
//!
//! A sphere's contacts with mesh wall `w` keep their history under partner id
//! [`mesh_partner`]`(w)`, the k-th contact of that wall (nearest first) in the k-th entry
//! with that id.

pub mod motion;
pub mod spec;
pub mod touch;
pub mod triangles;

pub use motion::{Motion, Pose};
pub use spec::{Rotation, WallConfig};
pub use touch::{SurfaceTouch, Touches, touches};
pub use triangles::TriangleMesh;

use crate::error::{Error, Result};
pub use crate::particles::{FIRST_MESH_WALL, MESH_WALLS};

/// The most a mesh wall may move in one step, as a share of the smallest sphere radius: its
/// contacts then build up over several steps, so no sphere is passed through.
pub const MAX_WALL_STEP: f64 = 0.1;

/// The history partner id of mesh wall `w`.
#[inline]
pub fn mesh_partner(w: usize) -> u32 {
    FIRST_MESH_WALL + w as u32
}

/// One mesh wall of a run.
#[derive(Debug, Clone)]
pub struct MeshWall {
    /// What the scene calls it (its mesh file).
    pub name: String,
    /// Its triangles in the rest pose.
    pub triangles: TriangleMesh,
    /// How it moves.
    pub motion: Motion,
    /// Its own sliding friction μ with the spheres (`None`: each pair's, by the materials).
    pub friction: Option<f32>,
    /// Its material, an index into the scene's materials (`None`: rigid).
    pub material: Option<u32>,
}

impl MeshWall {
    /// Its column in `table`: its material's, or a rigid wall's.
    pub fn column(&self, table: &crate::dem::model::MaterialTable) -> u32 {
        self.material.unwrap_or(table.column_of_rigid_wall())
    }

    /// The fastest any point of the wall moves \[m/s\]: its translation plus its turn times
    /// the farthest corner's distance from the rotation axis (which moves with it).
    pub fn top_speed(&self) -> f64 {
        let m = &self.motion;
        let reach = (self.triangles.triangles().iter())
            .flat_map(|t| t.corners)
            .map(|c| (c.as_dvec3() - m.centre).cross(m.axis).length())
            .fold(0.0, f64::max);
        m.velocity.length() + m.omega.abs() * reach
    }

    /// Its triangles in `pose`, three corners each.
    pub fn triangles_at(&self, pose: &Pose) -> Vec<[[f32; 3]; 3]> {
        let tris = self.triangles.triangles();
        tris.iter()
            .map(|t| t.corners.map(|c| pose.to_world(c).to_array()))
            .collect()
    }
}

/// The walls of a run: the six of the box (or none) and the mesh walls.
#[derive(Debug, Clone)]
pub struct WallSet {
    /// Whether the six walls of the box hold the spheres in.
    pub box_walls: bool,
    /// Mesh walls, in the scene's order.
    pub meshes: Vec<MeshWall>,
}

impl Default for WallSet {
    /// The box alone.
    fn default() -> Self {
        Self {
            box_walls: true,
            meshes: Vec::new(),
        }
    }
}

impl WallSet {
    /// The box walls (or not) and `meshes`, refusing more mesh walls than history ids.
    pub fn new(box_walls: bool, meshes: Vec<MeshWall>) -> Result<Self> {
        if meshes.len() > MESH_WALLS as usize {
            return Err(Error::TooLarge {
                what: "mesh walls of a scene".into(),
                got: meshes.len() as u64,
                limit: MESH_WALLS as u64,
            });
        }
        Ok(Self { box_walls, meshes })
    }

    /// Refuses a mesh wall that moves more than [`MAX_WALL_STEP`] of the smallest radius
    /// `r_min` in one step of `dt`: spheres would pass through it.
    pub fn check_speed(&self, dt: f64, r_min: f32) -> Result<()> {
        for (k, wall) in self.meshes.iter().enumerate() {
            let speed = wall.top_speed();
            let limit = MAX_WALL_STEP * r_min as f64;
            if speed * dt > limit {
                return Err(Error::InvalidConfig {
                    what: format!("wall {k} ({})", wall.name),
                    reason: format!(
                        "moves at up to {speed:.4e} m/s (its velocity and turn), {:.4e} m in a \
                         step of {dt:.4e} s, more than {MAX_WALL_STEP} of the smallest radius \
                         ({r_min:.4e} m): spheres would pass through it; lower its speed or \
                         the time step (below {:.4e} s)",
                        speed * dt,
                        limit / speed
                    ),
                });
            }
        }
        Ok(())
    }

    /// Whether these are the box walls alone (what every backend runs).
    pub fn is_box_only(&self) -> bool {
        self.box_walls && self.meshes.is_empty()
    }

    /// Every mesh wall's pose at time `t` \[s\].
    pub fn poses_at(&self, t: f64) -> Vec<Pose> {
        self.meshes.iter().map(|m| m.motion.pose_at(t)).collect()
    }

    /// The triangles of every mesh wall where they are at time `t` \[s\], three corners each.
    pub fn triangles_at(&self, t: f64) -> Vec<[[f32; 3]; 3]> {
        self.meshes
            .iter()
            .flat_map(|m| m.triangles_at(&m.motion.pose_at(t)))
            .collect()
    }

    /// In words, for a run's summary line.
    pub fn describe(&self) -> String {
        let meshes = match self.meshes.len() {
            1 => "1 mesh wall".to_owned(),
            n => format!("{n} mesh walls"),
        };
        match self.box_walls {
            true => format!("box walls and {meshes}"),
            false => format!("{meshes}, no box walls"),
        }
    }
}

/// What the spheres did to one wall in a step: the force and the torque about its centre.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct WallLoad {
    /// Force on the wall \[N\].
    pub force: [f64; 3],
    /// Torque on the wall about its rotation centre \[N·m\].
    pub torque: [f64; 3],
}

impl WallLoad {
    /// Adds `other`.
    pub fn add(&mut self, other: &WallLoad) {
        for a in 0..3 {
            self.force[a] += other.force[a];
            self.torque[a] += other.torque[a];
        }
    }
}
