// LSD radix sort of (u32 key, u32 value) pairs, one 4-bit digit per pass.
// Host side: src/gpu/radix_sort.rs (constants and `Params` must be kept in sync with it).
//
// A pass over the digit at bit `shift` runs:
//   1. `histogram`: block b (BLOCK pairs) counts its digits into hist[d * blocks + b];
//   2. an exclusive scan of hist in that (digit-major) order, by the scan of wgsl/core/scan.wgsl
//      (src/gpu/scan.rs), recorded between the two kernels;
//   3. `scatter`: block b ranks its pairs per digit (stable) and writes each to
//      hist[d * blocks + b] + its rank among the block's pairs of digit d.
// No subgroup operations: ranks come from per-thread counts and workgroup-memory prefix sums.
// Needs workgroup_scan.wgsl appended (the scan across the workgroup's threads).

// Parameters of one pass; 16 bytes, one slot per pass (dynamic uniform offset).
// Twin of `Params` in src/gpu/radix_sort.rs (tests/bindings.rs compares the layouts).
struct Params {
    // Number of pairs to sort.
    n: u32,
    // Bit of the key where this pass's digit starts.
    shift: u32,
    // Mask of the key bits that take part in the sort (low `key_bits` bits).
    key_mask: u32,
    // Sort blocks (workgroups doing work).
    blocks: u32,
}

// Keep in sync with src/gpu/radix_sort.rs.
const RADIX_BITS: u32 = 4u;
const RADIX: u32 = 16u;          // 1 << RADIX_BITS
const WG: u32 = 128u;            // threads per workgroup of `histogram` and `scatter`
const ITEMS: u32 = 16u;          // consecutive pairs per thread
const BLOCK: u32 = 2048u;        // WG * ITEMS: pairs per sort block
const CHUNKS: u32 = 8u;          // WG / RADIX: counter chunks of RADIX entries per digit row

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> keys_in: array<u32>;
@group(0) @binding(2) var<storage, read> values_in: array<u32>;
@group(0) @binding(3) var<storage, read_write> keys_out: array<u32>;
@group(0) @binding(4) var<storage, read_write> values_out: array<u32>;
@group(0) @binding(5) var<storage, read_write> hist: array<u32>;

// Per-thread digit counters, the logical matrix [digit][thread] (RADIX x WG, digit-major),
// stored with one pad word after every RADIX entries so that a thread walking its own RADIX
// consecutive entries does not hit the same bank as its neighbours.
var<workgroup> counts: array<u32, RADIX * WG + WG>;
// One value per thread, for the block-wide sums of `histogram`.
var<workgroup> partial: array<u32, WG>;
// Per digit: global start of the block's run of that digit minus its start inside the block.
var<workgroup> delta: array<u32, RADIX>;

// Index in `counts` of the logical entry (digit d, thread t).
fn slot(d: u32, t: u32) -> u32 {
    let l = d * WG + t;
    return l + (l >> RADIX_BITS);
}

// Index in `counts` of the k-th logical entry in digit-major order.
fn slot_flat(k: u32) -> u32 {
    return k + (k >> RADIX_BITS);
}

fn digit(key: u32) -> u32 {
    return ((key & params.key_mask) >> params.shift) & (RADIX - 1u);
}

// Flat index of this workgroup in a 2-D dispatch (see `gpu::workgroups`).
fn flat_group(wid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return wid.x + wid.y * nwg.x;
}

// Counts the digits of thread t's ITEMS consecutive pairs of `block` into its column of `counts`.
// Only thread t touches column t, so no atomics are needed.
fn count_own(block: u32, t: u32) {
    for (var d = 0u; d < RADIX; d++) {
        counts[slot(d, t)] = 0u;
    }
    let first = block * BLOCK + t * ITEMS;
    for (var i = 0u; i < ITEMS; i++) {
        let idx = first + i;
        if (idx < params.n) {
            let s = slot(digit(keys_in[idx]), t);
            counts[s] += 1u;
        }
    }
}

// Sum of thread t's chunk: the logical entries [t * RADIX, (t + 1) * RADIX) of `counts`, which all
// belong to digit t / CHUNKS.
fn chunk_sum(t: u32) -> u32 {
    var sum = 0u;
    for (var j = 0u; j < RADIX; j++) {
        sum += counts[slot_flat(t * RADIX + j)];
    }
    return sum;
}

// Step 1: hist[d * blocks + b] = number of pairs of digit d in sort block b.
@compute @workgroup_size(128)
fn histogram(
    @builtin(local_invocation_index) t: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let block = flat_group(wid, nwg);
    if (block >= params.blocks) {
        return;
    }
    count_own(block, t);
    workgroupBarrier();
    partial[t] = chunk_sum(t);
    workgroupBarrier();
    if (t < RADIX) {
        var total = 0u;
        for (var c = 0u; c < CHUNKS; c++) {
            total += partial[t * CHUNKS + c];
        }
        hist[t * params.blocks + block] = total;
    }
}

// Step 3: stable scatter of sort block b into keys_out / values_out.
@compute @workgroup_size(128)
fn scatter(
    @builtin(local_invocation_index) t: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let block = flat_group(wid, nwg);
    if (block >= params.blocks) {
        return;
    }
    count_own(block, t);
    workgroupBarrier();

    // Exclusive scan of `counts` in digit-major order: each thread its chunk of RADIX entries,
    // then the chunk totals across threads.
    let sum = chunk_sum(t);
    var run = shared_scan(t, sum).x - sum;
    for (var j = 0u; j < RADIX; j++) {
        let s = slot_flat(t * RADIX + j);
        let c = counts[s];
        counts[s] = run;
        run += c;
    }
    workgroupBarrier();

    // counts[slot(d, 0)] is now where digit d starts inside the block.
    if (t < RADIX) {
        delta[t] = hist[t * params.blocks + block] - counts[slot(t, 0u)];
    }
    workgroupBarrier();

    let first = block * BLOCK + t * ITEMS;
    for (var i = 0u; i < ITEMS; i++) {
        let idx = first + i;
        if (idx < params.n) {
            let key = keys_in[idx];
            let d = digit(key);
            let s = slot(d, t);
            let rank = counts[s];
            counts[s] = rank + 1u;
            let dst = delta[d] + rank;
            keys_out[dst] = key;
            values_out[dst] = values_in[idx];
        }
    }
}
