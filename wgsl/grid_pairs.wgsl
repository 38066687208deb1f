// Detection stage of the wgpu-compute backend (sorted proxy grid, single- or multi-level). With a
// single level, the sphere at
// sorted position p scans the rest of its own cell and its 13 forward neighbour cells: 14 of the
// 27, each unordered pair of neighbour cells visited once, so the narrow phase (collides,
// proxy.wgsl) alone decides and no pair is seen twice. With a dense table the cells of a row are
// contiguous: the rest of the own cell plus the next along x, then four three-cell row runs. With
// a hashed table each cell is looked up in its bucket and filtered by its coordinates; the
// multi-level grid (method.md) is hashed too, see scan_hashed. Needs grid_params.wgsl prepended,
// proxy.wgsl and pair_output.wgsl appended.

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

// The 13 forward neighbours of a cell (the other 13 see this one as theirs).
const FORWARD = array<vec3<i32>, 13>(
    vec3(1, 0, 0), vec3(-1, 1, 0), vec3(0, 1, 0), vec3(1, 1, 0),
    vec3(-1, -1, 1), vec3(0, -1, 1), vec3(1, -1, 1),
    vec3(-1, 0, 1), vec3(0, 0, 1), vec3(1, 0, 1),
    vec3(-1, 1, 1), vec3(0, 1, 1), vec3(1, 1, 1),
);

// Hashed table: tests sphere s (sorted position p, input index id) against the spheres of `cell`
// at `level` found in its bucket (spheres of other cells or levels sharing the bucket are
// skipped; in the own cell only q > p).
fn scan_hashed_cell(s: vec4<f32>, p: u32, id: u32, cell: vec3<u32>, level: u32, own: bool) -> u32 {
    let b = hash_cell(cell, level);
    var tested = 0u;
    for (var q = cell_start[b]; q < cell_start[b + 1u]; q += 1u) {
        let t = spheres[q];
        if (own && q <= p) || level_of(t.w) != level || any(cell_coords(t.xyz, level) != cell) {
            continue;
        }
        tested += 1u;
        if collides(dist2(s.xyz, t.xyz), s.w, t.w) {
            emit_pair(id, ids[q], params.capacity);
        }
    }
    return tested;
}

// Hashed table, one or several levels. At its own level a sphere scans its cell (q > p) and the
// 13 forward neighbours; at every coarser level all 27 cells around it, where only it (the
// smaller sphere) can find the pair.
fn scan_hashed(s: vec4<f32>, p: u32, id: u32) -> u32 {
    let own = level_of(s.w);
    var tested = 0u;
    for (var level = own; level < params.levels; level += 1u) {
        let cell = cell_coords(s.xyz, level);
        if level == own {
            tested += scan_hashed_cell(s, p, id, cell, level, true);
            for (var r = 0u; r < 13u; r += 1u) {
                tested += scan_hashed_cell(s, p, id, cell + bitcast<vec3<u32>>(FORWARD[r]), level, false);
            }
        } else {
            for (var k = 0u; k < 27u; k += 1u) {
                let offset = vec3(i32(k % 3u) - 1, i32((k / 3u) % 3u) - 1, i32(k / 9u) - 1);
                tested += scan_hashed_cell(s, p, id, cell + bitcast<vec3<u32>>(offset), level, false);
            }
        }
    }
    return tested;
}

@compute @workgroup_size(64)
fn find_pairs(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let p = gid.x + gid.y * params.row;
    var tested = 0u;
    if p < params.n {
        let s = spheres[p];
        let id = ids[p];
        if params.hashed != 0u {
            tested += scan_hashed(s, p, id);
        } else {
            let k = keys[p];
            tested += scan_run(s, id, p + 1u, cell_start[k + 2u]);
            let plane = params.nx * params.ny;
            let rows = array<u32, 4>(params.nx - 1u, plane - params.nx - 1u, plane - 1u, plane + params.nx - 1u);
            for (var r = 0u; r < 4u; r += 1u) {
                let first = k + rows[r];
                tested += scan_run(s, id, cell_start[first], cell_start[first + 3u]);
            }
        }
    }
    finish_pairs(tested, lid, params.capacity);
}
