// Detection stage of the wgpu-compute backend (single-level sorted proxy grid). The sphere at
// sorted position p scans the rest of its own cell and the next cell along x, then the three-cell
// runs of its four forward neighbour rows: 14 of the 27 cells, each unordered pair of neighbour
// cells visited once, so the narrow phase (collides, proxy.wgsl) alone decides and no pair is
// seen twice. Needs grid_params.wgsl prepended, proxy.wgsl and pair_output.wgsl appended.

@group(0) @binding(0) var<uniform> params: GridParams;
@group(0) @binding(1) var<storage, read> spheres: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> ids: array<u32>;
@group(0) @binding(5) var<storage, read> keys: array<u32>;
@group(0) @binding(6) var<storage, read> cell_start: array<u32>;

// Tests sphere s (input index id) against sorted positions a..b; returns how many were tested.
fn scan_run(s: vec4<f32>, id: u32, a: u32, b: u32) -> u32 {
    for (var q = a; q < b; q += 1u) {
        let t = spheres[q];
        if collides(dist2(s.xyz, t.xyz), s.w, t.w) {
            emit_pair(id, ids[q], params.capacity);
        }
    }
    return select(0u, b - a, b > a);
}

@compute @workgroup_size(64)
fn find_pairs(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let p = gid.x + gid.y * params.row;
    var tested = 0u;
    if p < params.n {
        let s = spheres[p];
        let id = ids[p];
        let k = keys[p];
        tested += scan_run(s, id, p + 1u, cell_start[k + 2u]);
        let plane = params.nx * params.ny;
        let rows = array<u32, 4>(params.nx - 1u, plane - params.nx - 1u, plane - 1u, plane + params.nx - 1u);
        for (var r = 0u; r < 4u; r += 1u) {
            let first = k + rows[r];
            tested += scan_run(s, id, cell_start[first], cell_start[first + 3u]);
        }
    }
    add_candidates(tested, lid);
}
