// The grid's parameters and cell functions, shared by grid_build.wgsl, cell_scan.wgsl,
// grid_pairs.wgsl and dem_grid.wgsl (the last two with grid_stencil.wgsl, which searches the
// cells). Twin of GridParams in src/engines/wgpu_compute/layout.rs (tests/bindings.rs compares
// the layouts).
//
// A grid has one level (cells of the largest proxy; its table dense or hashed) or several dense
// levels (the multi-level proxy grid of docs/method.md): level `levels - 1` is the top, whose
// class of radii is sized by `top_cell`, and every level below halves the class's size. A sphere
// lives at the finest level whose class size holds its proxy (or the finest level there is) and
// meets its partners there (half stencil) and at every coarser level (the cells within its reach),
// where only it, the smaller sphere, looks for the pair. A level's table may have cells finer than
// its class (`refine`): its search windows then span more, smaller cells.
struct GridParams {
    lo: vec3<f32>,      // lower corner of the centres' bounding box
    n: u32,             // number of spheres
    inv_cell: f32,      // 1 / cell side of the top (coarsest) level
    nx: u32,            // top-level cells along x, margin included
    ny: u32,            // top-level cells along y, margin included
    nz: u32,            // top-level cells along z, margin included
    cells: u32,         // dense: cells of all levels; hashed: number of buckets (a power of two)
    row: u32,           // invocations per dispatch row (2-D dispatch)
    capacity: u32,      // room in the pair buffer (detection only)
    hashed: u32,        // 0: dense tables; 1: one level, cells hashed into `cells` buckets
    levels: u32,        // 1: single grid; more: multi-level grid (dense), class sizes halving downwards
    top_cell: f32,      // class size of the top level (its cell side unless `refine` halves it)
    level_pad: f32,     // 1 + relative padding: sphere i lives where class size ≥ 2·r_i·level_pad
    block_shift: u32,   // the table's blocks for the scan (cell_scan.wgsl): 1 << block_shift entries
    max_radius: f32,    // largest radius, padded (grid_stencil.wgsl's windows)
    refine: u32,        // 4 bits a level (level k at bits 4k..4k+3): halvings of its cells below its class size
    skin: f32,          // DEM step: how far a sphere may move before its grid is re-binned (0: every step)
    level_first: array<vec4<u32>, 2>, // dense: table index of each level's first cell
}

// Level of a sphere of radius r: the finest level whose class size is at least 2·r·level_pad (so
// a partner's reach at that level is at most half the class size). Monotone in r.
fn level_of(r: f32) -> u32 {
    let top = i32(params.levels) - 1;
    if top == 0 {
        return 0u;
    }
    let need = 2.0 * r * params.level_pad;
    var shift = clamp(i32(floor(log2(params.top_cell / need))), 0, top);
    while shift > 0 && ldexp(params.top_cell, -shift) < need {
        shift -= 1;
    }
    while shift < top && ldexp(params.top_cell, -(shift + 1)) >= need {
        shift += 1;
    }
    return u32(top - shift);
}

// Halvings of `level`'s class size below the top's (`top_cell`).
fn class_shift(level: u32) -> u32 {
    return params.levels - 1u - level;
}

// Halvings of `level`'s cells below `top_cell`: its class's, refined.
fn cell_shift(level: u32) -> u32 {
    return class_shift(level) + ((params.refine >> (4u * level)) & 15u);
}

// Cells of `level` along each axis, margin included.
fn level_dims(level: u32) -> vec3<u32> {
    let shift = cell_shift(level);
    return ((vec3(params.nx, params.ny, params.nz) - vec3(2u)) << vec3(shift)) + vec3(2u);
}

// Cell of a centre at `level`, margin included (1 ..= n - 2 on each axis of that level).
fn cell_coords(c: vec3<f32>, level: u32) -> vec3<u32> {
    let shift = cell_shift(level);
    let u = max((c - params.lo) * ldexp(params.inv_cell, i32(shift)), vec3(0.0));
    return min(vec3<u32>(u), level_dims(level) - vec3(3u)) + vec3(1u);
}

// Bucket of a cell in the hashed table (coordinates may have wrapped: they then match no sphere).
fn hash_cell(cell: vec3<u32>) -> u32 {
    let h = (cell.x * 73856093u) ^ (cell.y * 19349663u) ^ (cell.z * 83492791u);
    return h & (params.cells - 1u);
}

// Table index of a cell of `level` in the dense tables.
fn dense_key(cell: vec3<u32>, level: u32) -> u32 {
    let dims = level_dims(level);
    return params.level_first[level / 4u][level % 4u] + cell.x + dims.x * (cell.y + dims.y * cell.z);
}

// Table entry of a sphere: its cell in the dense tables, or the bucket of its cell.
fn cell_key(s: vec4<f32>) -> u32 {
    let level = level_of(s.w);
    let cell = cell_coords(s.xyz, level);
    if params.hashed != 0u {
        return hash_cell(cell);
    }
    return dense_key(cell, level);
}
