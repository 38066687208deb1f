// Shared by both GPU render paths: one invocation per pixel, camera rays, the ray-sphere test,
// shading and the background. The path's own file (render_bvh.wgsl or render_rq.wgsl) comes
// first and defines `fn trace(o, d, t_max, first) -> Hit`.
// Keep in sync, line for line, with src/render/shade.rs (the CPU twin).

// Keep in sync with ViewUniform in src/render/gpu.rs.
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
            var c: vec3<f32>;
            if hit.k == NONE {
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
