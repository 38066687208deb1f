//! A scene ready to render: the spheres in Morton order with their colours and the tree over
//! them, and the mesh walls' triangles with a tree of their own, prepared once and shared by
//! every render path.

use super::bvh::{self, Node};
use super::colour::colours;
use crate::error::{Error, Result};
use glam::Vec3;
use rayon::slice::ParallelSliceMut;

/// Spheres to render, each with the colour of its value.
#[derive(Debug, Clone)]
pub struct Scene {
    /// `x, y, z, r` in Morton order of the centres.
    pub(crate) spheres: Vec<[f32; 4]>,
    /// Packed colour of each sphere (same order).
    pub(crate) colours: Vec<u32>,
    /// The tree over `spheres`.
    pub(crate) nodes: Vec<Node>,
    /// The walls' triangles, three corners `x, y, z, 0` each, in the order of `wall_nodes`.
    pub(crate) walls: Vec<[f32; 4]>,
    /// The tree over the triangles of `walls`.
    pub(crate) wall_nodes: Vec<Node>,
    bounds: Option<([f64; 3], [f64; 3])>,
}

impl Scene {
    /// A scene of spheres at `positions` \[m\] with `radii` \[m\], each coloured by where its
    /// entry of `values` falls in `range` (viridis; values outside are clamped).
    ///
    /// Slices of different lengths, non-finite coordinates or radii that are not finite and
    /// positive are an [`Error`]; no spheres is a valid, empty scene. Of spheres whose centres
    /// share a cell of side a thousandth of the smallest radius only the largest (the first in
    /// input order among equals) is drawn: the others lie inside it but for less than that
    /// share of their radius, and boxes so alike would make every ray through them visit each
    /// one on every path.
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
        let shown = outermost(positions, radii);
        let xyzr: Vec<[f32; 4]> = shown
            .iter()
            .map(|&i| {
                let (p, r) = (positions[i as usize], radii[i as usize]);
                [p[0], p[1], p[2], r]
            })
            .collect();
        let (order, keys) = bvh::morton_order(&xyzr);
        let all_colours = colours(values, range);
        let mut items: Vec<([f32; 4], u32)> = order
            .iter()
            .map(|&k| (xyzr[k as usize], all_colours[shown[k as usize] as usize]))
            .collect();
        let nodes = bvh::build(&mut items, &keys);
        let (spheres, colours) = items.into_iter().unzip();
        let bounds = nodes
            .first()
            .map(|root| (root.lo.map(f64::from), root.hi.map(f64::from)));
        Ok(Scene {
            spheres,
            colours,
            nodes,
            walls: Vec::new(),
            wall_nodes: Vec::new(),
            bounds,
        })
    }

    /// This scene with mesh walls, the triangles `triangles` (three corners each \[m\]), drawn
    /// as a translucent skin over what lies behind them; a corner that is not finite is an
    /// [`Error`].
    pub fn with_walls(mut self, triangles: &[[[f32; 3]; 3]]) -> Result<Scene> {
        if let Some(k) = triangles
            .iter()
            .position(|t| !t.as_flattened().iter().all(|x| x.is_finite()))
        {
            return Err(Error::Usage(format!(
                "wall triangle {k} has a corner that is not finite: {:?}",
                triangles[k]
            )));
        }
        if triangles.len() > u32::MAX as usize / 6 {
            return Err(Error::TooLarge {
                what: "wall triangles to render".into(),
                got: triangles.len() as u64,
                limit: u32::MAX as u64 / 6,
            });
        }
        // Each triangle enters the tree by its bounding sphere (centroid, farthest corner).
        let around = |t: &[[f32; 3]; 3]| {
            let c = t.iter().map(|&p| Vec3::from(p)).sum::<Vec3>() / 3.0;
            let r = t
                .iter()
                .map(|&p| Vec3::from(p).distance(c))
                .fold(0.0f32, f32::max);
            [c.x, c.y, c.z, r]
        };
        let spheres: Vec<[f32; 4]> = triangles.iter().map(around).collect();
        let (order, keys) = bvh::morton_order(&spheres);
        let mut items: Vec<([f32; 4], [[f32; 3]; 3])> = order
            .iter()
            .map(|&k| (spheres[k as usize], triangles[k as usize]))
            .collect();
        self.wall_nodes = bvh::build(&mut items, &keys);
        self.walls = items
            .iter()
            .flat_map(|(_, t)| t.map(|p| [p[0], p[1], p[2], 0.0]))
            .collect();
        let walls = self
            .wall_nodes
            .first()
            .map(|root| (root.lo.map(f64::from), root.hi.map(f64::from)));
        self.bounds = match (self.bounds, walls) {
            (Some((lo, hi)), Some((wlo, whi))) => Some((
                std::array::from_fn(|a| lo[a].min(wlo[a])),
                std::array::from_fn(|a| hi[a].max(whi[a])),
            )),
            (spheres, walls) => spheres.or(walls),
        };
        Ok(self)
    }

    /// The number of wall triangles drawn.
    pub fn wall_triangles(&self) -> usize {
        self.walls.len() / 3
    }

    /// The number of spheres drawn (see [`Scene::new`] for those left out).
    pub fn len(&self) -> usize {
        self.spheres.len()
    }

    /// Whether the scene has no spheres.
    pub fn is_empty(&self) -> bool {
        self.spheres.is_empty()
    }

    /// The box around every sphere and wall (`None` for an empty scene).
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        self.bounds
    }
}

/// Side of the cells within which only the largest sphere is drawn, as a share of the smallest
/// radius: a sphere left out sticks out of the one drawn by less than √3 of it, far below a
/// pixel unless a picture spans less than a thousandth of a sphere.
const MERGED_SHARE: f64 = 1e-3;

/// Input indices (ascending) of the spheres drawn: of each group whose centres share a cell of
/// side [`MERGED_SHARE`] of the smallest radius, the largest, the first in input order among
/// equal radii.
fn outermost(positions: &[[f32; 3]], radii: &[f32]) -> Vec<u32> {
    let r_min = radii.iter().copied().fold(f32::INFINITY, f32::min);
    let side = MERGED_SHARE * r_min as f64;
    // The cell of a centre, as the bits of its floored coordinates (−0 read as +0).
    let centre =
        |i: u32| positions[i as usize].map(|x| ((x as f64 / side).floor() + 0.0).to_bits());
    let mut by_centre: Vec<u32> = (0..positions.len() as u32).collect();
    by_centre.par_sort_unstable_by(|&a, &b| {
        centre(a)
            .cmp(&centre(b))
            .then(radii[b as usize].total_cmp(&radii[a as usize]))
            .then(a.cmp(&b))
    });
    let mut shown: Vec<u32> = by_centre
        .chunk_by(|&a, &b| centre(a) == centre(b))
        .map(|group| group[0])
        .collect();
    shown.par_sort_unstable();
    shown
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spheres_sharing_a_centre_are_drawn_once_as_the_largest() {
        // 10,000 spheres at the origin (the largest, 0.5, twice), two elsewhere.
        let n = 10_000;
        let mut positions = vec![[0.0f32; 3]; n];
        let mut radii: Vec<f32> = (0..n).map(|k| 0.1 + (k % 7) as f32 * 0.05).collect();
        radii[4000] = 0.5;
        radii[6000] = 0.5;
        positions[5] = [-0.0, 0.0, 0.0];
        positions.extend([[2.0, 0.0, 0.0], [0.0, 2.0, 0.0]]);
        radii.extend([0.1, 0.1]);
        let values: Vec<f32> = (0..n + 2).map(|k| k as f32).collect();
        let scene = Scene::new(&positions, &radii, &values, (0.0, (n + 1) as f32)).unwrap();
        assert_eq!(scene.len(), 3);
        // The tree over three spheres is one leaf: no ray visits more than one node.
        assert_eq!(scene.nodes.len(), 1);
        let at_origin = scene
            .spheres
            .iter()
            .position(|s| s[..3] == [0.0; 3])
            .unwrap();
        assert_eq!(scene.spheres[at_origin][3], 0.5);
        let colour_of_4000 = colours(&values, (0.0, (n + 1) as f32))[4000];
        assert_eq!(scene.colours[at_origin], colour_of_4000);
    }

    #[test]
    fn spheres_within_a_thousandth_of_a_radius_are_drawn_as_few() {
        // 100,000 spheres of r = 0.01 within 1e-6 of a point, and a lattice of spheres 2r apart.
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let mut positions: Vec<[f32; 3]> = (0..100_000)
            .map(|_| std::array::from_fn(|_| 0.5 + rng.random_range(-1e-6..1e-6f32)))
            .collect();
        let lattice =
            (0..10).flat_map(|i| (0..10).map(move |j| [0.02 * i as f32, 0.02 * j as f32, 0.0]));
        positions.extend(lattice);
        let radii = vec![0.01f32; positions.len()];
        let values = vec![0.0; positions.len()];
        let scene = Scene::new(&positions, &radii, &values, (0.0, 1.0)).unwrap();
        // At most one per cell the cluster touches (8 at most), and every lattice sphere.
        assert!(
            scene.len() <= 8 + 100 && scene.len() > 100,
            "{}",
            scene.len()
        );
    }
}
