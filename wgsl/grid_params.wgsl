// The grid's parameters and cell functions, shared by grid_build.wgsl and grid_pairs.wgsl.
// Keep in sync with GridParams in src/backend/wgpu_compute/mod.rs.
struct GridParams {
    lo: vec3<f32>,      // lower corner of the centres' bounding box
    n: u32,             // number of spheres
    inv_cell: f32,      // 1 / cell side of the top (coarsest) level
    nx: u32,            // top-level cells along x, margin included
    ny: u32,            // top-level cells along y, margin included
    nz: u32,            // top-level cells along z, margin included
    cells: u32,         // dense: nx·ny·nz; hashed: number of buckets (a power of two)
    row: u32,           // invocations per dispatch row (2-D dispatch)
    capacity: u32,      // room in the pair buffer (detection only)
    hashed: u32,        // 0: dense table over the grid; 1: cells hashed into `cells` buckets
    levels: u32,        // 1: single grid; K + 1: multi-level grid (hashed), cells halving downwards
    top_cell: f32,      // cell side of the top level
    level_pad: f32,     // 1 + relative padding: sphere i lives where cell ≥ 2·r_i·level_pad
    _pad0: u32,
}

// Level of a sphere of radius r: the finest level whose cells are at least 2·r·level_pad (so a
// partner of a sphere at or below that level lies in the 27 cells around it). Monotone in r.
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

// Cell of a centre at `level`, margin included (1 ..= n - 2 on each axis of that level).
fn cell_coords(c: vec3<f32>, level: u32) -> vec3<u32> {
    let shift = params.levels - 1u - level;
    let u = max((c - params.lo) * ldexp(params.inv_cell, i32(shift)), vec3(0.0));
    let top = ((vec3(params.nx, params.ny, params.nz) - vec3(2u)) << vec3(shift)) - vec3(1u);
    return min(vec3<u32>(u), top) + vec3(1u);
}

// Bucket of a cell of `level` in the hashed table (coordinates may have wrapped: they then match
// no sphere).
fn hash_cell(cell: vec3<u32>, level: u32) -> u32 {
    let h = (cell.x * 73856093u) ^ (cell.y * 19349663u) ^ (cell.z * 83492791u) ^ (level * 2654435761u);
    return h & (params.cells - 1u);
}

// Table entry of a sphere: linear key of its cell in the dense grid, or bucket of its cell and
// level in the hashed one.
fn cell_key(s: vec4<f32>) -> u32 {
    let level = level_of(s.w);
    let cell = cell_coords(s.xyz, level);
    if params.hashed != 0u {
        return hash_cell(cell, level);
    }
    return cell.x + params.nx * (cell.y + params.ny * cell.z);
}
