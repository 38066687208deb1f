// The resolve kernel of the wgpu-compute DEM step with the paper's law (dem_physics.wgsl's
// contact_force): part of the module dem_grid.wgsl describes.

struct Walker {
    p: u32,
    s: vec4<f32>,
    v: vec4<f32>,      // velocity and mass of sphere p
    run: vec4<f32>,    // p's force (xyz) and contacts (w) in the current run or bucket
    total: vec4<f32>,  // the sum of the runs' and buckets' (in this order)
}

// The paper's state is pos and vel alone.
fn carry(i: u32, p: u32) {}

fn walk_sphere(q: u32) -> vec4<f32> {
    return pos[q];
}

// Resolves sphere p against q: adds q's share there and p's to the current run.
fn visit(w: ptr<function, Walker>, q: u32, t: vec4<f32>) {
    let s = (*w).s;
    let v = (*w).v;
    let u = vel[q];
    let f = contact_force(s.xyz, v.xyz, s.w, v.w, t.xyz, u.xyz, t.w, u.w);
    if f.w != 0.0 {
        add_force(q, -f.xyz);
        (*w).run += f;
    }
}

fn walked(w: ptr<function, Walker>, n: u32) {
    (*w).total += (*w).run;
    (*w).run = vec4(0.0);
}

var<workgroup> group_contacts: atomic<u32>;

// Detection and contact resolution in one pass: every pair is found once (grid_walk.wgsl's
// stencil walk, as in grid_pairs.wgsl) by the thread of one of its spheres, which adds equal and
// opposite forces.
@compute @workgroup_size(256)
fn resolve(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let p = index(gid);
    var w = Walker(p, vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0));
    if p < params.n {
        w.s = pos[p];
        w.v = vel[p];
        stencil_walk(&w);
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
