// The stencil walk of the sorted proxy grid, shared by detection (grid_pairs.wgsl) and the DEM
// step (dem_grid.wgsl): sphere p visits every sphere q that may touch it exactly once over all
// threads. Dense tables: the rest of its own window row (q > p) and the rows of its own level's
// window after that row, then the full windows of every coarser level (grid_stencil.wgsl).
// Hashed table: the rest of its own cell (q > p) and its 13 forward neighbour cells, each looked
// up in its bucket and filtered by its coordinates (spheres of other cells sharing the bucket are
// skipped). Needs grid_params.wgsl, grid_stencil.wgsl and one of grid_cells_dense.wgsl (with
// `cell_start` bound) or grid_cells_sorted.wgsl prepended; the including shader defines
//   struct Walker { p: u32, s: vec4<f32>, ... }   sphere p (sorted position), s = pos/radius,
//                                                  and whatever its visits accumulate
//   fn visit(w: ptr<function, Walker>, q: u32, t: vec4<f32>)   one candidate q, t = its sphere
//   fn walked(w: ptr<function, Walker>, n: u32)    a run or bucket is done; n candidates visited
//   fn walk_sphere(q: u32) -> vec4<f32>                        sorted sphere q (centre, radius)
//   fn walker_cell(w: ptr<function, Walker>, level: u32) -> vec3<u32>   the cell sphere p was
//                                                  binned in at its own level (its sorted place's)

// Visits the sorted spheres a..b.
fn walk_run(w: ptr<function, Walker>, a: u32, b: u32) {
    for (var q = a; q < b; q += 1u) {
        visit(w, q, walk_sphere(q));
    }
    walked(w, select(0u, b - a, b > a));
}

// Hashed table: visits the spheres of `cell` found in its bucket (in the own cell only q > p).
fn walk_bucket(w: ptr<function, Walker>, cell: vec3<u32>, own: bool) {
    let b = hash_cell(cell);
    let run = cell_run(b, b + 1u);
    var n = 0u;
    for (var q = run.x; q < run.y; q += 1u) {
        let t = walk_sphere(q);
        if (own && q <= (*w).p) || any(cell_coords(t.xyz, 0u) != cell) {
            continue;
        }
        n += 1u;
        visit(w, q, t);
    }
    walked(w, n);
}

// Dense tables: visits the rows of `win` (at the walker's own level, `own`, those from the row
// of its cell `cell` on and, in each, the spheres after it). Rows go along y, then z; each row's
// first table index follows from the last one's (no division per row).
fn walk_window(w: ptr<function, Walker>, win: Window, cell: vec3<u32>, own: bool) {
    var y = 0u;
    var z = 0u;
    var after = 0u;
    if own {
        y = cell.y - win.lo.y;
        z = cell.z - win.lo.z;
        after = (*w).p + 1u;
    }
    var k = y + win.ny * z;
    var row = win.first + win.dims.x * (y + win.dims.y * z);
    // From the last row of one z-plane of the window to the first row of the next.
    let next_plane = win.dims.x * (win.dims.y - win.ny + 1u);
    while k < win.count {
        let run = cell_run(row, row + win.width);
        walk_run(w, max(run.x, after), run.y);
        k += 1u;
        y += 1u;
        if y == win.ny {
            y = 0u;
            row += next_plane;
        } else {
            row += win.dims.x;
        }
    }
}

fn stencil_walk(w: ptr<function, Walker>) {
    let p = (*w).p;
    let s = (*w).s;
    if params.hashed != 0u {
        let cell = cell_coords(s.xyz, 0u);
        walk_bucket(w, cell, true);
        for (var r = 0u; r < 13u; r += 1u) {
            walk_bucket(w, cell + bitcast<vec3<u32>>(FORWARD[r]), false);
        }
    } else {
        let own = level_of(s.w);
        walk_window(w, window(s, own), walker_cell(w, own), true);
        for (var level = own + 1u; level < params.levels; level += 1u) {
            walk_window(w, window(s, level), vec3(0u), false);
        }
    }
}
