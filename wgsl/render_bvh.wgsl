// Render path wgpu-compute: `trace` walks our own BVH (built on the CPU, src/render/bvh.rs),
// nearest child first, with a fixed stack. render_common.wgsl is appended to this file.
// Keep in sync, line for line, with `trace` in src/render/bvh.rs.

// Twin of Node in src/render/bvh.rs (tests/bindings.rs compares the layouts). Interior (count == 0): left child at index + 1,
// right child at `a`; leaf: spheres a .. a + count.
struct Node {
    lo: vec3<f32>,
    a: u32,
    hi: vec3<f32>,
    count: u32,
}

const STACK: u32 = 64u;

@group(0) @binding(4) var<storage, read> nodes: array<Node>;

fn safe(x: f32) -> f32 {
    return select(x, select(1e-20, -1e-20, x < 0.0), abs(x) < 1e-20);
}

// Where the ray enters the box (0 inside), or INF for a miss or an entry at or past t_max.
fn enter(node: Node, o: vec3<f32>, inv: vec3<f32>, t_max: f32) -> f32 {
    let a = (node.lo - o) * inv;
    let b = (node.hi - o) * inv;
    let lo = min(a, b);
    let hi = max(a, b);
    let t0 = max(max(max(lo.x, lo.y), lo.z), 0.0);
    let t1 = min(min(min(hi.x, hi.y), hi.z), t_max);
    return select(INF, t0, t0 <= t1 && t0 < t_max);
}

fn trace(o: vec3<f32>, d: vec3<f32>, t_max: f32, first: bool) -> Hit {
    var best = Hit(t_max, NONE);
    if view.n == 0u {
        return best;
    }
    let inv = vec3(1.0) / vec3(safe(d.x), safe(d.y), safe(d.z));
    var stack_node: array<u32, STACK>;
    var stack_t: array<f32, STACK>;
    var sp = 0u;
    let t_root = enter(nodes[0], o, inv, best.t);
    if t_root < INF {
        stack_node[0] = 0u;
        stack_t[0] = t_root;
        sp = 1u;
    }
    while sp > 0u {
        sp -= 1u;
        if stack_t[sp] >= best.t {
            continue;
        }
        let index = stack_node[sp];
        let node = nodes[index];
        if node.count > 0u {
            for (var k = node.a; k < node.a + node.count; k += 1u) {
                let t = hit_sphere(o, d, spheres[k]);
                if t < best.t {
                    best = Hit(t, k);
                    if first {
                        return best;
                    }
                }
            }
            continue;
        }
        let left = index + 1u;
        let right = node.a;
        let tl = enter(nodes[left], o, inv, best.t);
        let tr = enter(nodes[right], o, inv, best.t);
        // Push the farther child first, so the nearer one is searched first.
        var near = left;
        var t_near = tl;
        var far = right;
        var t_far = tr;
        if tr < tl {
            near = right;
            t_near = tr;
            far = left;
            t_far = tl;
        }
        if t_far < INF && sp < STACK {
            stack_node[sp] = far;
            stack_t[sp] = t_far;
            sp += 1u;
        }
        if t_near < INF && sp < STACK {
            stack_node[sp] = near;
            stack_t[sp] = t_near;
            sp += 1u;
        }
    }
    return best;
}
