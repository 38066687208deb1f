// The resolve kernel of the wgpu-compute DEM step with the granular contact law
// (dem_contact.wgsl, dem_granular.wgsl): part of the module dem_grid.wgsl describes. The stencil
// walk finds every pair once, by the thread of its owner p; the walls are resolved by each
// sphere's own thread in the same pass (they keep history in its slots).

// ω of set a, by its index (dem_grid.wgsl)
@group(0) @binding(25) var<storage, read> omega_a: array<vec4<f32>>;
// by state index: the index in set a of the sphere now at it (its row of the old history)
@group(0) @binding(38) var<storage, read_write> came_from: array<u32>;

fn carry(i: u32, p: u32) {
    omega[p] = omega_a[i];
    came_from[p] = i;
}

fn stable_id(p: u32) -> u32 {
    return ids[p];
}

fn row_before(p: u32) -> u32 {
    return came_from[p];
}

fn walk_sphere(q: u32) -> vec4<f32> {
    return pos[q];
}

fn visit(w: ptr<function, Walker>, q: u32, t: vec4<f32>) {
    meet_later(w, q, t);
}

fn walked(w: ptr<function, Walker>, n: u32) {}

var<workgroup> group_contacts: atomic<u32>;

@compute @workgroup_size(256)
fn resolve(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let p = index(gid);
    var touching = 0u;
    if p < params.n {
        var w = walker(p);
        stencil_walk(&w);
        resolve_deferred(&w);
        finish(&w);
        touching = w.touching;
    }
    atomicAdd(&group_contacts, touching);
    workgroupBarrier();
    if lid == 0u {
        atomicAdd(&counters[0], atomicLoad(&group_contacts));
    }
}
