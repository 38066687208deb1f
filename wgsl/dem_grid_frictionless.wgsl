// The resolve kernel of the wgpu-compute DEM step with the paper's law (dem_physics.wgsl's
// contact_force): part of the module dem_grid.wgsl describes.

struct Walker {
    p: u32,            // sorted place of the walker's sphere
    h: u32,            // its state row
    s: vec4<f32>,
    run: vec4<f32>,    // p's force (xyz) and contacts (w) in the current run or bucket
    total: vec4<f32>,  // the sum of the runs' and buckets' (in this order)
}

// The paper's state is pos and vel alone.
fn carry(i: u32, p: u32) {}

fn walk_sphere(q: u32) -> vec4<f32> {
    return walk_pos[q];
}

// Resolves sphere p against the sphere at sorted place q: adds q's share to its row and p's to
// the current run.
fn visit(w: ptr<function, Walker>, q: u32, t: vec4<f32>) {
    let s = (*w).s;
    let d = t.xyz - s.xyz;
    let reach = s.w + t.w;
    if d.x * d.x + d.y * d.y + d.z * d.z > reach * reach {
        return;
    }
    // The walker's velocity is read at its contacts, not before its walk (whose start the
    // read would hold up); after the first, from the cache.
    let v = vel[(*w).h];
    let row = home[q];
    let u = vel[row];
    let f = contact_force(s.xyz, v.xyz, s.w, v.w, t.xyz, u.xyz, t.w, u.w);
    if f.w != 0.0 {
        add_force(row, -f.xyz);
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
    var w = Walker(p, 0u, vec4(0.0), vec4(0.0), vec4(0.0));
    if p < params.n {
        w.h = home[p];
        w.s = walk_pos[p];
        stencil_walk(&w);
        if w.total.w != 0.0 {
            add_force(w.h, w.total.xyz);
        }
    }
    let total = w.total;
    atomicAdd(&group_contacts, u32(total.w));
    workgroupBarrier();
    if lid == 0u {
        atomicAdd(&counters[0], atomicLoad(&group_contacts));
    }
}
