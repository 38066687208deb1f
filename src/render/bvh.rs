//! The bounding-volume hierarchy of the `wgpu-compute` and `cpu` render paths: built on the CPU
//! over the spheres in Morton order (a top-down LBVH: each range splits where its highest
//! differing Morton bit flips), flattened depth first, and traversed nearest child first with a
//! small stack. [`trace`] is the CPU twin of `trace` in `wgsl/render_bvh.wgsl`.

use super::shade::{INF, hit_sphere};

/// Most spheres in one leaf.
const LEAF_SIZE: usize = 4;

/// Deepest the traversal stack may grow; keep in sync with `STACK` in `wgsl/render_bvh.wgsl`.
pub(crate) const STACK: usize = 64;

/// One node of the flattened tree. An interior node (`count == 0`) has its left child right
/// after it and its right child at `a`; a leaf holds the spheres `a..a + count`.
///
/// Keep in sync with `Node` in `wgsl/render_bvh.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct Node {
    pub lo: [f32; 3],
    pub a: u32,
    pub hi: [f32; 3],
    pub count: u32,
}
const _: () = assert!(size_of::<Node>() == 32);

/// Bits of a Morton key per axis.
const MORTON_AXIS_BITS: u32 = 10;

/// The order of `spheres` (`x, y, z, r`) along the Morton curve of their centres, with each
/// sphere's key.
pub(crate) fn morton_order(spheres: &[[f32; 4]]) -> (Vec<u32>, Vec<u32>) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for s in spheres {
        for k in 0..3 {
            lo[k] = lo[k].min(s[k]);
            hi[k] = hi[k].max(s[k]);
        }
    }
    let cells = (1u32 << MORTON_AXIS_BITS) as f64;
    let scale = [0, 1, 2].map(|k| {
        let extent = (hi[k] - lo[k]) as f64;
        if extent > 0.0 {
            (cells - 1.0) / extent
        } else {
            0.0
        }
    });
    let key = |s: &[f32; 4]| {
        (0..3).fold(0u32, |key, k| {
            let cell = ((s[k] - lo[k]) as f64 * scale[k]) as u32;
            key | spread(cell.min((1 << MORTON_AXIS_BITS) - 1)) << (2 - k)
        })
    };
    let mut order: Vec<u32> = (0..spheres.len() as u32).collect();
    let keys: Vec<u32> = spheres.iter().map(key).collect();
    radsort::sort_by_key(&mut order, |&i| keys[i as usize]);
    let sorted_keys = order.iter().map(|&i| keys[i as usize]).collect();
    (order, sorted_keys)
}

/// Spreads the low 10 bits of `v` to every third bit.
fn spread(v: u32) -> u32 {
    let mut v = v & 0x3ff;
    v = (v | (v << 16)) & 0x030000ff;
    v = (v | (v << 8)) & 0x0300f00f;
    v = (v | (v << 4)) & 0x030c30c3;
    (v | (v << 2)) & 0x09249249
}

/// Builds the tree over `spheres` already in Morton order (`keys` their sorted keys). An empty
/// set gives an empty tree. The depth stays below [`STACK`]: at most 30 Morton splits, then
/// halving ranges of equal keys.
pub(crate) fn build(spheres: &[[f32; 4]], keys: &[u32]) -> Vec<Node> {
    let mut nodes = Vec::with_capacity(2 * spheres.len() / LEAF_SIZE + 1);
    if !spheres.is_empty() {
        build_range(spheres, keys, 0, spheres.len(), &mut nodes);
    }
    nodes
}

fn build_range(spheres: &[[f32; 4]], keys: &[u32], lo: usize, hi: usize, nodes: &mut Vec<Node>) {
    let at = nodes.len();
    let (bmin, bmax) = bounds(&spheres[lo..hi]);
    nodes.push(Node {
        lo: bmin,
        a: lo as u32,
        hi: bmax,
        count: (hi - lo) as u32,
    });
    if hi - lo <= LEAF_SIZE {
        return;
    }
    let (first, last) = (keys[lo], keys[hi - 1]);
    let split = if first == last {
        (lo + hi) / 2
    } else {
        let bit = 31 - (first ^ last).leading_zeros();
        lo + keys[lo..hi].partition_point(|k| k & (1 << bit) == 0)
    };
    build_range(spheres, keys, lo, split, nodes);
    let right = nodes.len() as u32;
    build_range(spheres, keys, split, hi, nodes);
    nodes[at].a = right;
    nodes[at].count = 0;
}

fn bounds(spheres: &[[f32; 4]]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for s in spheres {
        for k in 0..3 {
            lo[k] = lo[k].min(s[k] - s[3]);
            hi[k] = hi[k].max(s[k] + s[3]);
        }
    }
    (lo, hi)
}

/// The nearest sphere the ray `o + t·d` (`d` a unit vector, `inv` its reciprocal) hits with
/// `t < t_max`: `(t, index)`, or `(t_max, u32::MAX)` for none. With `first`, stops at the first
/// hit found (shadow rays).
pub(crate) fn trace(
    nodes: &[Node],
    spheres: &[[f32; 4]],
    o: [f32; 3],
    d: [f32; 3],
    t_max: f32,
    first: bool,
) -> (f32, u32) {
    let mut best = (t_max, u32::MAX);
    if nodes.is_empty() {
        return best;
    }
    let inv = d.map(|x| 1.0 / safe(x));
    let mut stack = [(0u32, 0f32); STACK];
    let mut sp = 0;
    let t_root = enter(&nodes[0], o, inv, best.0);
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
                let t = hit_sphere(o, d, spheres[k as usize]);
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
        let tl = enter(&nodes[left as usize], o, inv, best.0);
        let tr = enter(&nodes[right as usize], o, inv, best.0);
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

/// Where the ray enters the node's box (0 when it starts inside), or [`INF`] when it misses it
/// or enters at or beyond `t_max`.
fn enter(node: &Node, o: [f32; 3], inv: [f32; 3], t_max: f32) -> f32 {
    let mut t0 = 0f32;
    let mut t1 = t_max;
    for k in 0..3 {
        let a = (node.lo[k] - o[k]) * inv[k];
        let b = (node.hi[k] - o[k]) * inv[k];
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    if t0 <= t1 && t0 < t_max { t0 } else { INF }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(spheres: &[[f32; 4]], o: [f32; 3], d: [f32; 3]) -> (f32, u32) {
        let mut best = (INF, u32::MAX);
        for (k, &s) in spheres.iter().enumerate() {
            let t = hit_sphere(o, d, s);
            if t < best.0 {
                best = (t, k as u32);
            }
        }
        best
    }

    #[test]
    fn the_tree_finds_the_same_nearest_sphere_as_brute_force() {
        let mut spheres = Vec::new();
        for i in 0..500u32 {
            let f = |m: u32| ((i * m) % 97) as f32 / 97.0;
            spheres.push([f(13), f(29), f(53), 0.01 + 0.02 * f(7)]);
        }
        let (order, keys) = morton_order(&spheres);
        let sorted: Vec<_> = order.iter().map(|&i| spheres[i as usize]).collect();
        let nodes = build(&sorted, &keys);
        for j in 0..200u32 {
            let a = j as f32 * 0.37;
            let d = {
                let v = [a.cos(), a.sin(), 0.3 * (a * 1.7).sin()];
                let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                v.map(|x| x / n)
            };
            let o = [0.5 - 2.0 * d[0], 0.5 - 2.0 * d[1], 0.5 - 2.0 * d[2]];
            let got = trace(&nodes, &sorted, o, d, INF, false);
            let want = brute(&sorted, o, d);
            assert_eq!(got, want, "ray {j}");
        }
    }

    #[test]
    fn an_empty_tree_hits_nothing() {
        assert!(build(&[], &[]).is_empty());
        assert_eq!(
            trace(&[], &[], [0.0; 3], [1.0, 0.0, 0.0], INF, false).1,
            u32::MAX
        );
    }
}
