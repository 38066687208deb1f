//! Filling a mesh with non-overlapping spheres on a jittered lattice.

use super::{Mesh, WindingTree};
use crate::error::{Error, Result};
use crate::spheres::MAX_MAGNITUDE;
use glam::DVec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;

/// Largest number of lattice points a fill may visit (those of the lattice over the mesh's
/// bounding box, inside or not): 2²⁷ ≈ 134 million, several GiB of spheres. A larger fill is
/// refused with [`Error::TooLarge`]; raise the spacing.
pub const MAX_LATTICE_POINTS: u64 = 1 << 27;

/// How to fill a mesh: lattice spacing, the radius mix, jitter and seed.
#[derive(Debug, Clone, PartialEq)]
pub struct FillSpec {
    /// Distance between neighbouring lattice points, the side of each sphere's own cubic cell
    /// \[m\]; finite and > 0. The paper's bunny uses 2.2·r with r = 0.005.
    pub spacing: f64,
    /// The radius mix: `(radius \[m\], weight)` pairs; each sphere's radius is drawn with
    /// probability weight / Σ weights, e.g. `[(r, 1.0), (r / 2.0, 1.0)]`. Not empty; radii
    /// finite, > 0 and at most `spacing / 2` (compared in `f32`); weights finite and > 0.
    pub radii: Vec<(f32, f64)>,
    /// Move each centre by a random offset, uniform within ±(spacing/2 − r) per axis, so that
    /// the sphere stays inside its own lattice cell. Without it centres sit on the lattice.
    pub jitter: bool,
    /// Seed of the random generator (radii and offsets): the same seed gives the same spheres,
    /// on any number of threads.
    pub seed: u64,
}

/// [`Error::InvalidConfig`] of the mesh fill.
fn fill_error(reason: String) -> Error {
    Error::InvalidConfig {
        what: "mesh fill".into(),
        reason,
    }
}

impl FillSpec {
    /// Checks the spec; errors are [`Error::InvalidConfig`] naming the offending value.
    pub fn validate(&self) -> Result<()> {
        let s = self.spacing;
        if !(s.is_finite() && s > 0.0) {
            return Err(fill_error(format!(
                "fill spacing must be finite and > 0, got {s}"
            )));
        }
        if self.radii.is_empty() {
            return Err(fill_error("fill radius mix is empty".into()));
        }
        for &(r, w) in &self.radii {
            if !(r.is_finite() && r > 0.0) {
                return Err(fill_error(format!(
                    "fill radius must be finite and > 0, got {r}"
                )));
            }
            // Compared in f32, the radii's precision: r = 0.05 fits a spacing of 0.1.
            if 2.0 * r > s as f32 {
                return Err(fill_error(format!(
                    "fill radius {r} does not fit its lattice cell: 2·r = {} > spacing {s}",
                    2.0 * r
                )));
            }
            if !(w.is_finite() && w > 0.0) {
                return Err(fill_error(format!(
                    "weight of fill radius {r} must be finite and > 0, got {w}"
                )));
            }
        }
        let total: f64 = self.radii.iter().map(|&(_, w)| w).sum();
        if !total.is_finite() {
            return Err(fill_error(format!(
                "fill radius weights must have a finite sum, got {total}"
            )));
        }
        Ok(())
    }
}

/// Least volume a mesh to fill encloses, as a share of its bounding box's.
const MIN_VOLUME_SHARE: f64 = 1e-6;

/// Refuses a mesh that encloses no volume (its bounds `lo..hi`): one whose triangles all have
/// zero area, a flat one, or one whose signed volume is nil next to its bounding box's (an open
/// sheet), which would be filled only where its winding numbers happen to reach ½ beside it.
fn check_encloses_volume(mesh: &Mesh, lo: [f64; 3], hi: [f64; 3]) -> Result<()> {
    let corners = |t: &[u32; 3]| t.map(|i| DVec3::from_array(mesh.vertices[i as usize]));
    let (area, volume) = mesh.triangles.iter().fold((0.0, 0.0), |(area, volume), t| {
        let [a, b, c] = corners(t);
        let normal = (b - a).cross(c - a);
        (
            area + 0.5 * normal.length(),
            volume + a.dot(b.cross(c)) / 6.0,
        )
    });
    let extent = DVec3::from(hi) - DVec3::from(lo);
    let boxed = extent.x * extent.y * extent.z;
    let reason = if area == 0.0 {
        "every triangle has zero area".to_owned()
    } else if boxed == 0.0 {
        format!("the mesh is flat (its bounds {lo:?} .. {hi:?} have no thickness)")
    } else if volume.abs() < MIN_VOLUME_SHARE * boxed {
        format!(
            "the mesh encloses no volume (signed volume {volume:e} within a bounding box of \
             {boxed:e}): an open sheet"
        )
    } else {
        return Ok(());
    };
    Err(fill_error(format!(
        "{reason}; a mesh to fill must be a closed surface"
    )))
}

/// The lattice over the mesh's bounding box: `n` points per axis, centred on the box.
struct Lattice {
    origin: DVec3,
    spacing: f64,
    n: [usize; 3],
}

impl Lattice {
    fn over(lo: DVec3, hi: DVec3, spacing: f64) -> Result<Self> {
        let counts = ((hi - lo) / spacing).ceil().max(DVec3::ONE);
        let total = counts.x * counts.y * counts.z;
        if total > MAX_LATTICE_POINTS as f64 {
            return Err(Error::TooLarge {
                what: format!(
                    "lattice points of a mesh fill at spacing {spacing} (a {} × {} × {} lattice; \
                     raise the spacing)",
                    counts.x, counts.y, counts.z
                ),
                got: total as u64,
                limit: MAX_LATTICE_POINTS,
            });
        }
        let n = counts.to_array().map(|c| c as usize);
        let origin = 0.5 * (lo + hi) - 0.5 * counts * spacing;
        let lattice = Self { origin, spacing, n };
        let far = origin
            .abs()
            .max((origin + counts * spacing).abs())
            .max_element();
        if far > f64::from(MAX_MAGNITUDE) {
            return Err(fill_error(format!(
                "mesh coordinates reach {far:e}, beyond the limit of {MAX_MAGNITUDE:e} for \
                 sphere centres"
            )));
        }
        Ok(lattice)
    }

    fn point(&self, i: usize, j: usize, k: usize) -> DVec3 {
        let index = DVec3::new(i as f64, j as f64, k as f64);
        self.origin + (index + 0.5) * self.spacing
    }
}

/// Fills `mesh` with spheres: one per lattice point (spacing `spec.spacing`, lattice centred on
/// the mesh's bounding box) whose generalized winding number is at least ½ in magnitude
/// ([`WindingTree::contains`]), so small holes in the mesh do not matter. Each sphere gets a radius drawn from the mix and, with `spec.jitter`, a
/// random offset that keeps it inside its own cell, so no two spheres overlap (up to the
/// rounding of centres to `f32`). Returns centres and radii in lattice order (x fastest, then
/// y, then z); empty when no lattice point is inside.
///
/// The inside test is decided at the lattice point, before the offset: a sphere near the
/// surface may stick out of the mesh by up to its cell's half-diagonal.
///
/// Errors: [`Error::InvalidConfig`] for an invalid spec ([`FillSpec::validate`]) or mesh
/// ([`Mesh::validate`]) or one whose coordinates exceed [`crate::MAX_MAGNITUDE`];
/// [`Error::TooLarge`] when the lattice over the bounding box would have more than
/// [`MAX_LATTICE_POINTS`] points.
pub fn fill(mesh: &Mesh, spec: &FillSpec) -> Result<(Vec<[f32; 3]>, Vec<f32>)> {
    spec.validate()?;
    mesh.validate()?;
    let Some((lo, hi)) = mesh.bounds() else {
        return Ok((Vec::new(), Vec::new()));
    };
    check_encloses_volume(mesh, lo, hi)?;
    let lattice = Lattice::over(lo.into(), hi.into(), spec.spacing)?;
    let tree = WindingTree::new(mesh);
    let [nx, ny, nz] = lattice.n;
    // One row of x per task: indices of the inside points, in order.
    let rows: Vec<Vec<u32>> = (0..ny * nz)
        .into_par_iter()
        .map(|row| {
            let (j, k) = (row % ny, row / ny);
            (0..nx)
                .filter(|&i| tree.contains(lattice.point(i, j, k).to_array()))
                .map(|i| i as u32)
                .collect()
        })
        .collect();

    let count: usize = rows.iter().map(Vec::len).sum();
    let mut centers = Vec::with_capacity(count);
    let mut radii = Vec::with_capacity(count);
    let mut rng = Pcg64::seed_from_u64(spec.seed);
    let cumulative: Vec<f64> = spec
        .radii
        .iter()
        .scan(0.0, |sum, &(_, w)| {
            *sum += w;
            Some(*sum)
        })
        .collect();
    let total_weight = cumulative.last().copied().unwrap_or(0.0);
    for (row, inside) in rows.iter().enumerate() {
        let (j, k) = (row % ny, row / ny);
        for &i in inside {
            let r = if spec.radii.len() == 1 {
                spec.radii[0].0
            } else {
                let u: f64 = rng.random_range(0.0..total_weight);
                let pick = cumulative
                    .iter()
                    .position(|&c| u < c)
                    .unwrap_or(spec.radii.len() - 1);
                spec.radii[pick].0
            };
            let p = lattice.point(i as usize, j, k);
            let room = (0.5 * spec.spacing - f64::from(r)).max(0.0);
            let c = if spec.jitter && room > 0.0 {
                // x, then y, then z: the order the seed's draws are taken in.
                p + DVec3::from_array(std::array::from_fn(|_| rng.random_range(-room..=room)))
            } else {
                p
            };
            centers.push(c.as_vec3().to_array());
            radii.push(r);
        }
    }
    Ok((centers, radii))
}
