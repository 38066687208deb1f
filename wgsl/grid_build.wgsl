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

// cell_start[c] = first sorted position whose key is >= c, for c in 0..=cells: one invocation
// per cell, a binary search over the sorted keys (no serial fill of empty stretches).
@compute @workgroup_size(256)
fn cell_starts(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = gid.x + gid.y * params.cell_row;
    if c > params.cells {
        return;
    }
    var lo = 0u;
    var hi = params.n;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        if keys[mid] < c {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    cell_start[c] = lo;
}
