// Build stage of the wgpu-rq backend: Morton keys of the centres, then the spheres reordered by
// key and their proxy boxes. Needs proxy.wgsl prepended.

// Twin of BuildParams in src/engines/wgpu_rq/shaders.rs (tests/bindings.rs compares the layouts).
struct BuildParams {
    lo: vec3<f32>,      // lower corner of the centres' bounding box
    n: u32,             // number of spheres
    scale: vec3<f32>,   // 1023 / extent per axis (0 where the extent is 0)
    mode: u32,          // MODE_MOCHI or MODE_NNS
    r_max: f32,         // largest radius
    pad_rel: f32,       // relative padding of the boxes
    row: u32,           // invocations per dispatch row (2-D dispatch)
}

@group(0) @binding(0) var<uniform> params: BuildParams;
@group(0) @binding(1) var<storage, read> spheres_in: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> keys: array<u32>;
@group(0) @binding(3) var<storage, read_write> order: array<u32>;

// The GPU twin of src/morton.rs (`spread`, `key`, `Grid::key`): the same keys.
fn spread_bits(v: u32) -> u32 {
    var x = v & 0x3ffu;
    x = (x | (x << 16u)) & 0x030000ffu;
    x = (x | (x << 8u)) & 0x0300f00fu;
    x = (x | (x << 4u)) & 0x030c30c3u;
    x = (x | (x << 2u)) & 0x09249249u;
    return x;
}

@compute @workgroup_size(256)
fn morton_keys(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * params.row;
    if i >= params.n {
        return;
    }
    let q = clamp((spheres_in[i].xyz - params.lo) * params.scale, vec3(0.0), vec3(1023.0));
    let c = vec3<u32>(q);
    keys[i] = spread_bits(c.x) | (spread_bits(c.y) << 1u) | (spread_bits(c.z) << 2u);
    order[i] = i;
}

// Second entry point: bindings 2 and 3 are read here, 4–5 written.
@group(0) @binding(4) var<storage, read_write> spheres_sorted: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> boxes: array<f32>;

@compute @workgroup_size(256)
fn proxy_boxes(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x + gid.y * params.row;
    if p >= params.n {
        return;
    }
    let s = spheres_in[order[p]];
    spheres_sorted[p] = s;
    let h = box_half_width(params.mode, s.w, params.r_max);
    // Conservative: pad by a few ulps of the largest coordinate involved.
    let pad = (max(max(abs(s.x), abs(s.y)), abs(s.z)) + h) * params.pad_rel;
    let lo = s.xyz - vec3(h + pad);
    let hi = s.xyz + vec3(h + pad);
    boxes[6u * p + 0u] = lo.x;
    boxes[6u * p + 1u] = lo.y;
    boxes[6u * p + 2u] = lo.z;
    boxes[6u * p + 3u] = hi.x;
    boxes[6u * p + 4u] = hi.y;
    boxes[6u * p + 5u] = hi.z;
}
