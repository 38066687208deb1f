// LSD radix sort of (u32 key, u32 value) pairs, one 4-bit digit per pass.
// Host side: src/gpu/radix_sort.rs (constants and `Params` must be kept in sync with it).
//
// A pass over the digit at bit `shift` runs:
//   1. `histogram`: block b (BLOCK pairs) counts its digits into hist[d * blocks + b];
//   2. `scan_blocks` / `scan_add`: an exclusive scan of hist in that (digit-major) order, in
//      several levels of SCAN_BLOCK entries;
//   3. `scatter`: block b ranks its pairs per digit (stable) and writes each to
//      hist[d * blocks + b] + its rank among the block's pairs of digit d.
// No subgroup operations: ranks come from per-thread counts and workgroup-memory prefix sums.

// Parameters of one dispatch; 32 bytes, one slot per dispatch (dynamic uniform offset).
// Keep in sync with `Params` in src/gpu/radix_sort.rs.
struct Params {
    // Number of pairs to sort.
    n: u32,
    // Bit of the key where this pass's digit starts.
    shift: u32,
    // Mask of the key bits that take part in the sort (low `key_bits` bits).
    key_mask: u32,
    // Workgroups doing work in this dispatch (sort blocks, or scan blocks).
    blocks: u32,
    // scan_blocks / scan_add: entries of the level being scanned.
    len: u32,
    // scan_blocks / scan_add: offset (in u32) of that level in `hist`.
    src: u32,
    // scan_blocks / scan_add: offset (in u32) of the next level (its block totals) in `hist`.
    dst: u32,
    _pad0: u32,
}

// Keep in sync with src/gpu/radix_sort.rs.
const RADIX_BITS: u32 = 4u;
const RADIX: u32 = 16u;          // 1 << RADIX_BITS
const WG: u32 = 128u;            // threads per workgroup of `histogram` and `scatter`
const ITEMS: u32 = 16u;          // consecutive pairs per thread
const BLOCK: u32 = 2048u;        // WG * ITEMS: pairs per sort block
const CHUNKS: u32 = 8u;          // WG / RADIX: counter chunks of RADIX entries per digit row
const SCAN_WG: u32 = 256u;       // threads per workgroup of `scan_blocks` and `scan_add`
const SCAN_ITEMS: u32 = 4u;      // entries per thread
const SCAN_BLOCK: u32 = 1024u;   // SCAN_WG * SCAN_ITEMS

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
// One value per thread, for block-wide scans and reductions.
var<workgroup> partial: array<u32, WG>;
// Per digit: global start of the block's run of that digit minus its start inside the block.
var<workgroup> delta: array<u32, RADIX>;
// One value per thread of the scan kernels.
var<workgroup> scan_tmp: array<u32, SCAN_WG>;

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

// Inclusive scan of `partial` (WG entries), Hillis-Steele; all threads must call it.
fn scan_partial(t: u32) {
    for (var off = 1u; off < WG; off <<= 1u) {
        var add = 0u;
        if (t >= off) {
            add = partial[t - off];
        }
        workgroupBarrier();
        partial[t] += add;
        workgroupBarrier();
    }
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

// Step 2a: exclusive scan of hist[src .. src + len) within blocks of SCAN_BLOCK entries, in place;
// each block's total goes to hist[dst + block].
@compute @workgroup_size(256)
fn scan_blocks(
    @builtin(local_invocation_index) t: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let block = flat_group(wid, nwg);
    if (block >= params.blocks) {
        return;
    }
    let first = block * SCAN_BLOCK + t * SCAN_ITEMS;
    var v: array<u32, 4>; // SCAN_ITEMS
    var sum = 0u;
    for (var i = 0u; i < SCAN_ITEMS; i++) {
        var x = 0u;
        if (first + i < params.len) {
            x = hist[params.src + first + i];
        }
        v[i] = sum;
        sum += x;
    }
    scan_tmp[t] = sum;
    workgroupBarrier();
    for (var off = 1u; off < SCAN_WG; off <<= 1u) {
        var add = 0u;
        if (t >= off) {
            add = scan_tmp[t - off];
        }
        workgroupBarrier();
        scan_tmp[t] += add;
        workgroupBarrier();
    }
    let before = scan_tmp[t] - sum;
    for (var i = 0u; i < SCAN_ITEMS; i++) {
        if (first + i < params.len) {
            hist[params.src + first + i] = before + v[i];
        }
    }
    if (t == SCAN_WG - 1u) {
        hist[params.dst + block] = scan_tmp[t];
    }
}

// Step 2b: adds to each entry of hist[src .. src + len) the scanned total of the blocks before
// its own (hist[dst + its block], already an exclusive scan).
@compute @workgroup_size(256)
fn scan_add(
    @builtin(local_invocation_index) t: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let block = flat_group(wid, nwg);
    if (block >= params.blocks) {
        return;
    }
    let carry = hist[params.dst + block];
    for (var i = 0u; i < SCAN_ITEMS; i++) {
        let k = block * SCAN_BLOCK + i * SCAN_WG + t;
        if (k < params.len) {
            hist[params.src + k] += carry;
        }
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
    partial[t] = sum;
    workgroupBarrier();
    scan_partial(t);
    var run = partial[t] - sum;
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
