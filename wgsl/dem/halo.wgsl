// A rank's exchange of ghosts on the device (src/engines/wgpu/halo.rs), so that a round moves
// the layer near its box's faces as records, and no sphere passes through the host one by one.
// `halo_gather` writes a record of each own sphere near a face into the list of every
// neighbouring box within the halo of it (one list a box that lies next to the rank's) and
// finds the own spheres' largest speed. The records that came are placed by `halo_rows` (each
// stable id's row) and `halo_place` (a ghost's new state into its row, the sphere the rank's
// own where it is in the box now; records of spheres the step does not hold listed as
// coming); `halo_leaving` then lists the spheres that leave (ghosts no owner sent, own spheres
// beyond the halo) and marks the own spheres that left the box as ghosts. `halo_name` writes
// the stable ids of the whole-run ids the rank names or forgets.
//
// Every test of where a centre lies is made in f32 on the record's own words (the centre plus
// its residual) against the faces in f32, on both ranks of a face alike, so that the rank that
// lets a sphere go and the rank that takes it agree on every sphere.

// Twin of HaloParams in src/engines/wgpu/halo.rs (tests/bindings.rs compares the layouts).
struct HaloParams {
    n: u32,           // rows in the state
    row: u32,         // invocations per dispatch row
    room: u32,        // records of each direction's list
    count: u32,       // records that came (`halo_place`), ids named (`halo_name`)
    near_lo: vec3<f32>, // a centre at or below it along an axis is within the halo of the box below
    stamp: u32,       // the round's mark of the ghosts it placed
    near_hi: vec3<f32>, // at or above: of the box above
    spins: u32,       // 1: `omega` holds the spins (the granular step), else none is bound
    box_lo: vec3<f32>,  // the rank's box: lo <= c < hi along every axis (outer sides infinite)
    leave_room: u32,  // entries of `leaving`
    box_hi: vec3<f32>,
    coming_room: u32, // entries of `coming`
    keep_lo: vec3<f32>, // the box grown by the halo: an own centre beyond it leaves the rank
    pad0: u32,
    keep_hi: vec3<f32>,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: HaloParams;
// The step's state by row: x, y, z, r; the residuals x, y, z, 0; vx, vy, vz, m; ωx, ωy, ωz and
// the material as a whole f32 number (dem_granular.wgsl).
@group(0) @binding(1) var<storage, read_write> pos: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> lo: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> vel: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> omega: array<vec4<f32>>;
// The stable id of each row.
@group(0) @binding(5) var<storage, read> ids: array<u32>;
// By stable id: 1 where the sphere is the rank's own, 0 for a ghost.
@group(0) @binding(6) var<storage, read_write> own: array<u32>;
// By stable id: its sphere's whole-run id.
@group(0) @binding(7) var<storage, read> whole: array<u32>;
// By whole-run id: its sphere's stable id + 1 (0: the step does not hold it).
@group(0) @binding(8) var<storage, read_write> stable_of: array<u32>;
// By stable id: the row it is in (`halo_rows`), and the stamp of the round that placed it.
@group(0) @binding(9) var<storage, read_write> row_of: array<u32>;
@group(0) @binding(10) var<storage, read_write> touched: array<u32>;
// Words 0..27: records in each list; then the largest own speed (as bits: speeds
// are not negative, so their bits order as they do), the leaving, the coming, the ghosts made
// own and the own spheres made ghosts.
@group(0) @binding(11) var<storage, read_write> counts: array<atomic<u32>, 32>;
// `room` records a list (one a neighbouring box), four vec4 a record: pos; lo with the
// whole-run id; vel; omega.
@group(0) @binding(12) var<storage, read_write> records: array<vec4<u32>>;
// The records that came, as `records` holds them.
@group(0) @binding(13) var<storage, read> incoming: array<vec4<u32>>;
// Each sphere that leaves: its row, stable id and 1 where it was the rank's own.
@group(0) @binding(14) var<storage, read_write> leaving: array<vec4<u32>>;
// The records that came for spheres the step does not hold, by their place in `incoming`.
@group(0) @binding(15) var<storage, read_write> coming: array<u32>;
// By direction: the list of `records` for the box that lies that way (NO_BOX: none does).
@group(0) @binding(16) var<storage, read> list_of: array<u32, 27>;
// Each whole-run id named or forgotten and its stable id + 1 (0: forgotten), distinct ids.
@group(0) @binding(17) var<storage, read> named: array<vec2<u32>>;

const NO_BOX: u32 = 0xffffffffu;
const FASTEST: u32 = 27u;
const LEAVING: u32 = 28u;
const COMING: u32 = 29u;
const MADE_OWN: u32 = 30u;
const MADE_GHOSTS: u32 = 31u;

var<workgroup> fastest: atomic<u32>;

fn in_box(c: vec3<f32>) -> bool {
    return all(c >= params.box_lo) && all(c < params.box_hi);
}

// The direction (dx, dy, dz) in -1..1 as a list's index.
fn direction(d: vec3<i32>) -> u32 {
    return u32(d.x + 1) + 3u * u32(d.y + 1) + 9u * u32(d.z + 1);
}

fn gather_row(r: u32) {
    let k = ids[r];
    if own[k] == 0u {
        return;
    }
    let v = vel[r];
    atomicMax(&fastest, bitcast<u32>(length(v.xyz)));
    let p = pos[r];
    let l = lo[r];
    let c = p.xyz + l.xyz;
    let below = c <= params.near_lo;
    let above = c >= params.near_hi;
    if !(any(below) || any(above)) {
        return;
    }
    var w = vec4<f32>(0.0);
    if params.spins != 0u {
        w = omega[r];
    }
    // Every neighbouring box within the halo along each axis: 0, and -1 or 1 where near.
    for (var dz = -1; dz <= 1; dz += 1) {
        for (var dy = -1; dy <= 1; dy += 1) {
            for (var dx = -1; dx <= 1; dx += 1) {
                let d = vec3<i32>(dx, dy, dz);
                let skip = (d == vec3<i32>(-1) & !below) | (d == vec3<i32>(1) & !above);
                if any(skip) || all(d == vec3<i32>(0)) {
                    continue;
                }
                let list = list_of[direction(d)];
                if list == NO_BOX {
                    continue;
                }
                let at = atomicAdd(&counts[list], 1u);
                if at < params.room {
                    let e = 4u * (list * params.room + at);
                    records[e] = bitcast<vec4<u32>>(p);
                    records[e + 1u] = vec4<u32>(bitcast<vec3<u32>>(l.xyz), whole[k]);
                    records[e + 2u] = vec4<u32>(bitcast<vec3<u32>>(v.xyz), 0u);
                    records[e + 3u] = bitcast<vec4<u32>>(w);
                }
            }
        }
    }
}

@compute @workgroup_size(256)
fn halo_gather(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    if li == 0u {
        atomicStore(&fastest, 0u);
    }
    workgroupBarrier();
    let r = gid.x + gid.y * params.row;
    if r < params.n {
        gather_row(r);
    }
    workgroupBarrier();
    if li == 0u {
        atomicMax(&counts[FASTEST], atomicLoad(&fastest));
    }
}

@compute @workgroup_size(256)
fn halo_rows(@builtin(global_invocation_id) gid: vec3<u32>) {
    let r = gid.x + gid.y * params.row;
    if r < params.n {
        row_of[ids[r]] = r;
    }
}

@compute @workgroup_size(256)
fn halo_place(@builtin(global_invocation_id) gid: vec3<u32>) {
    let e = gid.x + gid.y * params.row;
    if e >= params.count {
        return;
    }
    let p = bitcast<vec4<f32>>(incoming[4u * e]);
    let l = incoming[4u * e + 1u];
    let k1 = stable_of[l.w];
    if k1 == 0u {
        let at = atomicAdd(&counts[COMING], 1u);
        if at < params.coming_room {
            coming[at] = e;
        }
        return;
    }
    let k = k1 - 1u;
    let r = row_of[k];
    let residual = bitcast<vec3<f32>>(l.xyz);
    pos[r] = vec4<f32>(p.xyz, pos[r].w);
    lo[r] = vec4<f32>(residual, 0.0);
    vel[r] = vec4<f32>(bitcast<vec3<f32>>(incoming[4u * e + 2u].xyz), vel[r].w);
    if params.spins != 0u {
        omega[r] = vec4<f32>(bitcast<vec3<f32>>(incoming[4u * e + 3u].xyz), omega[r].w);
    }
    touched[k] = params.stamp;
    if in_box(p.xyz + residual) {
        own[k] = 1u;
        atomicAdd(&counts[MADE_OWN], 1u);
    }
}

fn leave(r: u32, k: u32, was_own: u32) {
    let at = atomicAdd(&counts[LEAVING], 1u);
    if at < params.leave_room {
        leaving[at] = vec4<u32>(r, k, was_own, 0u);
    }
}

@compute @workgroup_size(256)
fn halo_leaving(@builtin(global_invocation_id) gid: vec3<u32>) {
    let r = gid.x + gid.y * params.row;
    if r >= params.n {
        return;
    }
    let k = ids[r];
    if own[k] == 0u {
        if touched[k] != params.stamp {
            leave(r, k, 0u);
        }
        return;
    }
    let c = pos[r].xyz + lo[r].xyz;
    if in_box(c) {
        return;
    }
    if all(c >= params.keep_lo) && all(c <= params.keep_hi) {
        own[k] = 0u;
        touched[k] = params.stamp;
        atomicAdd(&counts[MADE_GHOSTS], 1u);
    } else {
        leave(r, k, 1u);
    }
}

@compute @workgroup_size(256)
fn halo_name(@builtin(global_invocation_id) gid: vec3<u32>) {
    let e = gid.x + gid.y * params.row;
    if e < params.count {
        let entry = named[e];
        stable_of[entry.x] = entry.y;
    }
}
