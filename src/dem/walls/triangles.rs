//! A wall's triangles in its rest geometry, with a bounding-volume hierarchy over them for the
//! query "which triangles come within a distance of this point", and the closest point of a
//! triangle (face, edge or vertex).

use glam::Vec3;

/// Triangles per leaf of the hierarchy at most.
const LEAF: usize = 4;

/// A node of the hierarchy: a box and either two children or a run of triangles.
#[derive(Debug, Clone, Copy)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    /// Leaf: the first triangle of its run in `order`; inner node: the second child (the
    /// first follows the node itself).
    index: u32,
    /// Triangles of a leaf; 0 for an inner node.
    count: u32,
}

/// One triangle, as the contact query needs it.
#[derive(Debug, Clone, Copy)]
pub struct Triangle {
    /// Corners.
    pub corners: [Vec3; 3],
    /// Unit normal, (b − a) × (c − a) normalized.
    pub normal: Vec3,
}

/// Triangles with a hierarchy over them. Degenerate triangles (no area) are left out: they
/// have no face and their edges belong to their neighbours.
#[derive(Debug, Clone)]
pub struct TriangleMesh {
    triangles: Vec<Triangle>,
    /// Triangle indices in the hierarchy's order.
    order: Vec<u32>,
    /// Nodes, depth first; the root is node 0 (none without triangles).
    nodes: Vec<Node>,
}

impl TriangleMesh {
    /// The triangles `triangles` (indices into `vertices`, in range) with their hierarchy.
    pub fn new(vertices: &[Vec3], triangles: &[[u32; 3]]) -> Self {
        let triangles: Vec<Triangle> = triangles
            .iter()
            .filter_map(|t| {
                let corners = t.map(|i| vertices[i as usize]);
                let [a, b, c] = corners;
                let normal = (b - a).cross(c - a).try_normalize()?;
                Some(Triangle { corners, normal })
            })
            .collect();
        let mut mesh = Self {
            order: (0..triangles.len() as u32).collect(),
            triangles,
            nodes: Vec::new(),
        };
        if !mesh.triangles.is_empty() {
            mesh.build(0, mesh.triangles.len());
        }
        mesh
    }

    /// The triangles (degenerate ones left out).
    pub fn triangles(&self) -> &[Triangle] {
        &self.triangles
    }

    /// Builds the subtree over `order[first..first + count]`, returns its node index.
    fn build(&mut self, first: usize, count: usize) -> u32 {
        let run = &mut self.order[first..first + count];
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for &t in run.iter() {
            for c in self.triangles[t as usize].corners {
                lo = lo.min(c);
                hi = hi.max(c);
            }
        }
        let at = self.nodes.len();
        self.nodes.push(Node {
            lo,
            hi,
            index: first as u32,
            count: count as u32,
        });
        if count <= LEAF {
            return at as u32;
        }
        // Median split of the centroids along the box's longest axis.
        let extent = hi - lo;
        let axis = if extent.x >= extent.y && extent.x >= extent.z {
            0
        } else if extent.y >= extent.z {
            1
        } else {
            2
        };
        let tris = &self.triangles;
        let key = |t: &u32| {
            let [a, b, c] = tris[*t as usize].corners;
            (a + b + c)[axis]
        };
        let half = count / 2;
        run.select_nth_unstable_by(half, |x, y| key(x).total_cmp(&key(y)));
        self.build(first, half);
        let second = self.build(first + half, count - half);
        self.nodes[at].index = second;
        self.nodes[at].count = 0;
        at as u32
    }

    /// Calls `visit` with every triangle whose bounding box comes within `reach` of `p`
    /// (a superset of the triangles within `reach`), in a fixed order.
    #[inline]
    pub fn for_each_near(&self, p: Vec3, reach: f32, mut visit: impl FnMut(&Triangle)) {
        if self.nodes.is_empty() {
            return;
        }
        // Median splits keep the depth near log2 of the triangles: 64 holds any mesh.
        let mut stack = [0u32; 64];
        let mut depth = 1;
        while depth > 0 {
            depth -= 1;
            let at = stack[depth];
            let node = self.nodes[at as usize];
            let gap = (node.lo - p).max(p - node.hi).max(Vec3::ZERO);
            if gap.length_squared() > reach * reach {
                continue;
            }
            if node.count > 0 {
                let run = node.index as usize..(node.index + node.count) as usize;
                for &t in &self.order[run] {
                    visit(&self.triangles[t as usize]);
                }
            } else {
                // The first child is visited first: pushed last.
                stack[depth] = node.index;
                stack[depth + 1] = at + 1;
                depth += 2;
            }
        }
    }
}

impl Triangle {
    /// The point of the triangle closest to `p`.
    ///
    /// The regions of the corners, then of the edges, then the face, by the signs of the
    /// barycentric coordinates (the classic Voronoi-region test); on the face the point is the
    /// projection along the unit normal, whose distance from `p` is then exact to rounding of
    /// `(p − a)·n`, whatever the triangle's size.
    #[inline]
    pub fn closest_point(&self, p: Vec3) -> Vec3 {
        let [a, b, c] = self.corners;
        let (ab, ac, ap) = (b - a, c - a, p - a);
        let (d1, d2) = (ab.dot(ap), ac.dot(ap));
        if d1 <= 0.0 && d2 <= 0.0 {
            return a;
        }
        let bp = p - b;
        let (d3, d4) = (ab.dot(bp), ac.dot(bp));
        if d3 >= 0.0 && d4 <= d3 {
            return b;
        }
        let vc = d1 * d4 - d3 * d2;
        if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            return a + ab * (d1 / (d1 - d3));
        }
        let cp = p - c;
        let (d5, d6) = (ab.dot(cp), ac.dot(cp));
        if d6 >= 0.0 && d5 <= d6 {
            return c;
        }
        let vb = d5 * d2 - d1 * d6;
        if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            return a + ac * (d2 / (d2 - d6));
        }
        let va = d3 * d6 - d5 * d4;
        if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
            let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            return b + (c - b) * w;
        }
        p - self.normal * ap.dot(self.normal)
    }
}
