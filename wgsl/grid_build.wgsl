// Build stage of the wgpu-compute backend: a counting sort of the spheres by cell.
// count_cells gives every sphere its rank among the spheres of its cell; cell_scan.wgsl scans the
// counts into cell_start (exclusive prefix sum over cells + 1 entries) and zeroes them; scatter
// writes every sphere's input index to its sorted place, cell_start[key] + rank (recomputing its
// key: cheaper than storing and reading it); and gather fetches the spheres into sorted order. Spheres in
// arbitrary input order land in random places: writing only their 4-byte indices there and
// reading the 16-byte spheres back in sorted order costs less than writing the spheres there
// (measured on the H200: scattering the spheres was most of the build). Keys (cell_key, grid_params.wgsl) are
// linear over a dense grid with one empty cell of margin on every side, or hashed buckets.
// Needs grid_params.wgsl prepended.

@group(0) @binding(0) var<uniform> params: GridParams;
@group(0) @binding(1) var<storage, read> spheres_in: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> ranks: array<u32>;
@group(0) @binding(4) var<storage, read_write> counts: array<atomic<u32>>;

@compute @workgroup_size(256)
fn count_cells(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * params.row;
    if i >= params.n {
        return;
    }
    ranks[i] = atomicAdd(&counts[cell_key(spheres_in[i])], 1u);
}

// Second entry point: reads bindings 1 and 3 and the scanned counts, writes the sorted indices.
@group(0) @binding(5) var<storage, read> cell_start: array<u32>;
@group(0) @binding(7) var<storage, read_write> ids: array<u32>;

@compute @workgroup_size(256)
fn scatter(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * params.row;
    if i >= params.n {
        return;
    }
    let p = cell_start[cell_key(spheres_in[i])] + ranks[i];
    ids[p] = i;
}

// Third entry point: the spheres in sorted order.
@group(0) @binding(8) var<storage, read_write> spheres: array<vec4<f32>>;

@compute @workgroup_size(256)
fn gather(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x + gid.y * params.row;
    if p >= params.n {
        return;
    }
    spheres[p] = spheres_in[ids[p]];
}
