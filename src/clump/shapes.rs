//! Built-in clump templates: the common shapes of multi-sphere DEM (dimers, trimers, tetrahedra,
//! rods) and a grain of any shape from a closed mesh filled with spheres.

use super::template::{ClumpTemplate, Component};
use crate::error::{Error, Result};
use crate::mesh::{FillSpec, Mesh, fill};
use glam::DVec3;

/// Spheres of radius `r` at `centres` (in units of r).
fn of_radius(name: &str, r: f64, centres: &[DVec3]) -> Result<ClumpTemplate> {
    let components = centres
        .iter()
        .map(|&c| Component {
            centre: c * r,
            radius: r,
        })
        .collect();
    ClumpTemplate::new(name, components)
}

impl ClumpTemplate {
    /// `dimer`: two spheres of radius `r` whose centres are r apart along x (the grain is 3r
    /// long and 2r wide).
    pub fn dimer(r: f64) -> Result<Self> {
        of_radius("dimer", r, &[DVec3::X * -0.5, DVec3::X * 0.5])
    }

    /// `trimer`: three spheres of radius `r` at the corners of an equilateral triangle of side
    /// r in the xy plane.
    pub fn trimer(r: f64) -> Result<Self> {
        let corner = |k: f64| {
            let a = k * 2.0 * std::f64::consts::PI / 3.0;
            DVec3::new(a.cos(), a.sin(), 0.0) / 3f64.sqrt()
        };
        of_radius("trimer", r, &[corner(0.0), corner(1.0), corner(2.0)])
    }

    /// `tetrahedron`: four spheres of radius `r` at the corners of a regular tetrahedron of edge
    /// r.
    pub fn tetrahedron(r: f64) -> Result<Self> {
        // Alternate corners of a cube of side 1/√2: edges of 1.
        let s = 0.5 / 2f64.sqrt();
        let corners = [
            DVec3::new(s, s, s),
            DVec3::new(s, -s, -s),
            DVec3::new(-s, s, -s),
            DVec3::new(-s, -s, s),
        ];
        of_radius("tetrahedron", r, &corners)
    }

    /// `rod N`: `n` spheres of radius `r` in a line along x, r apart (the grain is (n + 1)·r
    /// long); refused for no sphere.
    pub fn rod(n: usize, r: f64) -> Result<Self> {
        let middle = (n as f64 - 1.0) / 2.0;
        let centres: Vec<DVec3> = (0..n).map(|k| DVec3::X * (k as f64 - middle)).collect();
        of_radius(&format!("rod {n}"), r, &centres)
    }

    /// `from_mesh`: the closed `mesh` filled with spheres of radius `spacing`/2 on a cubic
    /// lattice of `spacing` (touching, each inside the mesh at its centre: the mesh filler,
    /// [`fill`]), named `name`; refused where no sphere fits.
    pub fn from_mesh(name: &str, mesh: &Mesh, spacing: f64) -> Result<Self> {
        let spec = FillSpec {
            spacing,
            radii: vec![((spacing / 2.0) as f32, 1.0)],
            jitter: false,
            seed: 0,
        };
        let (centres, radii) = fill(mesh, &spec)?;
        if centres.is_empty() {
            return Err(Error::InvalidConfig {
                what: format!("clump \"{name}\""),
                reason: format!(
                    "no sphere of the fill (spacing {spacing} m) lies inside its mesh: choose a \
                     smaller spacing"
                ),
            });
        }
        let components = centres
            .iter()
            .zip(&radii)
            .map(|(c, &r)| Component {
                centre: DVec3::from_array(c.map(f64::from)),
                radius: r as f64,
            })
            .collect();
        ClumpTemplate::new(name, components)
    }
}
