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

// The walk lists the candidates that reach its sphere by sorted place, the first NEAR_ROOM
// of them at near[k · params.n + p] (the k-th of place p: a warp's lanes write and read side by
// side), and they are resolved together from the list once the walk is done
// (`resolve_listed`): a warp's lanes then run the contact law in step, where resolving each at
// its place in the walk runs it once for every lane that meets a partner there. A sphere that
// met more walks again for each next NEAR_ROOM of them (a walk lists those from the walker's
// `list_from` on). The order of the contacts is the walk's. The walk and the resolution run in one kernel (`resolve`) or in two
// (`list_near`, then `resolve_near`, where the walk is long: it then runs without the contact
// law's registers).
const NEAR_ROOM: u32 = 16u;
// by sorted place: the candidates within reach that list_near met
@group(0) @binding(30) var<storage, read_write> listed: array<u32>;
@group(0) @binding(31) var<storage, read_write> near: array<u32>;

fn visit(w: ptr<function, Walker>, q: u32, t: vec4<f32>) {
    if !reaches((*w).s, t) {
        return;
    }
    let k = (*w).waiting - (*w).list_from;
    (*w).waiting += 1u;
    if k < NEAR_ROOM {
        near[k * params.n + (*w).p] = q;
    }
}

fn walked(w: ptr<function, Walker>, n: u32) {}

// Resolves the walker's `count` candidates within reach: those listed, then (walking again
// for each next NEAR_ROOM) the rest.
fn resolve_listed(w: ptr<function, Walker>, count: u32) {
    loop {
        let listed_now = min(count - (*w).list_from, NEAR_ROOM);
        for (var k = 0u; k < listed_now; k += 1u) {
            let q = near[k * params.n + (*w).p];
            contact_with(w, home[q], walk_pos[q]);
        }
        (*w).list_from += NEAR_ROOM;
        if (*w).list_from >= count {
            break;
        }
        (*w).waiting = 0u;
        stencil_walk(w);
    }
}

// The walk of each sorted place alone, listing the candidates that reach its sphere.
@compute @workgroup_size(256)
fn list_near(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = index(gid);
    if p >= params.n {
        return;
    }
    var w: Walker;
    w.p = p;
    w.s = walk_pos[p];
    stencil_walk(&w);
    listed[p] = w.waiting;
}

var<workgroup> group_contacts: atomic<u32>;

// Adds the touching pairs each thread of the workgroup resolved to the step's count.
fn count_touching(touching: u32, lid: u32) {
    atomicAdd(&group_contacts, touching);
    workgroupBarrier();
    if lid == 0u {
        atomicAdd(&counters[0], atomicLoad(&group_contacts));
    }
}

// The contacts of the thread's sorted place, its candidates within reach listed by its own walk
// (`walk`) or by list_near's, added to the step's touching pairs.
fn resolve_thread(gid: vec3<u32>, lid: u32, walk: bool) {
    let p = index(gid);
    var touching = 0u;
    if p < params.n {
        var w = walker(p, home[p], walk_pos[p]);
        var count = 0u;
        if walk {
            stencil_walk(&w);
            count = w.waiting;
        } else {
            count = listed[p];
        }
        resolve_listed(&w, count);
        finish(&w);
        touching = w.touching;
    }
    count_touching(touching, lid);
}

// The walk and the contacts of each sorted place.
@compute @workgroup_size(256)
fn resolve(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    resolve_thread(gid, lid, true);
}

// The contacts of each sorted place that list_near listed.
@compute @workgroup_size(256)
fn resolve_near(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    resolve_thread(gid, lid, false);
}
