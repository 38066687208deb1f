// Pair output shared by the detection shaders; keep in sync with src/gpu/pair_output.rs.
// Pairs are appended up to `capacity` while the counter keeps counting, so the host can grow the
// buffer and rerun: nothing is silently lost.
// counters[0]: pairs found; counters[1], counters[2]: candidates tested, low and high words.

@group(0) @binding(3) var<storage, read_write> counters: array<atomic<u32>, 4>;
@group(0) @binding(4) var<storage, read_write> pairs: array<vec2<u32>>;

var<workgroup> group_candidates: atomic<u32>;

// Records the pair of input indices a and b (either order).
fn emit_pair(a: u32, b: u32, capacity: u32) {
    let slot = atomicAdd(&counters[0], 1u);
    if slot < capacity {
        pairs[slot] = vec2(min(a, b), max(a, b));
    }
}

// Adds this invocation's candidate count to the 64-bit total. Call once per invocation, from
// uniform control flow (it holds a workgroup barrier).
fn add_candidates(tested: u32, local_index: u32) {
    atomicAdd(&group_candidates, tested);
    workgroupBarrier();
    if local_index == 0u {
        let total = atomicLoad(&group_candidates);
        let old = atomicAdd(&counters[1], total);
        if old > 0xffffffffu - total {
            atomicAdd(&counters[2], 1u);
        }
    }
}
