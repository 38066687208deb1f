// In-place exclusive prefix sum of u32 (wrapping), reduce-then-scan over levels of BLOCK entries.
// Host side: src/gpu/scan.rs (constants and `Params` must be kept in sync with it).
//
// Level 0 is the range being scanned (in `data`); level k + 1 holds one total per BLOCK entries of
// level k (in `sums`), up to a level of at most BLOCK entries. A scan of level 0 runs:
//   1. `reduce` on every level but the last, bottom up: block b's total goes to the next level;
//   2. `scan` on every level, top down: block b scans its entries in place and adds the scanned
//      total of the blocks before it (entry b of the next level, already scanned; the last level
//      has none).
// Level 0 is read twice and written once. No subgroup operations. Needs workgroup_scan.wgsl
// appended (the scan across the workgroup's threads, and its `part` array).

// Parameters of one dispatch; one slot per dispatch (dynamic uniform offset).
// Twin of `Params` in src/gpu/scan.rs (tests/bindings.rs compares the layouts).
struct Params {
    // Entries of the level.
    len: u32,
    // Offset (in u32) of the level in its buffer (`data` when in_data != 0, else `sums`).
    src: u32,
    // Offset (in u32) in `sums` of the next level: where `reduce` writes the block totals and
    // where `scan` reads the carries.
    dst: u32,
    // Workgroups doing work (blocks of the level); the rest of a 2-D grid returns at once.
    blocks: u32,
    // 1: the level is in `data`; 0: it is in `sums`.
    in_data: u32,
    // `scan`: 1 to add the carries of the next level; 0 for the last level.
    has_carry: u32,
}

// Keep in sync with src/gpu/scan.rs.
const WG: u32 = 256u;      // threads per workgroup
const ITEMS: u32 = 4u;     // entries per thread
const BLOCK: u32 = 1024u;  // WG * ITEMS: entries per workgroup
const TILE: u32 = 1056u;   // BLOCK + BLOCK / 32: one pad word per 32 entries

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> data: array<u32>;
@group(0) @binding(2) var<storage, read_write> sums: array<u32>;

// The block's entries, with a pad word after every 32 so that thread t reading its ITEMS
// consecutive entries avoids the banks of its neighbours.
var<workgroup> tile: array<u32, TILE>;
// `part` (workgroup_scan.wgsl): per-thread totals; `reduce` sums them in its first WG entries.

fn pad(k: u32) -> u32 {
    return k + (k >> 5u);
}

// Flat index of this workgroup in a 2-D dispatch (see `gpu::workgroups`).
fn flat_group(wid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return wid.x + wid.y * nwg.x;
}

// Entry i of the level (i < params.len).
fn load(i: u32) -> u32 {
    if (params.in_data != 0u) {
        return data[params.src + i];
    }
    return sums[params.src + i];
}

fn store(i: u32, v: u32) {
    if (params.in_data != 0u) {
        data[params.src + i] = v;
    } else {
        sums[params.src + i] = v;
    }
}

// sums[dst + b] = total of block b of the level.
@compute @workgroup_size(256)
fn reduce(
    @builtin(local_invocation_index) t: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let block = flat_group(wid, nwg);
    if (block >= params.blocks) {
        return;
    }
    let first = block * BLOCK;
    var sum = 0u;
    for (var i = 0u; i < ITEMS; i++) {
        let k = first + i * WG + t;
        if (k < params.len) {
            sum += load(k);
        }
    }
    part[t] = sum;
    workgroupBarrier();
    for (var off = WG / 2u; off > 0u; off >>= 1u) {
        if (t < off) {
            part[t] += part[t + off];
        }
        workgroupBarrier();
    }
    if (t == 0u) {
        sums[params.dst + block] = part[0];
    }
}

// Exclusive scan of block b of the level in place, plus sums[dst + b] when has_carry != 0.
@compute @workgroup_size(256)
fn scan(
    @builtin(local_invocation_index) t: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let block = flat_group(wid, nwg);
    if (block >= params.blocks) {
        return;
    }
    let first = block * BLOCK;
    // Coalesced loads into the tile.
    for (var i = 0u; i < ITEMS; i++) {
        let k = i * WG + t;
        var x = 0u;
        if (first + k < params.len) {
            x = load(first + k);
        }
        tile[pad(k)] = x;
    }
    workgroupBarrier();

    // Thread t scans its ITEMS consecutive entries.
    var v: array<u32, 4>; // ITEMS
    var sum = 0u;
    for (var j = 0u; j < ITEMS; j++) {
        let x = tile[pad(t * ITEMS + j)];
        v[j] = sum;
        sum += x;
    }

    // Exclusive scan of the thread totals.
    var before = shared_scan(t, sum).x - sum;
    if (params.has_carry != 0u) {
        before += sums[params.dst + block];
    }
    // Only thread t read these slots, before the barriers of the scan.
    for (var j = 0u; j < ITEMS; j++) {
        tile[pad(t * ITEMS + j)] = before + v[j];
    }
    workgroupBarrier();

    // Coalesced stores.
    for (var i = 0u; i < ITEMS; i++) {
        let k = i * WG + t;
        if (first + k < params.len) {
            store(first + k, tile[pad(k)]);
        }
    }
}
