// The cells a sphere searches in the grids of grid_params.wgsl (appended after it), as runs of
// sorted positions found by `cell_run` (grid_cells_dense.wgsl: read from the dense build's
// table; grid_cells_sorted.wgsl: searched in the sorted keys); shared by grid_pairs.wgsl and
// dem_grid.wgsl.

// The 13 forward neighbours of a cell (the other 13 see this one as theirs).
const FORWARD = array<vec3<i32>, 13>(
    vec3(1, 0, 0), vec3(-1, 1, 0), vec3(0, 1, 0), vec3(1, 1, 0),
    vec3(-1, -1, 1), vec3(0, -1, 1), vec3(1, -1, 1),
    vec3(-1, 0, 1), vec3(0, 0, 1), vec3(1, 0, 1),
    vec3(-1, 1, 1), vec3(0, 1, 1), vec3(1, 1, 1),
);

// Dense tables: the partners of sphere s at `level` lie in its window there: the cells within
// r_i plus the level's largest partner radius (plus the slack) of c_i along each axis (2 or 3
// cells per axis where the cells are the class's size, fewer than the 27 cells around its own
// when cells were grown, more where the level is refined), as rows of cells along x, each a run
// of sorted positions. At coarser levels s tests every sphere of its window (only the smaller
// sphere looks for a pair); at its own level only those after it in sorted order: rows before its
// own row are skipped and the rest start after p, so each pair is visited once.
// How far every sphere may be from the centre it was binned by: zero but in a DEM step that
// walks the cells of an earlier binning, which sets it at its walk's start.
var<private> window_slack: f32 = 0.0;

struct Window {
    first: u32,   // table index of the first cell of the first row
    width: u32,   // cells per row (along x)
    ny: u32,      // rows along y
    count: u32,   // rows in all
    dims: vec3<u32>,
    lo: vec3<u32>, // cell coordinates of the first cell
}

// Cell coordinates (margin included) of the cells within `reach` cells of u, per axis.
fn reach_cells(u: vec3<f32>, reach: f32, dims: vec3<u32>) -> array<vec3<u32>, 2> {
    let top = vec3<f32>(dims - vec3(3u));
    let lo = clamp(floor(u - vec3(reach)), vec3(0.0), top);
    let hi = clamp(floor(u + vec3(reach)), vec3(0.0), top);
    return array(vec3<u32>(lo) + vec3(1u), vec3<u32>(hi) + vec3(1u));
}

fn window(s: vec4<f32>, level: u32) -> Window {
    let inv = ldexp(params.inv_cell, i32(cell_shift(level)));
    let class_size = ldexp(params.top_cell, -i32(class_shift(level)));
    // A partner at `level` has r_j ≤ max_radius (padded on the host) and r_j·level_pad ≤ class_size / 2.
    // Coordinates in cells are within ~2^-11 cells of exact for up to 4096 cells per axis; the
    // window is widened by 1/256 cell, and clamping to the border cells keeps it monotone (the
    // clamped outliers stay in it), as cell_coords is. A DEM step that walks the cells of an
    // earlier binning (dem_grid_frictionless.wgsl) widens it by `window_slack`: a partner's
    // binned centre then lies within it too.
    let reach = (s.w + min(params.max_radius, 0.5 * class_size) + window_slack) * inv + 1.0 / 256.0;
    let dims = level_dims(level);
    let u = (s.xyz - params.lo) * inv;
    let cells = reach_cells(u, reach, dims);
    let lo = cells[0];
    let span = cells[1] - lo + vec3(1u);
    return Window(dense_key(lo, level), span.x, span.y, span.y * span.z, dims, lo);
}
