// Detection stage of the wgpu-compute backend (sorted proxy grid, single- or multi-level; see
// grid_params.wgsl and grid_stencil.wgsl). Each sphere scans the rows of its windows (dense
// tables), or with a hashed table the rest of its own cell and its 13
// forward neighbour cells, each looked up in its bucket and filtered by its coordinates. Each pair
// is visited once, so the narrow phase (collides, proxy.wgsl) alone decides. Needs
// grid_params.wgsl and grid_stencil.wgsl prepended, proxy.wgsl and pair_output.wgsl appended.

@group(0) @binding(0) var<uniform> params: GridParams;
@group(0) @binding(1) var<storage, read> spheres: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> ids: array<u32>;
@group(0) @binding(6) var<storage, read> cell_start: array<u32>;

// Tests sphere s (input index id) against sorted positions a..b; returns how many were tested.
fn scan_run(s: vec4<f32>, id: u32, a: u32, b: u32) -> u32 {
    for (var q = a; q < b; q += 1u) {
        let t = spheres[q];
        if collides(s.xyz, s.w, t.xyz, t.w) {
            emit_pair(id, q, params.capacity);
        }
    }
    return select(0u, b - a, b > a);
}

// Hashed table: tests sphere s (sorted position p, input index id) against the spheres of `cell`
// found in its bucket (spheres of other cells sharing the bucket are skipped; in the own cell
// only q > p).
fn scan_bucket(s: vec4<f32>, p: u32, id: u32, cell: vec3<u32>, own: bool) -> u32 {
    let b = hash_cell(cell);
    var tested = 0u;
    for (var q = cell_start[b]; q < cell_start[b + 1u]; q += 1u) {
        let t = spheres[q];
        if (own && q <= p) || any(cell_coords(t.xyz, 0u) != cell) {
            continue;
        }
        tested += 1u;
        if collides(s.xyz, s.w, t.xyz, t.w) {
            emit_pair(id, q, params.capacity);
        }
    }
    return tested;
}

@compute @workgroup_size(256)
fn find_pairs(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let p = gid.x + gid.y * params.row;
    var tested = 0u;
    if p < params.n {
        let s = spheres[p];
        let id = ids[p];
        if params.hashed != 0u {
            let cell = cell_coords(s.xyz, 0u);
            tested += scan_bucket(s, p, id, cell, true);
            for (var r = 0u; r < 13u; r += 1u) {
                tested += scan_bucket(s, p, id, cell + bitcast<vec3<u32>>(FORWARD[r]), false);
            }
        } else {
            let own = level_of(s.w);
            let w = window(s, own);
            for (var k = w.own_row; k < w.count; k += 1u) {
                let run = window_row(w, k);
                tested += scan_run(s, id, max(run.x, p + 1u), run.y);
            }
            for (var level = own + 1u; level < params.levels; level += 1u) {
                let w = window(s, level);
                for (var k = 0u; k < w.count; k += 1u) {
                    let run = window_row(w, k);
                    tested += scan_run(s, id, run.x, run.y);
                }
            }
        }
    }
    finish_pairs(tested, lid, params.capacity);
}
