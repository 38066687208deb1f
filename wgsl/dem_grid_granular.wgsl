// The resolve kernel of the wgpu-compute DEM step with the granular contact law
// (dem_contact.wgsl, dem_granular.wgsl): part of the module dem_grid.wgsl describes. The stencil
// walk finds every pair once, by the thread of its owner's sorted place p; the walls are
// resolved by each sphere's own thread in the same pass (they keep history in its slots). The
// history's rows are state rows: a binning step, whose state stays where it is, binds the
// identity as `came_from`.

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
    return walk_pos[q];
}

// The walk keeps the candidates that reach its sphere and resolves them together once it is
// done, or once DEFERRED are waiting: a warp's lanes then run the contact law in step, where
// resolving each at its place in the walk runs it once for every lane that meets a partner
// there. A candidate waits by its sorted place (its state row is read only as it is resolved,
// out of the walk's way). The order of the contacts is the walk's.
const DEFERRED: u32 = 8u;
var<private> deferred: array<u32, DEFERRED>;

fn visit(w: ptr<function, Walker>, q: u32, t: vec4<f32>) {
    if !reaches((*w).s, t) {
        return;
    }
    deferred[(*w).waiting] = q;
    (*w).waiting += 1u;
    if (*w).waiting == DEFERRED {
        resolve_deferred(w);
    }
}

// Resolves the candidates `visit` kept, in the order met.
fn resolve_deferred(w: ptr<function, Walker>) {
    for (var k = 0u; k < (*w).waiting; k += 1u) {
        let q = deferred[k];
        contact_with(w, home[q], walk_pos[q]);
    }
    (*w).waiting = 0u;
}

fn walked(w: ptr<function, Walker>, n: u32) {}

var<workgroup> group_contacts: atomic<u32>;

@compute @workgroup_size(256)
fn resolve(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let p = index(gid);
    var touching = 0u;
    if p < params.n {
        var w = walker(p, home[p], walk_pos[p]);
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
