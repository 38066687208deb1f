// The resolve kernel of the wgpu-rq DEM step with the granular contact law (dem_contact.wgsl,
// dem_granular.wgsl): part of the module dem_rq.wgsl describes. The state is in input order, so
// a sphere's index is its stable id and its history row; the ray of the pair's owner p (the
// proxy rule's choice) resolves it; the walls are resolved by each sphere's own thread in the
// same pass.

fn row_before(p: u32) -> u32 {
    return p;
}

fn walk_chunk() -> u32 {
    return rq.chunk;
}

fn visit(w: ptr<function, Walker>, q: u32) {
    let t = pos[q];
    if !keep_in(rq.mode, (*w).p, (*w).s.xyz, (*w).s.w + grown(), q, t.xyz, t.w + grown()) {
        return;
    }
    // Two components of one clump are never a pair (dem_clumps.wgsl).
    if CLUMPED && one_clump(stable_id((*w).h), stable_id(q)) {
        return;
    }
    meet(w, q, t);
}

var<workgroup> group_contacts: atomic<u32>;

@compute @workgroup_size(256)
fn resolve(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let p = gid.x + gid.y * dem.row;
    var touching = 0u;
    if p < dem.n {
        var w = walker(p, p, pos[p]);
        rq_walk(&w);
        finish(&w);
        touching = w.touching;
    }
    atomicAdd(&group_contacts, touching);
    workgroupBarrier();
    if lid == 0u {
        atomicAdd(&counters[0], atomicLoad(&group_contacts));
    }
}
