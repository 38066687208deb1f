// The grid's parameters, shared by grid_build.wgsl and grid_pairs.wgsl.
// Keep in sync with GridParams in src/backend/wgpu_compute/mod.rs.
struct GridParams {
    lo: vec3<f32>,      // lower corner of the centres' bounding box
    n: u32,             // number of spheres
    inv_cell: f32,      // 1 / cell side
    nx: u32,            // cells along x, margin included
    ny: u32,            // cells along y, margin included
    nz: u32,            // cells along z, margin included
    cells: u32,         // nx·ny·nz
    row: u32,           // invocations per dispatch row (2-D dispatch)
    capacity: u32,      // room in the pair buffer (detection only)
    _pad0: u32,
}
