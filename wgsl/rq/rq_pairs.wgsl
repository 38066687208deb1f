// Detection stage of the wgpu-rq backend: one zero-length point ray per sphere (rq_walk.wgsl);
// every AABB candidate is filtered by keep_in (proxy.wgsl) and written by emit_pair
// (pair_output.wgsl), the three appended to this file.
enable wgpu_ray_query;

// Twin of PairParams in src/engines/wgpu_rq/shaders.rs (tests/bindings.rs compares the layouts).
struct PairParams {
    n: u32,          // number of spheres
    capacity: u32,   // room in `pairs`
    mode: u32,       // MODE_MOCHI or MODE_NNS
    chunk: u32,      // primitives per BLAS: sorted index = custom_data * chunk + primitive_index
    row: u32,        // invocations per dispatch row (2-D dispatch)
}

@group(0) @binding(0) var<uniform> params: PairParams;
@group(0) @binding(1) var<storage, read> spheres: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> ids: array<u32>;
@group(0) @binding(5) var tlas: acceleration_structure;

struct Walker {
    p: u32,
    s: vec4<f32>,
    tested: u32,  // candidates tested
}

fn walk_chunk() -> u32 {
    return params.chunk;
}

fn visit(w: ptr<function, Walker>, q: u32) {
    let p = (*w).p;
    let s = (*w).s;
    (*w).tested += 1u;
    let t = spheres[q];
    if keep_in(params.mode, p, s.xyz, s.w, q, t.xyz, t.w) {
        emit_pair(ids[p], q, params.capacity);
    }
}

@compute @workgroup_size(64)
fn find_pairs(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let p = gid.x + gid.y * params.row;
    var w = Walker(p, vec4(0.0), 0u);
    if p < params.n {
        w.s = spheres[p];
        rq_walk(&w);
    }
    finish_pairs(w.tested, lid, params.capacity);
}
