//! Triangle meshes for the `mesh` scene: load one (OBJ, PLY, STL), fit it into a box, and fill
//! it with non-overlapping spheres on a jittered lattice.
//!
//! - [`Mesh`]: vertices and triangles, [`Mesh::bounds`], [`Mesh::fitted`]; [`torus`] makes a
//!   small watertight one, [`revolution`] a surface turned about an axis (cylinders, cones).
//! - [`load`]: reads `.obj`, `.ply` (ASCII and binary) and `.stl` (ASCII and binary);
//!   [`load_bytes`] the same from memory.
//! - [`winding_number`] and [`WindingTree`]: the generalized winding number, the inside test
//!   that tolerates holes (the Stanford bunny has open holes at its base).
//! - [`fill`] with a [`FillSpec`]: the lattice points inside the mesh, each with a radius drawn
//!   from a weighted mix and, optionally, a random offset that keeps it inside its own cell.
//!
//! ```
//! use mochi::mesh::{FillSpec, fill, torus};
//! let ring = torus(1.0, 0.4, 48, 24).fitted([0.0; 3], [1.0; 3]);
//! let radii = vec![(0.02, 1.0), (0.01, 1.0)]; // radius 0.02 or 0.01, equally likely
//! let spec = FillSpec { spacing: 0.05, radii, jitter: true, seed: 1 };
//! let (centers, radii) = fill(&ring, &spec)?;
//! assert_eq!(centers.len(), radii.len());
//! # Ok::<(), mochi::Error>(())
//! ```

mod fill;
mod load;
mod winding;

pub use fill::{FillSpec, MAX_LATTICE_POINTS, fill};
pub use load::{load, load_bytes};
pub use winding::{WindingTree, winding_number};

use crate::error::{Error, Result};
use glam::DVec3;
use std::f64::consts::TAU;

/// A triangle mesh: vertex positions and triangles as triples of vertex indices.
///
/// Triangles are oriented counter-clockwise seen from outside (outward normals), the usual
/// convention of the file formats; a mesh with every triangle reversed has winding number −1
/// inside and fills the same (see [`WindingTree::contains`]). The mesh need not be watertight.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions (any length unit; SI metres in the scenes).
    pub vertices: Vec<[f64; 3]>,
    /// Triangles, each three indices into `vertices`.
    pub triangles: Vec<[u32; 3]>,
}

/// What is wrong with a mesh, for [`Mesh::validate`] and the loaders.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Problem {
    /// No triangles at all.
    Empty,
    /// Vertex `.0` has a coordinate that is NaN or infinite.
    NonFinite(usize),
    /// Triangle `.0` refers to vertex `.1`, which does not exist.
    IndexOutOfRange(usize, u32),
}

impl Mesh {
    /// The axis-aligned box around all vertices, as `(lo, hi)`; `None` without vertices.
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        let first = *self.vertices.first()?;
        Some(self.vertices.iter().fold((first, first), |(lo, hi), v| {
            (
                std::array::from_fn(|a| lo[a].min(v[a])),
                std::array::from_fn(|a| hi[a].max(v[a])),
            )
        }))
    }

    /// This mesh scaled uniformly (aspect ratio kept) and moved so that its bounds are as large
    /// as fit in the box `[lo, hi]`, centred in it.
    ///
    /// The scale is the smallest ratio of box side to mesh extent over the axes along which the
    /// mesh has an extent; a mesh with no extent at all (a single point, or none) is only moved
    /// to the centre. A side with `hi < lo` counts as zero. Non-finite arguments give non-finite
    /// vertices, which [`Mesh::validate`] and [`fill`] reject.
    pub fn fitted(&self, lo: [f64; 3], hi: [f64; 3]) -> Mesh {
        let Some((m_lo, m_hi)) = self.bounds() else {
            return self.clone();
        };
        let (m_lo, m_hi) = (DVec3::from(m_lo), DVec3::from(m_hi));
        let (lo, hi) = (DVec3::from(lo), DVec3::from(hi));
        let (size, extent) = ((hi - lo).max(DVec3::ZERO), m_hi - m_lo);
        let scale = (0..3)
            .filter(|&a| extent[a] > 0.0)
            .map(|a| size[a] / extent[a])
            .fold(f64::INFINITY, f64::min);
        let scale = if scale.is_finite() { scale } else { 1.0 };
        let from = 0.5 * (m_lo + m_hi);
        let to = 0.5 * (lo + hi);
        Mesh {
            vertices: self
                .vertices
                .iter()
                .map(|&v| (to + scale * (DVec3::from(v) - from)).to_array())
                .collect(),
            triangles: self.triangles.clone(),
        }
    }

    /// Checks that the mesh can be filled: at least one triangle, every index in range, every
    /// coordinate finite. Errors are [`Error::InvalidConfig`].
    pub fn validate(&self) -> Result<()> {
        match self.problem() {
            None => Ok(()),
            Some(p) => Err(Error::InvalidConfig {
                what: "mesh".into(),
                reason: p.describe(),
            }),
        }
    }

    /// The first thing wrong with the mesh, if any.
    pub(crate) fn problem(&self) -> Option<Problem> {
        if self.triangles.is_empty() {
            return Some(Problem::Empty);
        }
        if let Some(i) = self
            .vertices
            .iter()
            .position(|v| v.iter().any(|x| !x.is_finite()))
        {
            return Some(Problem::NonFinite(i));
        }
        let n = self.vertices.len();
        self.triangles.iter().enumerate().find_map(|(t, tri)| {
            tri.iter()
                .find(|&&i| i as usize >= n)
                .map(|&i| Problem::IndexOutOfRange(t, i))
        })
    }
}

impl Problem {
    /// A sentence fragment for error messages.
    pub(crate) fn describe(&self) -> String {
        match *self {
            Problem::Empty => "no triangles".into(),
            Problem::NonFinite(v) => format!("vertex {v} has a non-finite coordinate"),
            Problem::IndexOutOfRange(t, i) => {
                format!("triangle {t} refers to vertex {i}, which does not exist")
            }
        }
    }
}

/// A watertight torus around the z axis, centred at the origin, with outward-facing triangles.
///
/// `major` is the distance from the centre to the middle of the tube, `minor` the tube's radius
/// (same unit); the tube is cut into `segments_around` rings of `segments_tube` vertices each
/// (each count at least 3; smaller counts are raised to 3). Its vertices lie on the exact torus,
/// so its volume approaches 2π²·major·minor² as the counts grow.
pub fn torus(major: f64, minor: f64, segments_around: u32, segments_tube: u32) -> Mesh {
    let (na, nt) = (segments_around.max(3), segments_tube.max(3));
    let mut vertices = Vec::with_capacity(na as usize * nt as usize);
    for i in 0..na {
        let u = TAU * f64::from(i) / f64::from(na);
        for j in 0..nt {
            let v = TAU * f64::from(j) / f64::from(nt);
            let rho = major + minor * v.cos();
            vertices.push([rho * u.cos(), rho * u.sin(), minor * v.sin()]);
        }
    }
    let index = |i: u32, j: u32| (i % na) * nt + (j % nt);
    let mut triangles = Vec::with_capacity(2 * vertices.len());
    for i in 0..na {
        for j in 0..nt {
            // Quad (i, j) → (i+1, j) → (i+1, j+1) → (i, j+1): counter-clockwise seen from
            // outside, since ∂/∂u × ∂/∂v points away from the tube's centre line.
            let (a, b, c, d) = (
                index(i, j),
                index(i + 1, j),
                index(i + 1, j + 1),
                index(i, j + 1),
            );
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    Mesh {
        vertices,
        triangles,
    }
}

/// The surface swept by the polyline `profile` of (distance from the z axis, height) points
/// turning once about the z axis, in `sides` steps (at least 3): a quad (two triangles) per
/// segment and step. A profile point on the axis gives triangles of zero area there, which
/// users of the mesh may drop.
pub fn revolution(profile: &[(f64, f64)], sides: u32) -> Mesh {
    let sides = sides.max(3);
    let rings = profile.len() as u32;
    let mut vertices = Vec::with_capacity((sides * rings) as usize);
    for k in 0..sides {
        let phi = TAU * f64::from(k) / f64::from(sides);
        for &(rho, z) in profile {
            vertices.push([rho * phi.cos(), rho * phi.sin(), z]);
        }
    }
    let index = |k: u32, j: u32| (k % sides) * rings + j;
    let mut triangles = Vec::new();
    for k in 0..sides {
        for j in 0..rings.saturating_sub(1) {
            let (a, b, c, d) = (
                index(k, j),
                index(k + 1, j),
                index(k + 1, j + 1),
                index(k, j + 1),
            );
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    Mesh {
        vertices,
        triangles,
    }
}
