// Pair output shared by the detection shaders; keep in sync with src/gpu/pair_output.rs. Needs
// `ids` (the input index of each sorted position) declared by the shader.
// Pairs are appended up to `capacity` while the counter keeps counting, so the host can grow the
// buffer and rerun: nothing is silently lost.
// counters[0]: pairs found; counters[1], counters[2]: candidates tested, low and high words.
//
// A thread keeps the sorted positions of its first LOCAL_PAIRS partners; at the end
// (finish_pairs) the workgroup reserves room for all their pairs with one global atomic and each
// thread looks its partners' input indices up and writes its pairs at its offset. One atomic per
// pair on a single counter was most of the detection time on contact-heavy scenes; the indices
// are looked up at the end rather than in the search (docs/performance-log/).
// Pairs beyond LOCAL_PAIRS take a global atomic each.

@group(0) @binding(3) var<storage, read_write> counters: array<atomic<u32>, 4>;
@group(0) @binding(4) var<storage, read_write> pairs: array<vec2<u32>>;

const LOCAL_PAIRS: u32 = 4u;

var<private> local_partners: array<u32, LOCAL_PAIRS>;
var<private> local_count: u32;
var<private> own_id: u32;
var<workgroup> group_candidates: atomic<u32>;
var<workgroup> group_pairs: atomic<u32>;
var<workgroup> group_base: u32;

// Records the pair of the thread's sphere (input index `own`, the same at every call) and the
// sphere at sorted position q.
fn emit_pair(own: u32, q: u32, capacity: u32) {
    own_id = own;
    if local_count < LOCAL_PAIRS {
        local_partners[local_count] = q;
        local_count += 1u;
        return;
    }
    let slot = atomicAdd(&counters[0], 1u);
    if slot < capacity {
        pairs[slot] = ordered_pair(own, ids[q]);
    }
}

fn ordered_pair(a: u32, b: u32) -> vec2<u32> {
    return vec2(min(a, b), max(a, b));
}

// Writes the pairs kept back and adds this invocation's candidate count to the 64-bit
// total. Call once per invocation, from uniform control flow (it holds workgroup barriers).
fn finish_pairs(tested: u32, local_index: u32, capacity: u32) {
    atomicAdd(&group_candidates, tested);
    let offset = atomicAdd(&group_pairs, local_count);
    workgroupBarrier();
    // Two threads (of two subgroups, where they have at most 32 lanes) reserve the room and
    // count the candidates, so the workgroup waits for one global atomic, not three in a row
    // (measured on the H200: ~1 µs per 1M spheres). Workgroups have more than 32 threads.
    if local_index == 0u {
        group_base = atomicAdd(&counters[0], atomicLoad(&group_pairs));
    }
    if local_index == 32u {
        let total = atomicLoad(&group_candidates);
        let old = atomicAdd(&counters[1], total);
        if old > 0xffffffffu - total {
            atomicAdd(&counters[2], 1u);
        }
    }
    let base = workgroupUniformLoad(&group_base);
    for (var k = 0u; k < local_count; k += 1u) {
        let slot = base + offset + k;
        if slot < capacity {
            pairs[slot] = ordered_pair(own_id, ids[local_partners[k]]);
        }
    }
}
