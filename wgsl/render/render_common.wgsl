// Shared by both GPU render paths: one invocation per pixel, camera rays, the ray-sphere and
// ray-triangle tests, our own BVH's traversal (`walk`: the spheres' tree in the wgpu-compute
// path, the mesh walls' tree in both), shading and the background. The path's own file
// (render_bvh.wgsl or render_rq.wgsl) comes first and defines
// `fn trace(o, d, t_max, first) -> Hit`, the nearest sphere.
// Keep in sync, line for line, with src/render/shade.rs and `trace` in src/render/bvh.rs (the
// CPU twins).

// Twin of View in src/render/shaders.rs (tests/bindings.rs compares the layouts).
struct View {
    eye: vec3<f32>,
    width: u32,      // picture width [pixels]
    corner: vec3<f32>,
    height: u32,     // picture height [pixels]
    right: vec3<f32>,
    samples: u32,    // rays per pixel side (samples² per pixel)
    down: vec3<f32>,
    shadows: u32,    // 1: cast shadow rays
    light: vec3<f32>,
    n: u32,          // number of spheres
    floor_lo: vec3<f32>,
    floor_on: u32,   // 1: draw the floor z = floor_lo.z over floor_lo.xy .. floor_hi.xy
    floor_hi: vec3<f32>,
    walls: u32,      // number of wall triangles
}

// Twin of Node in src/render/bvh.rs (tests/bindings.rs compares the layouts). Interior
// (count == 0): left child at index + 1, right child at `a`; leaf: primitives a .. a + count.
// Every primitive below a node lies inside its box lo .. hi, and where radius >= 0 inside its
// ball (centre, radius); a negative radius: no ball to test.
struct Node {
    lo: vec3<f32>,
    a: u32,
    hi: vec3<f32>,
    count: u32,
    centre: vec3<f32>,
    radius: f32,
}

struct Hit {
    t: f32,
    k: u32,          // sphere index (Morton order), NONE for a miss
}

const INF: f32 = 3.0e38;
const NONE: u32 = 0xffffffffu;
const AMBIENT: f32 = 0.2;
const FACING: f32 = 0.15;
const DIFFUSE: f32 = 0.65;
const SPECULAR: f32 = 0.3;
const SHININESS: f32 = 40.0;
const SHADOW_LIFT: f32 = 0.02;
const FLOOR_LIGHT: vec3<f32> = vec3(0.86, 0.86, 0.84);
const FLOOR_DARK: vec3<f32> = vec3(0.74, 0.74, 0.72);
const FLOOR_CELLS: f32 = 10.0;
const FLOOR_LIFT: f32 = 1e-5;
const SKY_TOP: vec3<f32> = vec3(0.95, 0.96, 0.97);
const SKY_BOTTOM: vec3<f32> = vec3(0.78, 0.80, 0.84);
const WALL_COLOUR: vec3<f32> = vec3(0.55, 0.60, 0.68);
const WALL_ALPHA: f32 = 0.35;
const STACK: u32 = 64u;
// A node's ball is widened by this share of the ray's distance from its centre (twin of
// BALL_SLACK in src/render/bvh.rs).
const BALL_SLACK: f32 = 1.0 / 1048576.0;
// The trees `walk` searches.
const SPHERE_TREE: u32 = 0u;
const WALL_TREE: u32 = 1u;

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> spheres: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> colours: array<u32>;
@group(0) @binding(3) var<storage, read_write> pixels: array<u32>;
@group(0) @binding(4) var<storage, read> nodes: array<Node>;
@group(0) @binding(6) var<storage, read> wall_nodes: array<Node>;
@group(0) @binding(7) var<storage, read> walls: array<vec4<f32>>;  // three corners a triangle

fn hit_sphere(o: vec3<f32>, d: vec3<f32>, s: vec4<f32>) -> f32 {
    let oc = o - s.xyz;
    let b = dot(oc, d);
    let q = oc - d * b;
    let h = s.w * s.w - dot(q, q);
    if h < 0.0 {
        return INF;
    }
    let root = sqrt(h);
    let near = -b - root;
    if near > 0.0 {
        return near;
    }
    let far = -b + root;
    return select(INF, far, far > 0.0);
}

// Where the ray meets wall triangle k for t > 0, from either side, or INF (Möller–Trumbore).
fn hit_triangle(o: vec3<f32>, d: vec3<f32>, k: u32) -> f32 {
    let a = walls[3u * k].xyz;
    let e1 = walls[3u * k + 1u].xyz - a;
    let e2 = walls[3u * k + 2u].xyz - a;
    let p = cross(d, e2);
    let det = dot(e1, p);
    if det == 0.0 {
        return INF;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = dot(s, p) * inv;
    let q = cross(s, e1);
    let v = dot(d, q) * inv;
    if u < 0.0 || v < 0.0 || u + v > 1.0 {
        return INF;
    }
    let t = dot(e2, q) * inv;
    return select(INF, t, t > 0.0);
}

// `c`, seen through wall triangle k along d: its shade laid over `c`.
fn through_wall(c: vec3<f32>, k: u32, d: vec3<f32>) -> vec3<f32> {
    let a = walls[3u * k].xyz;
    let n0 = normalize(cross(walls[3u * k + 1u].xyz - a, walls[3u * k + 2u].xyz - a));
    let n = select(n0, -n0, dot(n0, d) > 0.0);
    return c + (shade(WALL_COLOUR, n, -d, view.light, 1.0) - c) * WALL_ALPHA;
}

fn safe(x: f32) -> f32 {
    return select(x, select(1e-20, -1e-20, x < 0.0), abs(x) < 1e-20);
}

// Where the ray enters the node, inside both its box and its (widened) ball (0 inside both),
// or INF for a miss of either, for box and ball passed at different times, or for an entry at
// or past t_max; a node without a ball is entered where its box is.
fn enter(node: Node, o: vec3<f32>, d: vec3<f32>, inv: vec3<f32>, t_max: f32) -> f32 {
    let a = (node.lo - o) * inv;
    let b = (node.hi - o) * inv;
    let lo = min(a, b);
    let hi = max(a, b);
    let box_in = max(max(max(lo.x, lo.y), lo.z), 0.0);
    let box_out = min(min(min(hi.x, hi.y), hi.z), t_max);
    if box_in > box_out || box_in >= t_max {
        return INF;
    }
    if node.radius < 0.0 {
        return box_in;
    }
    let oc = o - node.centre;
    let along = dot(oc, d);
    let q = oc - d * along;
    let r = node.radius + (abs(along) + node.radius) * BALL_SLACK;
    let h = r * r - dot(q, q);
    if h < 0.0 {
        return INF;
    }
    let root = sqrt(h);
    let t0 = max(box_in, -along - root);
    let t1 = min(box_out, -along + root);
    return select(INF, t0, t0 <= t1 && t0 < t_max);
}

fn node_of(tree: u32, index: u32) -> Node {
    if tree == SPHERE_TREE {
        return nodes[index];
    }
    return wall_nodes[index];
}

fn hit_leaf(tree: u32, o: vec3<f32>, d: vec3<f32>, k: u32) -> f32 {
    if tree == SPHERE_TREE {
        return hit_sphere(o, d, spheres[k]);
    }
    return hit_triangle(o, d, k);
}

// The nearest primitive of `tree` the ray hits with t < t_max, searching our own BVH nearest
// child first with a fixed stack; with `first`, the first hit found (shadow rays).
fn walk(tree: u32, o: vec3<f32>, d: vec3<f32>, t_max: f32, first: bool) -> Hit {
    var best = Hit(t_max, NONE);
    if (tree == SPHERE_TREE && view.n == 0u) || (tree == WALL_TREE && view.walls == 0u) {
        return best;
    }
    let inv = vec3(1.0) / vec3(safe(d.x), safe(d.y), safe(d.z));
    var stack_node: array<u32, STACK>;
    var stack_t: array<f32, STACK>;
    var sp = 0u;
    let t_root = enter(node_of(tree, 0u), o, d, inv, best.t);
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
        let node = node_of(tree, index);
        if node.count > 0u {
            for (var k = node.a; k < node.a + node.count; k += 1u) {
                let t = hit_leaf(tree, o, d, k);
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
        let tl = enter(node_of(tree, left), o, d, inv, best.t);
        let tr = enter(node_of(tree, right), o, d, inv, best.t);
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

fn hit_floor(o: vec3<f32>, d: vec3<f32>, t_max: f32) -> f32 {
    if d.z == 0.0 {
        return INF;
    }
    let t = (view.floor_lo.z - o.z) / d.z;
    let p = o + d * t;
    let inside = p.x >= view.floor_lo.x && p.x <= view.floor_hi.x && p.y >= view.floor_lo.y && p.y <= view.floor_hi.y;
    return select(INF, t, t > 0.0 && t < t_max && inside);
}

fn floor_colour(p: vec3<f32>) -> vec3<f32> {
    let u = floor((p.x - view.floor_lo.x) / (view.floor_hi.x - view.floor_lo.x) * FLOOR_CELLS);
    let v = floor((p.y - view.floor_lo.y) / (view.floor_hi.y - view.floor_lo.y) * FLOOR_CELLS);
    let w = u + v;
    return select(FLOOR_DARK, FLOOR_LIGHT, w - 2.0 * floor(w / 2.0) < 0.5);
}

fn shade(base: vec3<f32>, n: vec3<f32>, v: vec3<f32>, l: vec3<f32>, lit: f32) -> vec3<f32> {
    let diffuse = max(dot(n, l), 0.0) * lit;
    let facing = max(dot(n, v), 0.0);
    let h = normalize(l + v);
    let highlight = pow(max(dot(n, h), 0.0), SHININESS) * SPECULAR * lit;
    let k = AMBIENT + FACING * facing + DIFFUSE * diffuse;
    return base * k + vec3(highlight);
}

fn background(v: f32) -> vec3<f32> {
    return SKY_TOP + (SKY_BOTTOM - SKY_TOP) * clamp(v, 0.0, 1.0);
}

@compute @workgroup_size(8, 8)
fn render(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= view.width || gid.y >= view.height {
        return;
    }
    var sum = vec3(0.0);
    let ss = view.samples;
    for (var sy = 0u; sy < ss; sy += 1u) {
        for (var sx = 0u; sx < ss; sx += 1u) {
            let fx = f32(gid.x) + (f32(sx) + 0.5) / f32(ss);
            let fy = f32(gid.y) + (f32(sy) + 0.5) / f32(ss);
            let d = normalize(view.corner + view.right * fx + view.down * fy);
            let hit = trace(view.eye, d, INF, false);
            var t_floor = INF;
            if view.floor_on != 0u {
                t_floor = hit_floor(view.eye, d, hit.t);
            }
            var c: vec3<f32>;
            if t_floor < INF {
                let p = view.eye + d * t_floor;
                let n = vec3(0.0, 0.0, select(-1.0, 1.0, d.z < 0.0));
                var lit = 1.0;
                if view.shadows != 0u && dot(n, view.light) > 0.0 {
                    let lift = FLOOR_LIFT * (view.floor_hi.x - view.floor_lo.x + view.floor_hi.y - view.floor_lo.y);
                    let start = p + n * lift;
                    if trace(start, view.light, INF, true).k != NONE {
                        lit = 0.0;
                    }
                }
                c = shade(floor_colour(p), n, -d, view.light, lit);
            } else if hit.k == NONE {
                c = background(fy / f32(view.height));
            } else {
                let s = spheres[hit.k];
                let n = normalize(view.eye + d * hit.t - s.xyz);
                var lit = 1.0;
                if view.shadows != 0u && dot(n, view.light) > 0.0 {
                    let start = s.xyz + n * (s.w * (1.0 + SHADOW_LIFT));
                    if trace(start, view.light, INF, true).k != NONE {
                        lit = 0.0;
                    }
                }
                c = shade(unpack4x8unorm(colours[hit.k]).rgb, n, -d, view.light, lit);
            }
            let wall = walk(WALL_TREE, view.eye, d, min(hit.t, t_floor), false).k;
            if wall != NONE {
                c = through_wall(c, wall, d);
            }
            sum += c;
        }
    }
    let mean = sum / f32(ss * ss);
    pixels[gid.x + gid.y * view.width] = pack4x8unorm(vec4(mean, 1.0));
}
