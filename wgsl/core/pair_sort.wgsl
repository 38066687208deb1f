// The detection's pairs sorted on the GPU (src/gpu/pair_sort.rs), (i, j) ascending with i < j.
//
// Bucketed (the usual way): `count` ranks each pair among those of its first index i (atomics
// on the buckets, one per sphere); the host's exclusive scan (src/gpu/scan.rs) turns the bucket
// counts into each bucket's start; `place` moves every pair into its bucket (in any order
// within it), and `order` puts each bucket's pairs in order of j: a pair's place is the number
// of its bucket's pairs of smaller j (j is unique within a bucket). A bucket of more than
// LONG_BUCKET pairs (a sphere whose first-index pairs are that many) is copied as it is and
// raises `long_bucket`, and the host sorts the pairs again by radix.
//
// By radix (after a long bucket, or where the spheres far outnumber the pairs): `split` the
// pairs into their two indices, two stable radix sorts (by j, then by i), `join` them back.

struct Params {
    count: u32,   // pairs
    row: u32,     // invocations per dispatch row (2-D dispatch)
}

// Pairs of one bucket past which `order` leaves the bucket to the radix sort (each of its pairs
// reads the whole bucket).
const LONG_BUCKET: u32 = 1024u;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> pairs: array<vec2<u32>>;
@group(0) @binding(2) var<storage, read_write> firsts: array<u32>;
@group(0) @binding(3) var<storage, read_write> seconds: array<u32>;
// per sphere (and one past the last): pairs whose first index it is, then (scanned) where its
// bucket starts
@group(0) @binding(4) var<storage, read_write> buckets: array<atomic<u32>>;
// per pair: its rank in its bucket (count), read by place
@group(0) @binding(5) var<storage, read_write> ranks: array<u32>;
// the pairs in their buckets, unordered within each
@group(0) @binding(6) var<storage, read_write> grouped: array<vec2<u32>>;
// 1 where some bucket is longer than LONG_BUCKET (cleared by the host)
@group(0) @binding(7) var<storage, read_write> long_bucket: atomic<u32>;

fn pair_index(gid: vec3<u32>) -> u32 {
    return gid.x + gid.y * params.row;
}

@compute @workgroup_size(256)
fn count(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = pair_index(gid);
    if k >= params.count {
        return;
    }
    ranks[k] = atomicAdd(&buckets[pairs[k].x], 1u);
}

@compute @workgroup_size(256)
fn place(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = pair_index(gid);
    if k >= params.count {
        return;
    }
    let p = pairs[k];
    grouped[atomicLoad(&buckets[p.x]) + ranks[k]] = p;
}

@compute @workgroup_size(256)
fn order(@builtin(global_invocation_id) gid: vec3<u32>) {
    let m = pair_index(gid);
    if m >= params.count {
        return;
    }
    let p = grouped[m];
    let first = atomicLoad(&buckets[p.x]);
    let end = atomicLoad(&buckets[p.x + 1u]);
    if end - first > LONG_BUCKET {
        atomicStore(&long_bucket, 1u);
        pairs[m] = p;
        return;
    }
    var before = 0u;
    for (var t = first; t < end; t += 1u) {
        before += select(0u, 1u, grouped[t].y < p.y);
    }
    pairs[first + before] = p;
}

@compute @workgroup_size(256)
fn split(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = pair_index(gid);
    if k >= params.count {
        return;
    }
    let p = pairs[k];
    firsts[k] = p.x;
    seconds[k] = p.y;
}

@compute @workgroup_size(256)
fn join(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = pair_index(gid);
    if k >= params.count {
        return;
    }
    pairs[k] = vec2(firsts[k], seconds[k]);
}
