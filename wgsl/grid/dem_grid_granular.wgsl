// The resolve kernel of the wgpu-compute DEM step with the granular contact law
// (dem_contact.wgsl, dem_granular.wgsl): part of the module dem_grid.wgsl describes. The stencil
// walk finds every pair once, by the thread of its owner's sorted place p; the walls are
// resolved by each sphere's own thread in the same pass (they keep history in its slots). The
// history's rows are state rows: a binning step, whose state stays where it is, binds the
// identity as `came_from`. Needs one of lanes_subgroups.wgsl or lanes_single.wgsl before it.

// ω of set a, by its index (dem_grid.wgsl)
@group(0) @binding(25) var<storage, read> omega_a: array<vec4<f32>>;
// by state index: the index in set a of the sphere now at it (its row of the old history)
@group(0) @binding(38) var<storage, read_write> came_from: array<u32>;

fn carry(i: u32, p: u32) {
    omega[p] = omega_a[i];
    came_from[p] = i;
}

fn row_before(p: u32) -> u32 {
    return came_from[p];
}

// Read-only views of walk_pos (27) and home (26) for the kernels that walk, which only read
// them: no kernel reads one buffer through both.
@group(0) @binding(27) var<storage, read> walk_pos_ro: array<vec4<f32>>;
@group(0) @binding(26) var<storage, read> home_ro: array<u32>;

fn walk_sphere(q: u32) -> vec4<f32> {
    return walk_pos_ro[q];
}

// The windows of a walk reach dem.reach further where contacts adhere and the walk lists those
// apart: a contact may hold that far past touching (the hashed table's cells are grown by it on
// the host).
fn widen_windows() {
    if COHESIVE && !APART_FROM_HISTORY {
        window_slack = dem.reach;
    }
}

// The granular step re-bins every step: a sphere's cell is that of its centre.
fn walker_cell(w: ptr<function, Walker>, level: u32) -> vec3<u32> {
    return cell_coords((*w).s.xyz, level);
}

// dem_grid.wgsl's `integrate_and_count` for a run with clumps (dem_clumps.wgsl): a component
// stays where its clump's step put it, and is counted there.
@compute @workgroup_size(256)
fn integrate_and_count_clumped(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x + gid.y * dem.row;
    if p >= dem.n {
        return;
    }
    ranks[p] = atomicAdd(&counts[cell_key(integrate_or_keep(p))], 1u);
}

// The walk lists the candidates that reach its sphere by sorted place, the first NEAR_ROOM
// of them at near[k · params.n + p] (the k-th of place p: a warp's lanes write and read side by
// side), and they are resolved once the walk is done, the subgroup's lists shared among its
// lanes (`share_listed`): its lanes then run the contact law in step, where resolving each at
// its place in the walk runs it once for every lane that meets a partner there. A sphere that
// met more walks again for each next NEAR_ROOM of them (`resolve_rest`: a walk lists those from
// the walker's `list_from` on). The order of the contacts is the walk's. The walk and the
// resolution run in one kernel (`resolve`) or in two (`list_near`, then `resolve_near`, where the
// walk is long: it then runs without the contact law's registers).
const NEAR_ROOM: u32 = 16u;
// by sorted place: the candidates within reach that list_near met
@group(0) @binding(30) var<storage, read_write> listed: array<u32>;
@group(0) @binding(31) var<storage, read_write> near: array<u32>;

fn visit(w: ptr<function, Walker>, q: u32, t: vec4<f32>) {
    // Two components of one clump are never a pair (dem_clumps.wgsl; CLUMPED first: without
    // clumps, no id is read); where contacts apart come from the history, the walk lists only
    // those that touch (dem_grid_bonds.wgsl).
    if !walk_lists((*w).s, t) || (CLUMPED && one_clump(stable_id(home_ro[(*w).p]), stable_id(home_ro[q]))) {
        return;
    }
    let k = (*w).waiting - (*w).list_from;
    (*w).waiting += 1u;
    if k < NEAR_ROOM {
        near[k * params.n + (*w).p] = q;
    }
}

fn walked(w: ptr<function, Walker>, n: u32) {}

// The walker's contacts past the first NEAR_ROOM of its `count` candidates within reach, walking
// again for each next NEAR_ROOM (the first are `share_listed`'s).
fn resolve_rest(w: ptr<function, Walker>, count: u32) {
    (*w).list_from = NEAR_ROOM;
    while (*w).list_from < count {
        (*w).waiting = 0u;
        stencil_walk(w);
        let listed_now = min(count - (*w).list_from, NEAR_ROOM);
        for (var k = 0u; k < listed_now; k += 1u) {
            let q = near[k * params.n + (*w).p];
            take(w, contact_with(w, home_ro[q], walk_pos_ro[q]));
        }
        (*w).list_from += NEAR_ROOM;
    }
}

// The walker of lane `o` as the lane resolving its k-th listed contact sees it: its sphere, its
// history rows and its k-th slot next.
fn walker_of_lane(w: ptr<function, Walker>, o: u32, k: u32) -> Walker {
    let me = (*w).me;
    let s = lane_vec4f((*w).s, o);
    let v = lane_vec4f(vec4(me.v, me.m), o);
    let ids = lane_vec4u(vec4((*w).a, (*w).kept, (*w).own_old.part, (*w).own_old.slot), o);
    let own_new = lane_vec2u(vec2((*w).own_new.part, (*w).own_new.slot), o);
    var theirs: Walker;
    theirs.p = lane_u32((*w).p, o);
    theirs.s = s;
    // One material: every lane's is 0, and no lane asks for it.
    var material = 0u;
    if !ONE_MATERIAL {
        material = lane_u32(me.material, o);
    }
    theirs.me = Body(s.xyz, v.xyz, lane_vec3f(me.w, o), s.w, v.w, material);
    theirs.a = ids.x;
    theirs.kept = ids.y;
    theirs.own_old = SlotAt(ids.z, ids.w);
    theirs.own_new = SlotAt(own_new.x, own_new.y);
    theirs.held = k;
    return theirs;
}

// The first NEAR_ROOM listed contacts of every lane's walker (of its `count` candidates within
// reach), shared among the subgroup's lanes: all the lanes' lists laid end to end, a lane resolves
// every lane_count-th contact (its owner the lane whose part of the row holds it, found by
// bisection), and each walker takes the sum of its contacts from the last lane that resolved one
// of them in a round (a scan over the lanes of each owner's run). A list's k-th contact keeps
// slot k, so a walker's first NEAR_ROOM slots hold its listed contacts in their order. Returns
// the touching pairs this lane resolved.
fn share_listed(w: ptr<function, Walker>, count: u32, lanes: Lanes) -> u32 {
    let lane = lane_index(lanes);
    let size = lane_count(lanes);
    let mine = min(count, NEAR_ROOM);
    let end = lanes_inclusive_add(mine);
    let first = end - mine;
    let total = lanes_add(mine);
    var touching = 0u;
    for (var round = 0u; round < total; round += size) {
        let j = round + lane;
        // The owner: the lanes whose lists end at or before j come first.
        var o = 0u;
        for (var step = size / 2u; step > 0u; step /= 2u) {
            if lane_u32(end, o + step - 1u) <= j {
                o += step;
            }
        }
        let k = j - lane_u32(first, o);
        var theirs = walker_of_lane(w, o, k);
        var force = vec3(0.0);
        var torque = vec3(0.0);
        if j < total {
            let q = near[k * params.n + theirs.p];
            let c = contact_with(&theirs, home_ro[q], walk_pos_ro[q]);
            force = c.force;
            torque = c.torque_i;
            touching += u32(c.touching);
        }
        // Sums over each owner's run of lanes up to this one.
        for (var delta = 1u; delta < size; delta *= 2u) {
            let below = lane_below_u32(o, delta);
            let f = lane_below_vec3f(force, delta);
            let t = lane_below_vec3f(torque, delta);
            if lane >= delta && below == o {
                force += f;
                torque += t;
            }
        }
        // Each walker's run in this round ends at lane `last`.
        let start = max(first, round);
        let to = min(end, round + size);
        let last = select(lane, to - 1u - round, to > start);
        let f = lane_vec3f(force, last);
        let t = lane_vec3f(torque, last);
        if to > start {
            (*w).force += f;
            (*w).torque += t;
        }
    }
    (*w).held = mine;
    return touching;
}

// The walk of each sorted place alone, listing the candidates that reach its sphere.
@compute @workgroup_size(256)
fn list_near(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = index(gid);
    if p >= params.n {
        return;
    }
    widen_windows();
    var w: Walker;
    w.p = p;
    w.s = walk_pos_ro[p];
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
// (`walk`) or by list_near's, added to the step's touching pairs. Every thread of the workgroup
// calls it (it holds barriers): those past the spheres with nothing to resolve.
fn resolve_thread(gid: vec3<u32>, lid: u32, lanes: Lanes, walk: bool) {
    widen_windows();
    let p = index(gid);
    let here = p < params.n;
    var w: Walker;
    var count = 0u;
    if here {
        w = walker(p, home_ro[p], walk_pos_ro[p]);
        if walk {
            stencil_walk(&w);
            count = w.waiting;
        } else {
            count = listed[p];
        }
    }
    if walk {
        // Every list is written before a lane reads another's.
        storageBarrier();
    }
    var touching = share_listed(&w, count, lanes);
    // No list is read any more where a walk writes it again.
    storageBarrier();
    if here {
        resolve_rest(&w, count);
        resolve_apart(&w);
        finish(&w);
        touching += w.touching;
    }
    count_touching(touching, lid);
}

// The walk and the contacts of each sorted place.
@compute @workgroup_size(256)
fn resolve(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
    lanes: Lanes,
) {
    resolve_thread(gid, lid, lanes, true);
}

// The contacts of each sorted place that list_near listed.
@compute @workgroup_size(256)
fn resolve_near(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
    lanes: Lanes,
) {
    resolve_thread(gid, lid, lanes, false);
}
