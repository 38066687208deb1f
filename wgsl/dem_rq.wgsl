// DEM step of the wgpu-rq backend: the paper's pipeline on ray queries. Per step the proxy boxes
// of the spheres (in input order; the BLAS and TLAS are rebuilt from them by the host's encoder),
// then one zero-length ray per sphere whose candidates pass the proxy rule (proxy.wgsl) and have
// their contact resolved at once: equal and opposite forces on both spheres. Needs
// dem_physics.wgsl, a dem_force_*.wgsl and proxy.wgsl appended.
enable wgpu_ray_query;

// Keep in sync with RqParams in src/dem/wgpu_rq.rs.
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

// One point ray per sphere; each pair the rule keeps is resolved by the ray that found it.
@compute @workgroup_size(256)
fn resolve(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let p = gid.x + gid.y * dem.row;
    var total = vec4(0.0);
    if p < dem.n {
        let s = pos[p];
        let v = vel[p];
        var query: ray_query;
        rayQueryInitialize(&query, tlas, RayDesc(0u, 0xffu, 0.0, 0.0, s.xyz, vec3(0.0, 0.0, 1.0)));
        while rayQueryProceed(&query) {
            let hit = rayQueryGetCandidateIntersection(&query);
            if hit.kind != RAY_QUERY_INTERSECTION_AABB {
                continue;
            }
            let q = hit.instance_custom_data * rq.chunk + hit.primitive_index;
            let t = pos[q];
            if !keep_in(rq.mode, p, s.xyz, s.w, q, t.xyz, t.w) {
                continue;
            }
            let u = vel[q];
            let f = contact_force(s.xyz, v.xyz, s.w, v.w, t.xyz, u.xyz, t.w, u.w);
            if f.w != 0.0 {
                add_force(q, -f.xyz);
                total += f;
            }
        }
        if total.w != 0.0 {
            add_force(p, total.xyz);
        }
    }
    atomicAdd(&group_contacts, u32(total.w));
    workgroupBarrier();
    if lid == 0u {
        atomicAdd(&counters[0], atomicLoad(&group_contacts));
    }
}
