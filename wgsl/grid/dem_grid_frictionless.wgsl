// The resolve kernel of the wgpu-compute DEM step with the paper's law (dem_physics.wgsl's
// contact_force): part of the module dem_grid.wgsl describes.

// Candidates within reach a walk lists before resolving them (the walk's loop then holds no
// contact law).
const ROOM: u32 = 8u;
const RESOLVE_GROUP: u32 = 256u; // threads of a resolve workgroup
var<workgroup> near_slots: array<u32, ROOM * RESOLVE_GROUP>;

struct Walker {
    p: u32,            // sorted place of the walker's sphere
    h: u32,            // its state row
    s: vec4<f32>,
    base: u32,         // its first slot in near_slots
    listed: u32,       // candidates within reach listed this walk
    found: u32,        // candidates within reach met this walk
    skip: u32,         // those met before are resolved already (by an earlier walk)
}

// The skin (params.skin > 0: the dense build's paper step, docs/method.md "Re-binning only when
// a sphere may have left its cells"). A step re-bins only where some sphere may have moved more
// than `skin` since the last binning: `begin_step` decides from the largest displacement of each
// step since (their sum bounds every sphere's distance from its binned centre), and sets the
// indirect dispatches of the binning's passes to all workgroups or none. A binning sorts the
// state into the other set and copies it back (`bin_return`), so the state is always in the
// last binning's order and the walk reads it in place. The steps between walk the last
// binning's cells, every window widened by the drift since, at most the skin (`window_slack`,
// grid_stencil.wgsl), from the spheres' current centres: a pair within reach then has its
// partner's binned cell in the walker's window, and each walker starts from the row of its own binned cell (`walker_cell`): each pair
// is still visited once.
// by sorted place: the y and z of the cell its sphere was binned in at its level (y | z << 16)
@group(0) @binding(28) var<storage, read_write> walk_row: array<u32>;
// the skin's words, at the offsets below (host: src/engines/wgpu_compute/skin.rs)
@group(0) @binding(32) var<storage, read_write> skin_state: array<atomic<u32>>;
// [0]: the displacement above which a sphere reports its own this step; [1]: the drift, a
// bound on every sphere's distance from its binned centre this step (`begin_step` sets both)
@group(0) @binding(33) var<storage, read_write> skin_limit: array<f32>;
const ARGS_SPHERES: u32 = 0u;  // this step's dispatch of the binning's sphere passes (x, y, z)
const ARGS_BLOCKS: u32 = 4u;   // and of the scan's (x, y, z)
const FULL_SPHERES: u32 = 8u;  // their x when the step re-bins (the host's)
const FULL_BLOCKS: u32 = 12u;
const DRIFT: u32 = 16u;        // f32: bound on every sphere's distance from its binned centre
const REBINS: u32 = 17u;       // steps that binned, since the host last cleared it
const MOVED: u32 = 32u;        // DRIFT_SLOTS slots: the largest displacement reported this step (f32 bits)
const DRIFT_SLOTS: u32 = 64u;

// The paper's state is pos and vel alone; where the step may skip its binning, the scatter
// notes each sorted place's binned row for the steps that then skip theirs.
fn carry(i: u32, p: u32) {
    if params.skin > 0.0 {
        let s = pos_a[i];
        let cell = cell_coords(s.xyz, level_of(s.w));
        walk_row[p] = cell.y | (cell.z << 16u);
    }
}

// Read-only views of walk_pos (27), home (26), vel (11) and walk_row (28) for the resolve
// kernel, which only reads them: no kernel reads one buffer through both.
@group(0) @binding(27) var<storage, read> walk_pos_ro: array<vec4<f32>>;
@group(0) @binding(26) var<storage, read> home_ro: array<u32>;
@group(0) @binding(11) var<storage, read> vel_ro: array<vec4<f32>>;
@group(0) @binding(28) var<storage, read> walk_row_ro: array<u32>;

fn walk_sphere(q: u32) -> vec4<f32> {
    return walk_pos_ro[q];
}

// The cell the walker's sphere was binned in at its own level (its y and z: the walk needs no
// more): that of its centre, or the one its row notes where the centre may have moved since.
fn walker_cell(w: ptr<function, Walker>, level: u32) -> vec3<u32> {
    if params.skin == 0.0 {
        return cell_coords((*w).s.xyz, level);
    }
    let row = walk_row_ro[(*w).p];
    return vec3(0u, row & 0xffffu, row >> 16u);
}

var<workgroup> step_moved: atomic<u32>;

// The first pass of a step that may skip its binning: starts the step (clock, contact counter),
// adds a bound on the last step's largest displacement to the drift and re-bins where the drift
// passed the skin. Only the spheres that moved more than the limit reported their displacement
// (few atomics), so the step's largest is at most the larger of the limit and the largest
// reported; the limit then follows the motion: just above the largest reported where it was
// exceeded, a little lower at each binning (so it comes down where the motion does). One
// workgroup of DRIFT_SLOTS threads.
@compute @workgroup_size(64)
fn begin_step(@builtin(local_invocation_index) lid: u32) {
    atomicMax(&step_moved, atomicExchange(&skin_state[MOVED + lid], 0u));
    workgroupBarrier();
    if lid == 0u {
        atomicAdd(&clock, 1u);
        atomicStore(&counters[0], 0u);
        let limit = skin_limit[0];
        let reported = bitcast<f32>(atomicLoad(&step_moved));
        // The factor covers the f32 rounding of each displacement and of the sum.
        let moved = max(limit, reported) * (1.0 + 1.0 / 1024.0);
        let drift = bitcast<f32>(atomicLoad(&skin_state[DRIFT])) + moved;
        let rebin = !(drift <= params.skin); // NaN or ∞ re-bins too
        var next = limit;
        if reported > limit {
            next = 1.25 * reported;
        }
        skin_limit[0] = select(next, 0.8 * next, rebin);
        skin_limit[1] = select(drift, 0.0, rebin);
        atomicStore(&skin_state[DRIFT], bitcast<u32>(select(drift, 0.0, rebin)));
        let spheres = atomicLoad(&skin_state[FULL_SPHERES]);
        let blocks = atomicLoad(&skin_state[FULL_BLOCKS]);
        atomicStore(&skin_state[ARGS_SPHERES], select(0u, spheres, rebin));
        atomicStore(&skin_state[ARGS_BLOCKS], select(0u, blocks, rebin));
        atomicAdd(&skin_state[REBINS], u32(rebin));
    }
}

// The first pass of a step that bins whatever the drift (the first after the host wrote the
// state or laid the grid out, and every sorting step).
@compute @workgroup_size(64)
fn begin_binning(@builtin(local_invocation_index) lid: u32) {
    atomicStore(&skin_state[MOVED + lid], 0u);
    if lid == 0u {
        atomicAdd(&clock, 1u);
        atomicStore(&counters[0], 0u);
        atomicStore(&skin_state[DRIFT], 0u);
        skin_limit[1] = 0.0;
        atomicAdd(&skin_state[REBINS], 1u);
    }
}

// A binning's last pass where the step may skip its binning: the sorted set (bound as set a)
// copied back to the state's set, which then stays in the binning's order.
@compute @workgroup_size(256)
fn bin_return(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = index(gid);
    if i >= params.n {
        return;
    }
    pos[i] = pos_a[i];
    pos_lo[i] = pos_lo_a[i];
    vel[i] = vel_a[i];
    ids[i] = ids_a[i];
}

// The integration kernel where the step may skip its binning: a sphere that moved more than the
// limit reports its displacement (the largest in one of DRIFT_SLOTS slots, by workgroup: few
// atomics meet at one word).
@compute @workgroup_size(256)
fn integrate_and_report(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let p = gid.x + gid.y * dem.row;
    if p >= dem.n {
        return;
    }
    let was = pos[p].xyz;
    let d = length(integrate_sphere(p).xyz - was);
    if d > skin_limit[0] {
        let slot = MOVED + wid.x % DRIFT_SLOTS;
        if bitcast<u32>(d) > atomicLoad(&skin_state[slot]) {
            atomicMax(&skin_state[slot], bitcast<u32>(d));
        }
    }
}

// Lists the sphere at sorted place q where it is within reach of the walker's.
fn visit(w: ptr<function, Walker>, q: u32, t: vec4<f32>) {
    let s = (*w).s;
    let d = t.xyz - s.xyz;
    let reach = s.w + t.w;
    if d.x * d.x + d.y * d.y + d.z * d.z > reach * reach {
        return;
    }
    let f = (*w).found;
    (*w).found = f + 1u;
    if f >= (*w).skip && (*w).listed < ROOM {
        near_slots[(*w).base + (*w).listed] = q;
        (*w).listed += 1u;
    }
}

// A run's end: nothing to sum (the listed contacts are resolved after the walk).
fn walked(w: ptr<function, Walker>, n: u32) {}

var<workgroup> group_contacts: atomic<u32>;

// Detection and contact resolution in one pass: every pair is found once (grid_walk.wgsl's
// stencil walk, as in grid_pairs.wgsl) by the thread of one of its spheres, which adds equal and
// opposite forces: it lists up to ROOM candidates within reach, resolves them, and walks again for
// the next ROOM while there are more.
@compute @workgroup_size(RESOLVE_GROUP)
fn resolve(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let p = index(gid);
    var total = vec4(0.0);
    if params.skin > 0.0 {
        window_slack = skin_limit[1];
    }
    if p < params.n {
        let h = home_ro[p];
        let s = walk_pos_ro[p];
        var skip = 0u;
        loop {
            var w = Walker(p, h, s, lid * ROOM, 0u, 0u, skip);
            stencil_walk(&w);
            if w.listed > 0u {
                let v = vel_ro[h];
                for (var k = 0u; k < w.listed; k += 1u) {
                    let q = near_slots[w.base + k];
                    let t = walk_pos_ro[q];
                    let row = home_ro[q];
                    let u = vel_ro[row];
                    let f = contact_force(s.xyz, v.xyz, s.w, v.w, t.xyz, u.xyz, t.w, u.w);
                    if f.w != 0.0 {
                        add_force(row, -f.xyz);
                        total += f;
                    }
                }
            }
            if w.found <= skip + ROOM {
                break;
            }
            skip += ROOM;
        }
        if total.w != 0.0 {
            add_force(h, total.xyz);
        }
    }
    atomicAdd(&group_contacts, u32(total.w));
    workgroupBarrier();
    if lid == 0u {
        atomicAdd(&counters[0], atomicLoad(&group_contacts));
    }
}
