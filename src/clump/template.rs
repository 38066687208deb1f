//! A clump's shape: component spheres in the body frame, and the mass properties of their union
//! (overlaps counted once).
//!
//! The union is integrated column by column: the template's bounding box is cut into square
//! columns along z, in each the spheres' chords are merged into disjoint intervals and
//! integrated exactly in z (length, first and second moments), and the columns are summed by
//! the midpoint rule in x and y (each column's x² and y² with its width's h²/12 added). The
//! error is the midpoint rule's at the union's outline, under 1e-4 of the volume and the
//! moments at the default resolution (tests/clumps.rs checks a sphere, overlapping and
//! touching dimers against their closed forms).

use crate::error::{Error, Result};
use glam::{DMat3, DVec3};

/// One component sphere of a clump, in the body frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Component {
    /// Centre in the body frame \[m\].
    pub centre: DVec3,
    /// Radius \[m\].
    pub radius: f64,
}

/// A clump's shape: its name and its component spheres.
#[derive(Debug, Clone, PartialEq)]
pub struct ClumpTemplate {
    /// What scenes call it.
    pub name: String,
    /// The component spheres, in the body frame.
    pub components: Vec<Component>,
}

/// What a template's shape gives at unit density: the union's volume, its centre, and its
/// principal moments of inertia with their axes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassProperties {
    /// Volume of the union \[m³\] (the mass at unit density).
    pub volume: f64,
    /// Centre of the union (of mass, at uniform density) in the template's frame \[m\].
    pub centre: DVec3,
    /// The inertia tensor about `centre` at unit density, in the template's frame \[m⁵\].
    pub inertia: DMat3,
    /// The principal moments at unit density, smallest first \[m⁵\].
    pub moments: DVec3,
    /// The principal axes as the columns of a rotation (determinant 1), in the order of
    /// `moments`: a vector's principal coordinates p give `axes * p` in the template's frame.
    pub axes: DMat3,
}

impl MassProperties {
    /// These properties with the inertia tensor `inertia` \[m⁵\] (at unit density, about
    /// `centre`, in the template's frame) in place of the union's, and its principal moments
    /// and axes: a grain whose spheres only approximate its shape keeps its own inertia.
    pub fn with_inertia(self, inertia: DMat3) -> Self {
        let (moments, axes) = principal(&inertia);
        Self {
            inertia,
            moments,
            axes,
            ..self
        }
    }
}

/// Columns along the longer side of the bounding box's base in [`ClumpTemplate::mass_properties`].
pub const DEFAULT_COLUMNS: usize = 600;

impl ClumpTemplate {
    /// The template `name` of `components`, refused where there is none or one has a centre
    /// that is not finite or a radius that is not positive and finite.
    pub fn new(name: &str, components: Vec<Component>) -> Result<Self> {
        let bad = |reason: String| {
            Err(Error::InvalidConfig {
                what: format!("clump \"{name}\""),
                reason,
            })
        };
        if components.is_empty() {
            return bad("has no component spheres".into());
        }
        for (k, c) in components.iter().enumerate() {
            if !(c.centre.is_finite() && c.radius.is_finite() && c.radius > 0.0) {
                return bad(format!(
                    "component {k} has centre {:?} and radius {}: a finite centre and a \
                     positive radius are needed",
                    c.centre.to_array(),
                    c.radius
                ));
            }
        }
        Ok(Self {
            name: name.into(),
            components,
        })
    }

    /// The mass properties of the union of the components at unit density, integrated with
    /// [`DEFAULT_COLUMNS`] columns.
    pub fn mass_properties(&self) -> MassProperties {
        self.mass_properties_with(DEFAULT_COLUMNS)
    }

    /// [`mass_properties`](Self::mass_properties) with `columns` columns along the longer side
    /// of the bounding box's base.
    pub fn mass_properties_with(&self, columns: usize) -> MassProperties {
        let lo = self
            .components
            .iter()
            .map(|c| c.centre - DVec3::splat(c.radius))
            .fold(DVec3::INFINITY, DVec3::min);
        let hi = self
            .components
            .iter()
            .map(|c| c.centre + DVec3::splat(c.radius))
            .fold(DVec3::NEG_INFINITY, DVec3::max);
        let h = (hi.x - lo.x).max(hi.y - lo.y) / columns.max(1) as f64;
        let (nx, ny) = (
            ((hi.x - lo.x) / h).ceil() as usize,
            ((hi.y - lo.y) / h).ceil() as usize,
        );
        let area = h * h;
        // Sums over the columns: volume, first moments, second moments x², y², z², xy, xz, yz.
        let mut volume = 0.0;
        let mut first = DVec3::ZERO;
        let (mut xx, mut yy, mut zz, mut xy, mut xz, mut yz) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let mut chords: Vec<(f64, f64)> = Vec::with_capacity(self.components.len());
        for i in 0..nx {
            let x = lo.x + (i as f64 + 0.5) * h;
            for j in 0..ny {
                let y = lo.y + (j as f64 + 0.5) * h;
                chords.clear();
                for c in &self.components {
                    let (dx, dy) = (x - c.centre.x, y - c.centre.y);
                    let half2 = c.radius * c.radius - dx * dx - dy * dy;
                    if half2 > 0.0 {
                        let half = half2.sqrt();
                        chords.push((c.centre.z - half, c.centre.z + half));
                    }
                }
                if chords.is_empty() {
                    continue;
                }
                // The union of the chords: ∫dz, ∫z dz, ∫z² dz over it.
                chords.sort_by(|a, b| a.0.total_cmp(&b.0));
                let (mut length, mut z1, mut z2) = (0.0, 0.0, 0.0);
                let mut open = chords[0];
                for &(a, b) in chords[1..].iter().chain([&(f64::INFINITY, f64::INFINITY)]) {
                    if a <= open.1 {
                        open.1 = open.1.max(b);
                        continue;
                    }
                    let (s, t) = open;
                    length += t - s;
                    z1 += (t * t - s * s) / 2.0;
                    z2 += (t * t * t - s * s * s) / 3.0;
                    open = (a, b);
                }
                volume += area * length;
                first += area * DVec3::new(x * length, y * length, z1);
                // A column's x² over its width: x_c² + h²/12 (the same for y).
                xx += area * (x * x + h * h / 12.0) * length;
                yy += area * (y * y + h * h / 12.0) * length;
                zz += area * z2;
                xy += area * x * y * length;
                xz += area * x * z1;
                yz += area * y * z1;
            }
        }
        let centre = first / volume;
        // Second moments about the centre (parallel axes), then the inertia tensor
        // I = ∫(|r|²·1 − r rᵀ) dV.
        let c = centre;
        let sxx = xx - volume * c.x * c.x;
        let syy = yy - volume * c.y * c.y;
        let szz = zz - volume * c.z * c.z;
        let sxy = xy - volume * c.x * c.y;
        let sxz = xz - volume * c.x * c.z;
        let syz = yz - volume * c.y * c.z;
        let inertia = DMat3::from_cols(
            DVec3::new(syy + szz, -sxy, -sxz),
            DVec3::new(-sxy, sxx + szz, -syz),
            DVec3::new(-sxz, -syz, sxx + syy),
        );
        let (moments, axes) = principal(&inertia);
        MassProperties {
            volume,
            centre,
            inertia,
            moments,
            axes,
        }
    }

    /// This template in its principal frame: the components moved so that the union's centre
    /// is the origin and its principal axes (smallest moment first) are x, y and z; with the
    /// mass properties there (`inertia` diagonal, `axes` the identity).
    pub fn in_principal_frame(&self) -> (ClumpTemplate, MassProperties) {
        self.moved_to_principal_frame(&self.mass_properties())
    }

    /// [`in_principal_frame`](Self::in_principal_frame) with the template's mass properties
    /// `m` (its [`mass_properties`](Self::mass_properties)) given.
    pub fn moved_to_principal_frame(&self, m: &MassProperties) -> (ClumpTemplate, MassProperties) {
        let to_principal = m.axes.transpose();
        let components = self
            .components
            .iter()
            .map(|c| Component {
                centre: to_principal * (c.centre - m.centre),
                radius: c.radius,
            })
            .collect();
        let moved = ClumpTemplate {
            name: self.name.clone(),
            components,
        };
        let properties = MassProperties {
            centre: DVec3::ZERO,
            inertia: DMat3::from_diagonal(m.moments),
            axes: DMat3::IDENTITY,
            ..*m
        };
        (moved, properties)
    }
}

/// The eigenvalues of the symmetric `inertia` (smallest first) and its eigenvectors as the
/// columns of a rotation (a right-handed frame).
fn principal(inertia: &DMat3) -> (DVec3, DMat3) {
    let m = nalgebra::Matrix3::from_fn(|r, c| inertia.col(c)[r]);
    let eigen = nalgebra::SymmetricEigen::new(m);
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| eigen.eigenvalues[a].total_cmp(&eigen.eigenvalues[b]));
    let column = |k: usize| {
        let v = eigen.eigenvectors.column(order[k]);
        DVec3::new(v[0], v[1], v[2]).normalize()
    };
    let (a, b) = (column(0), column(1));
    // The third axis completes a right-handed frame (the eigenvector up to its sign).
    let axes = DMat3::from_cols(a, b, a.cross(b));
    let moments = DVec3::new(
        eigen.eigenvalues[order[0]],
        eigen.eigenvalues[order[1]],
        eigen.eigenvalues[order[2]],
    );
    (moments, axes)
}
