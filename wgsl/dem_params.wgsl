// What every GPU DEM step shares: its parameters, the state it steps and its clock, and gravity.
// Keep DemParams in sync with src/engines/gpu_step.rs. Prepended to dem_physics.wgsl (the
// paper's law) or to dem_contact.wgsl and dem_granular.wgsl (the granular step).

struct DemParams {
    box_lo: vec3<f32>,
    n: u32,
    box_hi: vec3<f32>,
    row: u32,               // invocations per dispatch row of a 256-wide kernel
    gravity: vec3<f32>,     // at t = 0
    dt: f32,
    stiffness: f32,
    damping_ratio: f32,
    gravity_spin: f32,      // rad/s about the y axis
    _pad1: u32,
}

@group(0) @binding(1) var<uniform> dem: DemParams;
@group(0) @binding(10) var<storage, read_write> pos: array<vec4<f32>>;   // x, y, z, r
@group(0) @binding(11) var<storage, read_write> vel: array<vec4<f32>>;   // vx, vy, vz, mass
// steps begun since t = 0
@group(0) @binding(16) var<storage, read_write> clock: atomic<u32>;

// The effective value a·b/(a + b) of two positive values (m*, R*, I*) without their product,
// which underflows f32 for small spheres: lo/(1 + lo/hi), symmetric in a and b. Keep in sync with
// `effective` in src/dem/model/contact.rs.
fn effective(a: f32, b: f32) -> f32 {
    let lo = min(a, b);
    let hi = max(a, b);
    return lo / (1.0 + lo / hi);
}

// √(a·b) without the product, which underflows (or overflows) f32: √a·√b. Keep in sync with
// `root_product` in src/dem/model/contact.rs.
fn root_product(a: f32, b: f32) -> f32 {
    return sqrt(a) * sqrt(b);
}

// Gravity at step `step`, turned about the y axis by gravity_spin · t.
fn gravity_at(step: u32) -> vec3<f32> {
    let angle = dem.gravity_spin * (f32(step) * dem.dt);
    let s = sin(angle);
    let c = cos(angle);
    let g = dem.gravity;
    return vec3(g.x * c + g.z * s, g.y, g.z * c - g.x * s);
}
