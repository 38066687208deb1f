//! The bounding-volume hierarchy of the `wgpu-compute` and `cpu` render paths: built on the CPU
//! over the spheres in Morton order (a top-down LBVH: each range splits where its highest
//! differing Morton bit flips, a range of equal keys at the median of its widest axis),
//! flattened depth first, and traversed nearest child first with a small stack. The mesh walls'
//! triangles get a tree of their own, built the same way over each triangle's bounding sphere.
//! [`trace`] is the CPU twin of `walk` in `wgsl/render/render_common.wgsl`.
//!
//! Each node bounds its primitives by a box and, where that is tighter (a small ball in its box,
//! [`BALL_TO_BOX`]), by a ball as well; a ray enters it where it is inside both. Boxes alone
//! fail heavily overlapping spheres: around a cluster of spheres whose centres nearly coincide
//! every box is nearly the same, and a ray enters each of them well before it meets any sphere
//! (near the box's corners), so it would test every sphere of the cluster; the balls are nearly
//! the spheres themselves, and a ray enters a ball no earlier than the spread of its centres
//! before the nearest sphere in it. A leaf's ball is around its spheres, an interior node's
//! around its children's balls.

use super::shade::{INF, hit_sphere};
use crate::gpu::shader::{SharedStruct, Vec3f, shared_struct};
use crate::morton;
use glam::Vec3;

/// Most spheres in one leaf.
const LEAF_SIZE: usize = 4;

/// Deepest the traversal stack may grow; keep in sync with `STACK` in `wgsl/render/render_common.wgsl`.
pub(crate) const STACK: usize = 64;

/// Relative widening of a node's ball per unit of the ray's distance from its centre, as
/// [`enter`] applies it: it covers the rounding of the ray–ball test and of the primitives'
/// own tests, so a ray that hits a primitive always enters the balls around it first (a search
/// of random grazing rays past spheres of every size and spread found a quarter of it enough and
/// an eighth too little). Keep in sync with `BALL_SLACK` in `wgsl/render/render_common.wgsl`.
const BALL_SLACK: f32 = 1.0 / 1_048_576.0;

/// Largest ratio of a node's ball's volume to its box's at which the traversal tests the ball
/// too: about a sphere's in its own box (π/6) and below, as around spheres that nearly coincide.
/// A ball larger than that (around spheres side by side, or a flat wall) would rarely cut off
/// what the box lets through, and only add its test.
const BALL_TO_BOX: f64 = 0.6;

/// One node of the flattened tree. An interior node (`count == 0`) has its left child right
/// after it and its right child at `a`; a leaf holds the spheres `a..a + count`. Every
/// primitive below it lies inside the box `lo..hi`, and where `radius >= 0` inside the ball of
/// centre `centre` and radius `radius` (a negative radius: no ball to test, see
/// [`BALL_TO_BOX`]).
///
/// WGSL twin: `Node` in `wgsl/render/render_common.wgsl` (uploaded as a storage array).
#[derive(Debug, Clone, Copy, PartialEq, encase::ShaderType)]
pub(crate) struct Node {
    pub lo: Vec3f,
    pub a: u32,
    pub hi: Vec3f,
    pub count: u32,
    pub centre: Vec3f,
    pub radius: f32,
}

/// [`Node`] as a [`SharedStruct`].
pub(crate) fn node() -> SharedStruct {
    shared_struct!(
        "Node",
        Node {
            lo,
            a,
            hi,
            count,
            centre,
            radius
        }
    )
}

/// The order of `spheres` (`x, y, z, r`) along the Morton curve of their centres
/// ([`morton::order`]), with each sphere's key in that order.
pub(crate) fn morton_order(spheres: &[[f32; 4]]) -> (Vec<u32>, Vec<u32>) {
    let centres: Vec<[f32; 3]> = spheres.iter().map(|s| [s[0], s[1], s[2]]).collect();
    morton::order(&centres)
}

/// The centre of the sphere `x, y, z, r`.
fn centre(s: &[f32; 4]) -> Vec3 {
    Vec3::new(s[0], s[1], s[2])
}

/// The box around the centres of `spheres` (inverted, ∞ to −∞, for none).
fn centre_bounds<'a>(spheres: impl IntoIterator<Item = &'a [f32; 4]>) -> (Vec3, Vec3) {
    spheres
        .into_iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), s| {
            (lo.min(centre(s)), hi.max(centre(s)))
        })
}

/// Builds the tree over `items` (a sphere `x, y, z, r` and its payload) already in Morton order
/// (`keys` their sorted keys). An empty set gives an empty tree. A range of equal keys (a
/// cluster finer than the Morton grid) is split at the median of its widest axis, which
/// reorders `items` within it, so ranges stay spatially compact at any scale. The depth stays
/// below [`STACK`]: at most 30 Morton splits, then halving ranges.
pub(crate) fn build<T>(items: &mut [([f32; 4], T)], keys: &[u32]) -> Vec<Node> {
    let mut nodes = Vec::with_capacity(2 * items.len() / LEAF_SIZE + 1);
    if !items.is_empty() {
        build_range(items, keys, 0, items.len(), &mut nodes);
    }
    for node in &mut nodes {
        let ball = 4.0 / 3.0 * std::f64::consts::PI * f64::from(node.radius).powi(3);
        let cube = (0..3)
            .map(|k| f64::from(node.hi[k]) - f64::from(node.lo[k]))
            .product::<f64>();
        if ball > BALL_TO_BOX * cube {
            node.radius = -1.0;
        }
    }
    nodes
}

fn build_range<T>(
    items: &mut [([f32; 4], T)],
    keys: &[u32],
    lo: usize,
    hi: usize,
    nodes: &mut Vec<Node>,
) {
    let at = nodes.len();
    let (bmin, bmax) = bounds(items[lo..hi].iter().map(|item| &item.0));
    // A leaf's ball is around its spheres; an interior node's is set below, around its
    // children's.
    let (centre, radius) = match hi - lo <= LEAF_SIZE {
        true => ball(&items[lo..hi]),
        false => (Vec3::ZERO, 0.0),
    };
    nodes.push(Node {
        lo: bmin.into(),
        a: lo as u32,
        hi: bmax.into(),
        count: (hi - lo) as u32,
        centre: centre.into(),
        radius,
    });
    if hi - lo <= LEAF_SIZE {
        return;
    }
    let (first, last) = (keys[lo], keys[hi - 1]);
    let split = if first == last {
        let mid = (lo + hi) / 2;
        let axis = widest_axis(&items[lo..hi]);
        items[lo..hi].select_nth_unstable_by(mid - lo, |a, b| a.0[axis].total_cmp(&b.0[axis]));
        mid
    } else {
        let bit = 31 - (first ^ last).leading_zeros();
        lo + keys[lo..hi].partition_point(|k| k & (1 << bit) == 0)
    };
    build_range(items, keys, lo, split, nodes);
    let right = nodes.len() as u32;
    build_range(items, keys, split, hi, nodes);
    let (centre, radius) = enclosing(&nodes[at + 1], &nodes[right as usize]);
    let node = &mut nodes[at];
    node.a = right;
    node.count = 0;
    node.centre = centre.into();
    node.radius = radius;
}

/// A ball around the balls of nodes `a` and `b`: the smallest for the two as `f64` would
/// place it, its centre rounded to `f32` and its radius then measured from there in `f64` and
/// rounded up, so that it holds both balls as `f32` stores them.
fn enclosing(a: &Node, b: &Node) -> (Vec3, f32) {
    let (ca, cb) = (
        Vec3::from(a.centre).as_dvec3(),
        Vec3::from(b.centre).as_dvec3(),
    );
    let (ra, rb) = (f64::from(a.radius), f64::from(b.radius));
    let d = ca.distance(cb);
    let centre = if d + rb <= ra {
        ca
    } else if d + ra <= rb {
        cb
    } else {
        ca + (cb - ca) * ((d + rb - ra) / (2.0 * d))
    };
    let c = centre.as_vec3();
    let reach = |x: glam::DVec3, r: f64| c.as_dvec3().distance(x) + r;
    (c, (reach(ca, ra).max(reach(cb, rb)) as f32).next_up())
}

/// The axis along which the centres of `items` spread the most.
fn widest_axis<T>(items: &[([f32; 4], T)]) -> usize {
    let (lo, hi) = centre_bounds(items.iter().map(|(s, _)| s));
    let extent = hi - lo;
    (0..3)
        .max_by(|&a, &b| extent[a].total_cmp(&extent[b]))
        .unwrap_or(0)
}

/// A ball around the spheres of `items` (not empty; a leaf's): centred on the box of their
/// centres, its radius the farthest reach of a sphere from there, computed in `f64` and rounded
/// up, so that it holds each sphere as `f32` stores it.
fn ball<T>(items: &[([f32; 4], T)]) -> (Vec3, f32) {
    let (lo, hi) = centre_bounds(items.iter().map(|(s, _)| s));
    let c = (lo + hi) * 0.5;
    let reach = items
        .iter()
        .map(|(s, _)| {
            let d = (0..3).map(|k| f64::from(s[k]) - f64::from(c[k]));
            d.map(|x| x * x).sum::<f64>().sqrt() + f64::from(s[3])
        })
        .fold(0.0f64, f64::max);
    // `as` rounds to nearest; one step up makes it an upper bound.
    (c, (reach as f32).next_up())
}

/// The box around `spheres` (`x, y, z, r`).
fn bounds<'a>(spheres: impl Iterator<Item = &'a [f32; 4]>) -> (Vec3, Vec3) {
    spheres.fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), s| {
        (lo.min(centre(s) - s[3]), hi.max(centre(s) + s[3]))
    })
}

/// The nearest sphere of `spheres` (in the order of the tree `nodes`) that the ray `o + t·d`
/// hits with `t < t_max`, as [`trace`] finds it.
pub(crate) fn trace_spheres(
    nodes: &[Node],
    spheres: &[[f32; 4]],
    o: Vec3,
    d: Vec3,
    t_max: f32,
    first: bool,
) -> (f32, u32) {
    trace(nodes, o, d, t_max, first, |k| {
        hit_sphere(o, d, spheres[k as usize])
    })
}

/// The nearest primitive the ray `o + t·d` (`d` a unit vector) hits with `t < t_max`, `hit(k)`
/// being where it meets primitive `k` of the tree `nodes` (or [`INF`]): `(t, index)`, or
/// `(t_max, u32::MAX)` for none. With `first`, stops at the first hit found (shadow rays).
pub(crate) fn trace(
    nodes: &[Node],
    o: Vec3,
    d: Vec3,
    t_max: f32,
    first: bool,
    hit: impl Fn(u32) -> f32,
) -> (f32, u32) {
    let mut best = (t_max, u32::MAX);
    if nodes.is_empty() {
        return best;
    }
    let inv = d.map(safe).recip();
    let mut stack = [(0u32, 0f32); STACK];
    let mut sp = 0;
    let t_root = enter(&nodes[0], o, d, inv, best.0);
    if t_root < INF {
        stack[0] = (0, t_root);
        sp = 1;
    }
    while sp > 0 {
        sp -= 1;
        let (index, t_enter) = stack[sp];
        if t_enter >= best.0 {
            continue;
        }
        let node = &nodes[index as usize];
        if node.count > 0 {
            for k in node.a..node.a + node.count {
                let t = hit(k);
                if t < best.0 {
                    best = (t, k);
                    if first {
                        return best;
                    }
                }
            }
            continue;
        }
        let (left, right) = (index + 1, node.a);
        let tl = enter(&nodes[left as usize], o, d, inv, best.0);
        let tr = enter(&nodes[right as usize], o, d, inv, best.0);
        // Push the farther child first, so the nearer one is searched first.
        let (near, far) = if tl <= tr {
            ((left, tl), (right, tr))
        } else {
            ((right, tr), (left, tl))
        };
        for (child, t) in [far, near] {
            if t < INF {
                stack[sp] = (child, t);
                sp += 1;
            }
        }
    }
    best
}

/// A direction component kept away from zero, so its reciprocal is finite.
pub(crate) fn safe(x: f32) -> f32 {
    if x.abs() < 1e-20 {
        1e-20f32.copysign(x)
    } else {
        x
    }
}

/// Where the ray `o + t·d` (`inv` the reciprocals of `d`'s components, kept finite) enters the
/// node, inside both its box and its ball (0 when it starts inside both), or [`INF`] when it
/// misses either, passes through them at different times, or enters at or beyond `t_max`. The
/// ball is widened by [`BALL_SLACK`] of the ray's distance, so the entry is never later than a
/// hit of a primitive below the node as [`hit_sphere`] or `hit_triangle` computes it. A node
/// without a ball (a negative radius) is entered where its box is.
fn enter(node: &Node, o: Vec3, d: Vec3, inv: Vec3, t_max: f32) -> f32 {
    let a = (Vec3::from(node.lo) - o) * inv;
    let b = (Vec3::from(node.hi) - o) * inv;
    let box_in = a.min(b).max_element().max(0.0);
    let box_out = a.max(b).min_element().min(t_max);
    if box_in > box_out || box_in >= t_max {
        return INF;
    }
    if node.radius < 0.0 {
        return box_in;
    }
    let oc = o - Vec3::from(node.centre);
    let along = oc.dot(d);
    let q = oc - d * along;
    let r = node.radius + (along.abs() + node.radius) * BALL_SLACK;
    let h = r * r - q.dot(q);
    if h < 0.0 {
        return INF;
    }
    let root = h.sqrt();
    let t0 = box_in.max(-along - root);
    let t1 = box_out.min(-along + root);
    if t0 <= t1 && t0 < t_max { t0 } else { INF }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(spheres: &[[f32; 4]], o: Vec3, d: Vec3) -> (f32, u32) {
        let mut best = (INF, u32::MAX);
        for (k, &s) in spheres.iter().enumerate() {
            let t = hit_sphere(o, d, s);
            if t < best.0 {
                best = (t, k as u32);
            }
        }
        best
    }

    /// The tree over `spheres` and the spheres in its order.
    fn tree(spheres: &[[f32; 4]]) -> (Vec<Node>, Vec<[f32; 4]>) {
        let (order, keys) = morton_order(spheres);
        let mut items: Vec<_> = order.iter().map(|&i| (spheres[i as usize], ())).collect();
        let nodes = build(&mut items, &keys);
        (nodes, items.into_iter().map(|(s, _)| s).collect())
    }

    #[test]
    fn a_cluster_finer_than_the_morton_grid_is_split_in_space() {
        // 4,096 small spheres in a 0.01 cube, one far away: the cluster's keys are all equal.
        let mut spheres: Vec<[f32; 4]> = (0..4096u32)
            .map(|i| {
                let f = |m: u32| {
                    let h = i.wrapping_mul(0x9E37_79B9) ^ m.wrapping_mul(0x85EB_CA6B);
                    let h = (h ^ (h >> 15)).wrapping_mul(0x2C1B_3C6D);
                    ((h ^ (h >> 12)) % 1009) as f32 / 1009.0 * 0.01
                };
                [f(13), f(29), f(53), 1e-4]
            })
            .collect();
        spheres.push([1e4, 1e4, 1e4, 1.0]);
        let (nodes, sorted) = tree(&spheres);
        // Index order would give each leaf a box spanning much of the cluster (together hundreds
        // of times its volume); split in space, the leaves' boxes tile it.
        let volume = |n: &Node| (0..3).map(|k| n.hi[k] - n.lo[k]).product::<f32>();
        let leaves: f32 = nodes
            .iter()
            .filter(|n| n.count > 0 && n.hi[0] < 1.0)
            .map(volume)
            .sum();
        assert!(leaves < 0.0102f32.powi(3), "leaf volume {leaves}");
        for j in 0..100u32 {
            let a = j as f32 * 0.61;
            let d = Vec3::new(a.cos() * 0.6, a.sin() * 0.6, 0.8);
            let o = 0.005 - 0.05 * d;
            assert_eq!(
                trace_spheres(&nodes, &sorted, o, d, INF, false),
                brute(&sorted, o, d),
                "ray {j}"
            );
        }
    }

    #[test]
    fn the_tree_finds_the_same_nearest_sphere_as_brute_force() {
        let mut spheres = Vec::new();
        for i in 0..500u32 {
            let f = |m: u32| ((i * m) % 97) as f32 / 97.0;
            spheres.push([f(13), f(29), f(53), 0.01 + 0.02 * f(7)]);
        }
        let (nodes, sorted) = tree(&spheres);
        for j in 0..200u32 {
            let a = j as f32 * 0.37;
            let v = Vec3::new(a.cos(), a.sin(), 0.3 * (a * 1.7).sin());
            let d = v / v.length();
            let o = 0.5 - 2.0 * d;
            let got = trace_spheres(&nodes, &sorted, o, d, INF, false);
            let want = brute(&sorted, o, d);
            assert_eq!(got, want, "ray {j}");
        }
    }

    /// The depth of the tree below `index` (a leaf: 1) and its largest leaf.
    fn depth_and_largest_leaf(nodes: &[Node], index: usize) -> (usize, u32) {
        let node = &nodes[index];
        if node.count > 0 {
            return (1, node.count);
        }
        let (dl, ll) = depth_and_largest_leaf(nodes, index + 1);
        let (dr, lr) = depth_and_largest_leaf(nodes, node.a as usize);
        (1 + dl.max(dr), ll.max(lr))
    }

    #[test]
    fn a_near_coincident_cluster_costs_few_sphere_tests_per_ray() {
        // 100,000 spheres of radius 0.01 whose centres lie within 1e-6 of one point: every box
        // holds nearly the same sphere, so boxes alone let a ray through the cluster test
        // almost every sphere. Two such points: at the origin, and off it.
        let n = 100_000u32;
        let unit = |i: u32, m: u32| {
            let h = i.wrapping_mul(0x9E37_79B9) ^ m.wrapping_mul(0x85EB_CA6B);
            let h = (h ^ (h >> 15)).wrapping_mul(0x2C1B_3C6D);
            ((h ^ (h >> 12)) % 100_003) as f32 / 100_003.0 * 2.0 - 1.0
        };
        for point in [Vec3::ZERO, Vec3::new(0.3, -0.2, 0.5)] {
            // Uniform in the ball of radius 1e-6 (points of the cube outside it are skipped).
            let spheres: Vec<[f32; 4]> = (0..)
                .map(|i| Vec3::new(unit(i, 1), unit(i, 2), unit(i, 3)))
                .filter(|u| u.length_squared() <= 1.0)
                .take(n as usize)
                .map(|u| {
                    let c = point + 1e-6 * u;
                    [c.x, c.y, c.z, 0.01]
                })
                .collect();
            let (nodes, sorted) = tree(&spheres);
            let (depth, largest) = depth_and_largest_leaf(&nodes, 0);
            assert!(
                depth < STACK && largest as usize <= LEAF_SIZE,
                "{depth} {largest}"
            );
            // Rays from a camera 0.05 away, through the cluster at every impact parameter and
            // past it; and rays from just outside the surface, outwards (shadow rays).
            let mut rays = Vec::new();
            for j in 0..120u32 {
                let a = j as f32 * 0.61;
                let eye = point + 0.05 * Vec3::new(a.cos(), a.sin(), 0.4 * (a * 1.3).sin());
                let aim = point + 0.013 * (j as f32 / 120.0) * Vec3::new(-a.sin(), a.cos(), 0.3);
                rays.push((eye, (aim - eye).normalize(), false));
                let out = Vec3::new((a * 0.7).cos(), (a * 0.7).sin(), 0.5 * a.sin()).normalize();
                rays.push((
                    point + 1.02 * 0.01 * out,
                    (out + 0.3 * Vec3::Z).normalize(),
                    true,
                ));
            }
            for (j, &(o, d, first)) in rays.iter().enumerate() {
                let tests = std::cell::Cell::new(0u32);
                let got = trace(&nodes, o, d, INF, first, |k| {
                    tests.set(tests.get() + 1);
                    hit_sphere(o, d, sorted[k as usize])
                });
                let want = brute(&sorted, o, d);
                if first {
                    assert_eq!(got.1 == u32::MAX, want.1 == u32::MAX, "ray {j}");
                } else {
                    // Spheres this close tie; the tree may find another of the nearest.
                    assert_eq!(got.0, want.0, "ray {j}");
                }
                if got.1 != u32::MAX {
                    assert_eq!(hit_sphere(o, d, sorted[got.1 as usize]), got.0, "ray {j}");
                }
                assert!(
                    tests.get() < 2_000,
                    "ray {j} ({o}, {d}) tested {} spheres",
                    tests.get()
                );
            }
        }
    }

    #[test]
    fn an_empty_tree_hits_nothing() {
        assert!(build::<()>(&mut [], &[]).is_empty());
        assert_eq!(
            trace_spheres(&[], &[], Vec3::ZERO, Vec3::X, INF, false).1,
            u32::MAX
        );
    }
}
