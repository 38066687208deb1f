// The grid's parameters and cell functions, shared by grid_build.wgsl and grid_pairs.wgsl.
// Keep in sync with GridParams in src/backend/wgpu_compute/mod.rs.
struct GridParams {
    lo: vec3<f32>,      // lower corner of the centres' bounding box
    n: u32,             // number of spheres
    inv_cell: f32,      // 1 / cell side
    nx: u32,            // cells along x, margin included
    ny: u32,            // cells along y, margin included
    nz: u32,            // cells along z, margin included
    cells: u32,         // dense: nx·ny·nz; hashed: number of buckets (a power of two)
    row: u32,           // invocations per dispatch row (2-D dispatch)
    capacity: u32,      // room in the pair buffer (detection only)
    hashed: u32,        // 0: dense table over the grid; 1: cells hashed into `cells` buckets
}

// Cell of a centre, margin included (1 ..= n - 2 on each axis).
fn cell_coords(c: vec3<f32>) -> vec3<u32> {
    let u = max((c - params.lo) * params.inv_cell, vec3(0.0));
    let top = vec3(params.nx, params.ny, params.nz) - vec3(3u);
    return min(vec3<u32>(u), top) + vec3(1u);
}

// Bucket of a cell in the hashed table (coordinates may have wrapped: they then match no sphere).
fn hash_cell(cell: vec3<u32>) -> u32 {
    return ((cell.x * 73856093u) ^ (cell.y * 19349663u) ^ (cell.z * 83492791u)) & (params.cells - 1u);
}

// Table entry of a centre's cell: linear key of the dense grid, or bucket of the hashed one.
fn cell_key(c: vec3<f32>) -> u32 {
    let cell = cell_coords(c);
    if params.hashed != 0u {
        return hash_cell(cell);
    }
    return cell.x + params.nx * (cell.y + params.ny * cell.z);
}
