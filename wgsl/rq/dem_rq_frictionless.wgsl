// The resolve kernel of the wgpu-rq DEM step with the paper's law (dem_physics.wgsl's
// contact_force): part of the module dem_rq.wgsl describes.

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
