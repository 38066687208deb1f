//! A scene ready to render: the spheres in Morton order with their colours and the tree over
//! them, prepared once and shared by every render path.

use super::bvh::{self, Node};
use super::colour::colours;
use crate::error::{Error, Result};

/// Spheres to render, each with the colour of its value.
#[derive(Debug, Clone)]
pub struct Scene {
    /// `x, y, z, r` in Morton order of the centres.
    pub(crate) spheres: Vec<[f32; 4]>,
    /// Packed colour of each sphere (same order).
    pub(crate) colours: Vec<u32>,
    /// The tree over `spheres`.
    pub(crate) nodes: Vec<Node>,
    bounds: Option<([f64; 3], [f64; 3])>,
}

impl Scene {
    /// A scene of spheres at `positions` \[m\] with `radii` \[m\], each coloured by where its
    /// entry of `values` falls in `range` (viridis; values outside are clamped).
    ///
    /// Slices of different lengths, non-finite coordinates or radii that are not finite and
    /// positive are an [`Error`]; no spheres is a valid, empty scene.
    pub fn new(
        positions: &[[f32; 3]],
        radii: &[f32],
        values: &[f32],
        range: (f32, f32),
    ) -> Result<Scene> {
        if radii.len() != positions.len() || values.len() != positions.len() {
            return Err(Error::Usage(format!(
                "scene: {} positions, {} radii and {} values (must be equal)",
                positions.len(),
                radii.len(),
                values.len()
            )));
        }
        if positions.len() > u32::MAX as usize / 2 {
            return Err(Error::TooLarge {
                what: "spheres to render".into(),
                got: positions.len() as u64,
                limit: u32::MAX as u64 / 2,
            });
        }
        for (index, (p, &r)) in positions.iter().zip(radii).enumerate() {
            if !p.iter().all(|x| x.is_finite()) {
                return Err(Error::InvalidSphere {
                    index,
                    reason: format!("centre {p:?} is not finite"),
                });
            }
            if !(r.is_finite() && r > 0.0) {
                return Err(Error::InvalidSphere {
                    index,
                    reason: format!("radius {r} is not finite and positive"),
                });
            }
        }
        let xyzr: Vec<[f32; 4]> = positions
            .iter()
            .zip(radii)
            .map(|(p, &r)| [p[0], p[1], p[2], r])
            .collect();
        let (order, keys) = bvh::morton_order(&xyzr);
        let spheres: Vec<_> = order.iter().map(|&i| xyzr[i as usize]).collect();
        let all_colours = colours(values, range);
        let colours = order.iter().map(|&i| all_colours[i as usize]).collect();
        let nodes = bvh::build(&spheres, &keys);
        let bounds = nodes
            .first()
            .map(|root| (root.lo.map(f64::from), root.hi.map(f64::from)));
        Ok(Scene {
            spheres,
            colours,
            nodes,
            bounds,
        })
    }

    /// The number of spheres.
    pub fn len(&self) -> usize {
        self.spheres.len()
    }

    /// Whether the scene has no spheres.
    pub fn is_empty(&self) -> bool {
        self.spheres.is_empty()
    }

    /// The box around every sphere (`None` for an empty scene).
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        self.bounds
    }
}
