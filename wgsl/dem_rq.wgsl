// DEM step of the wgpu-rq backend: the paper's pipeline on ray queries. Per step the proxy boxes
// of the spheres (in input order; the BLAS and TLAS are rebuilt from them by the host's encoder),
// then one zero-length ray per sphere whose candidates pass the proxy rule (proxy.wgsl) and have
// their contact resolved at once: equal and opposite forces on both spheres. Needs
// rq_walk.wgsl, dem_physics.wgsl, a dem_force_*.wgsl and proxy.wgsl appended.
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

// The proxy box of every sphere (half-width 2·r, or 2·r_max in nns mode, padded by a few ulps);
// starts the step's clock.
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
    let h = box_half_width(rq.mode, s.w, rq.r_max);
    let pad = (max(max(abs(s.x), abs(s.y)), abs(s.z)) + h) * rq.pad_rel;
    for (var a = 0u; a < 3u; a += 1u) {
        boxes[6u * p + a] = s[a] - (h + pad);
        boxes[6u * p + 3u + a] = s[a] + (h + pad);
    }
}

var<workgroup> group_contacts: atomic<u32>;

struct Walker {
    p: u32,
    s: vec4<f32>,
    v: vec4<f32>,      // velocity and mass of sphere p
    total: vec4<f32>,  // p's force (xyz) and number of contacts (w)
}

fn walk_chunk() -> u32 {
    return rq.chunk;
}

// Resolves sphere p against candidate q if the rule keeps the pair: adds q's share there and
// p's to the walker.
fn visit(w: ptr<function, Walker>, q: u32) {
    let p = (*w).p;
    let s = (*w).s;
    let v = (*w).v;
    let t = pos[q];
    if !keep_in(rq.mode, p, s.xyz, s.w, q, t.xyz, t.w) {
        return;
    }
    let u = vel[q];
    let f = contact_force(s.xyz, v.xyz, s.w, v.w, t.xyz, u.xyz, t.w, u.w);
    if f.w != 0.0 {
        add_force(q, -f.xyz);
        (*w).total += f;
    }
}

// One point ray per sphere (rq_walk.wgsl); each pair the rule keeps is resolved by the ray that
// found it.
@compute @workgroup_size(256)
fn resolve(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let p = gid.x + gid.y * dem.row;
    var w = Walker(p, vec4(0.0), vec4(0.0), vec4(0.0));
    if p < dem.n {
        w.s = pos[p];
        w.v = vel[p];
        rq_walk(&w);
        if w.total.w != 0.0 {
            add_force(p, w.total.xyz);
        }
    }
    let total = w.total;
    atomicAdd(&group_contacts, u32(total.w));
    workgroupBarrier();
    if lid == 0u {
        atomicAdd(&counters[0], atomicLoad(&group_contacts));
    }
}
