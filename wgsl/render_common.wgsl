// Shared by both GPU render paths: one invocation per pixel, camera rays, the ray-sphere test,
// shading and the background. The path's own file (render_bvh.wgsl or render_rq.wgsl) comes
// first and defines `fn trace(o, d, t_max, first) -> Hit`.
// Keep in sync, line for line, with src/render/shade.rs (the CPU twin).

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

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> spheres: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> colours: array<u32>;
@group(0) @binding(3) var<storage, read_write> pixels: array<u32>;

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
            sum += c;
        }
    }
    let mean = sum / f32(ss * ss);
    pixels[gid.x + gid.y * view.width] = pack4x8unorm(vec4(mean, 1.0));
}
