// The detection's pairs split into their two indices for the radix sort and joined back
// (src/gpu/pair_sort.rs): `split` before the sorts, `join` after them.

struct Params {
    count: u32,   // pairs
    row: u32,     // invocations per dispatch row (2-D dispatch)
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> pairs: array<vec2<u32>>;
@group(0) @binding(2) var<storage, read_write> firsts: array<u32>;
@group(0) @binding(3) var<storage, read_write> seconds: array<u32>;

@compute @workgroup_size(256)
fn split(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x + gid.y * params.row;
    if k >= params.count {
        return;
    }
    let p = pairs[k];
    firsts[k] = p.x;
    seconds[k] = p.y;
}

@compute @workgroup_size(256)
fn join(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x + gid.y * params.row;
    if k >= params.count {
        return;
    }
    pairs[k] = vec2(firsts[k], seconds[k]);
}
