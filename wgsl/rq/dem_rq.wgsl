// DEM step of the wgpu-rq backend: the paper's pipeline on ray queries. Per step the proxy boxes
// of the spheres (in input order; the BLAS and TLAS are rebuilt from them by the host's encoder),
// then one zero-length ray per sphere whose candidates pass the proxy rule (proxy.wgsl) and have
// their contact resolved at once: equal and opposite forces on both spheres. This file holds
// what both variants of the step share; the resolve kernel is dem_rq_frictionless.wgsl's (the
// paper's law) or dem_rq_granular.wgsl's. Needs one resolve file, rq_walk.wgsl, dem_params.wgsl,
// the physics of the variant, a dem_force_*.wgsl and proxy.wgsl appended.
enable wgpu_ray_query;

// Twin of RqParams in src/engines/wgpu_rq/shaders.rs (tests/bindings.rs compares the layouts).
struct RqParams {
    chunk: u32,      // primitives per BLAS: sphere index = custom_data * chunk + primitive_index
    pad_rel: f32,    // relative padding of the boxes
    mode: u32,       // MODE_MOCHI or MODE_NNS
    r_max: f32,      // largest radius
}

@group(0) @binding(0) var<uniform> rq: RqParams;
@group(0) @binding(5) var<storage, read_write> boxes: array<f32>;
@group(0) @binding(6) var tlas: acceleration_structure;
// counters[0]: touching pairs found in the step
@group(0) @binding(14) var<storage, read_write> counters: array<atomic<u32>, 4>;

// The state is in input order: a sphere's index is its stable id.
fn stable_id(p: u32) -> u32 {
    return p;
}

// How much the proxy rule grows each sphere's radius: half the reach past touching at which
// contacts may hold (0 but where they adhere), so that it finds every pair within that reach.
fn grown() -> f32 {
    return 0.5 * dem.reach;
}

// The proxy box of every sphere (half-width 2·r, or 2·r_max in nns mode, padded by a few ulps;
// r grown by grown()); starts the step's clock.
@compute @workgroup_size(256)
fn proxy_boxes(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x + gid.y * dem.row;
    if p == 0u {
        atomicAdd(&clock, 1u);
    }
    if p >= dem.n {
        return;
    }
    let s = pos[p];
    let h = box_half_width(rq.mode, s.w + grown(), rq.r_max + grown());
    let pad = (max(max(abs(s.x), abs(s.y)), abs(s.z)) + h) * rq.pad_rel;
    for (var a = 0u; a < 3u; a += 1u) {
        boxes[6u * p + a] = s[a] - (h + pad);
        boxes[6u * p + 3u + a] = s[a] + (h + pad);
    }
}
