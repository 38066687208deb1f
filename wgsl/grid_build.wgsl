// Build stage of the wgpu-compute backend: each sphere's cell key, then (after the radix sort)
// the spheres reordered by cell and the table of where each cell starts.
// Keys are linear, x + nx·(y + ny·z), over a grid with one empty cell of margin on every side.

@group(0) @binding(0) var<uniform> params: GridParams;
@group(0) @binding(1) var<storage, read> spheres_in: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> keys: array<u32>;
@group(0) @binding(3) var<storage, read_write> order: array<u32>;
@group(0) @binding(4) var<storage, read_write> spheres: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> cell_start: array<u32>;

fn cell_key(c: vec3<f32>) -> u32 {
    let u = max((c - params.lo) * params.inv_cell, vec3(0.0));
    let top = vec3(params.nx, params.ny, params.nz) - vec3(2u);
    let cell = min(vec3<u32>(u), top - vec3(1u)) + vec3(1u);
    return cell.x + params.nx * (cell.y + params.ny * cell.z);
}

@compute @workgroup_size(256)
fn cell_keys(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * params.row;
    if i >= params.n {
        return;
    }
    keys[i] = cell_key(spheres_in[i].xyz);
    order[i] = i;
}

@compute @workgroup_size(256)
fn reorder(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x + gid.y * params.row;
    if p >= params.n {
        return;
    }
    spheres[p] = spheres_in[order[p]];
}

// cell_start[c] = first sorted position whose key is >= c, for c in 0..=cells.
@compute @workgroup_size(256)
fn cell_starts(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x + gid.y * params.row;
    if p >= params.n {
        return;
    }
    let k = keys[p];
    var first = 0u;
    if p > 0u {
        first = keys[p - 1u] + 1u;
    }
    for (var c = first; c <= k; c += 1u) {
        cell_start[c] = p;
    }
    if p == params.n - 1u {
        for (var c = k + 1u; c <= params.cells; c += 1u) {
            cell_start[c] = params.n;
        }
    }
}
