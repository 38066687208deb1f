// DEM step of the wgpu-compute backend (docs/method.md, "The DEM step"): the binning of every
// variant of the step; its resolve kernel is dem_grid_frictionless.wgsl's (the paper's law, with
// a fixed or a per-pair stiffness) or dem_grid_granular.wgsl's, its integration kernel
// dem_integrate.wgsl's or dem_granular.wgsl's (`integrate_sphere`), which also define
//   fn carry(i: u32, p: u32)   moves the per-sphere state of index i of set a to index p of the
//                              sorted set (the granular step's ω; the paper's step's binned rows
//                              where it may skip its binning)
// Needs grid_params.wgsl and grid_stencil.wgsl prepended, one resolve file, grid_walk.wgsl,
// dem_params.wgsl, the physics of the variant and one of dem_force_f32.wgsl /
// dem_force_cas.wgsl appended.
//
// The state (pos, vel, ids and the centres' residuals, pos_lo) lives in two sets of buffers. A sorting step bins one set (`*_a`,
// nearly sorted already, so the atomics of the counting sort hit few cells at a time) into the
// other in sorted order (`bin_scatter`), resolves every contact there and integrates in place.
// A binning step (`bin_index`, the paper's step between its sorting steps) moves no state: it
// bins set a's rows by index, writing each sorted place's row (`home`) and sphere (`walk_pos`),
// and the step resolves and integrates set a in place. The resolve kernels walk the sorted
// spheres and reach the state through `home` (bound to the identity in a sorting step, with
// `walk_pos` bound to the sorted set's pos). The paper's step with a skin
// (dem_grid_frictionless.wgsl) re-bins only some steps, each by a scatter and a copy back: its
// state stays on one set, sorted, and every step resolves and integrates it as a sorting step.

@group(0) @binding(0) var<uniform> params: GridParams;
@group(0) @binding(2) var<storage, read> pos_a: array<vec4<f32>>;   // x, y, z, r
@group(0) @binding(3) var<storage, read> vel_a: array<vec4<f32>>;   // vx, vy, vz, mass
@group(0) @binding(4) var<storage, read> ids_a: array<u32>;
@group(0) @binding(35) var<storage, read> pos_lo_a: array<vec4<f32>>;   // residuals of pos_a
@group(0) @binding(6) var<storage, read_write> ranks: array<u32>;
@group(0) @binding(7) var<storage, read_write> counts: array<atomic<u32>>;
@group(0) @binding(8) var<storage, read> cell_start: array<u32>;
@group(0) @binding(12) var<storage, read_write> ids: array<u32>;
// bindings 1 (dem), 10 (pos), 11 (vel), 16 (clock): dem_params.wgsl; 13 (force): dem_force_*.wgsl
// counters[0]: touching pairs found in the step
@group(0) @binding(14) var<storage, read_write> counters: array<atomic<u32>, 4>;
// bounds of the centres as order-preserving u32 keys: min x, y, z, max x, y, z
@group(0) @binding(15) var<storage, read_write> bounds: array<atomic<u32>, 6>;
// by sorted place: the state row of the sphere there, and its centre and radius
@group(0) @binding(26) var<storage, read_write> home: array<u32>;
@group(0) @binding(27) var<storage, read_write> walk_pos: array<vec4<f32>>;

// The input index the sphere at state index p had when the step opened (ids have gaps where
// spheres left).
fn stable_id(p: u32) -> u32 {
    return ids[p];
}

fn index(gid: vec3<u32>) -> u32 {
    return gid.x + gid.y * params.row;
}

// Counting sort, first pass: the rank within its cell of every sphere of set a (then
// cell_scan.wgsl scans the counts into cell_start and zeroes them). The dense build's step
// counts its spheres as it integrates them (`integrate_and_count`), for the next step: this
// pass runs only where the counts are not those of the state and the layout (at a batch's
// start, after the host laid the grid out again or wrote the state).
@compute @workgroup_size(256)
fn bin_count(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = index(gid);
    if i >= params.n {
        return;
    }
    ranks[i] = atomicAdd(&counts[cell_key(pos_a[i])], 1u);
}

// The step's counters, by the binning's first or last pass (once per step; where the step may
// skip its binning, by its own first pass: dem_grid_frictionless.wgsl's `begin_step`).
fn start_step(i: u32) {
    if i == 0u && params.skin == 0.0 {
        atomicAdd(&clock, 1u);
        atomicStore(&counters[0], 0u);
    }
}

// The integration kernel, then the counting sort's first pass of the next step for the sphere
// (its rank in the cell of its new centre).
@compute @workgroup_size(256)
fn integrate_and_count(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x + gid.y * dem.row;
    if p >= dem.n {
        return;
    }
    ranks[p] = atomicAdd(&counts[cell_key(integrate_sphere(p))], 1u);
}

// The sorted place of sphere i of set a (centre and radius s), after the scan.
fn sorted_place(i: u32, s: vec4<f32>) -> u32 {
    return cell_start[cell_key(s)] + ranks[i];
}

// Counting sort, last pass (after the scan): set a → sorted set (the force accumulators are zero
// between steps: the integration zeroes them); the resolve file's `carry` moves its own
// per-sphere state along.
@compute @workgroup_size(256)
fn bin_scatter(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = index(gid);
    start_step(i);
    if i >= params.n {
        return;
    }
    let s = pos_a[i];
    let p = sorted_place(i, s);
    ids[p] = ids_a[i];
    pos[p] = s;
    pos_lo[p] = pos_lo_a[i];
    vel[p] = vel_a[i];
    carry(i, p);
}

// Counting sort, last pass of a binning step (after the scan): each sphere of set a at its
// sorted place by index (`home`, `walk_pos`); the state stays where it is.
@compute @workgroup_size(256)
fn bin_index(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = index(gid);
    start_step(i);
    if i >= params.n {
        return;
    }
    let s = pos_a[i];
    let p = sorted_place(i, s);
    home[p] = i;
    walk_pos[p] = s;
}

// Order-preserving u32 key of a float (for atomicMin / atomicMax).
fn order_key(x: f32) -> u32 {
    let b = bitcast<u32>(x);
    return select(b | 0x80000000u, ~b, (b & 0x80000000u) != 0u);
}

var<workgroup> group_bounds: array<atomic<u32>, 6>;

// Bounds of the centres of set a, into `bounds` (reset by the host to empty first).
@compute @workgroup_size(256)
fn reduce_bounds(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    if lid < 3u {
        atomicStore(&group_bounds[lid], 0xffffffffu);
        atomicStore(&group_bounds[lid + 3u], 0u);
    }
    workgroupBarrier();
    let i = index(gid);
    if i < params.n {
        let c = pos_a[i].xyz;
        for (var a = 0u; a < 3u; a += 1u) {
            atomicMin(&group_bounds[a], order_key(c[a]));
            atomicMax(&group_bounds[a + 3u], order_key(c[a]));
        }
    }
    workgroupBarrier();
    if lid < 3u {
        atomicMin(&bounds[lid], atomicLoad(&group_bounds[lid]));
        atomicMax(&bounds[lid + 3u], atomicLoad(&group_bounds[lid + 3u]));
    }
}
