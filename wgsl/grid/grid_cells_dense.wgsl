// Runs of cells in the dense build's table (grid_build.wgsl, cell_scan.wgsl): the sorted
// positions of the spheres whose table entries lie in first..end. Appended after
// grid_stencil.wgsl by the searches of the dense build; the including shader binds `cell_start`.
// Twin: grid_cells_sorted.wgsl (the same function over sorted keys).

fn cell_run(first: u32, end: u32) -> vec2<u32> {
    return vec2(cell_start[first], cell_start[end]);
}
