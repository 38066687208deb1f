// Sorted-key build stage of the wgpu-compute backend: every sphere's cell key (its table entry,
// cell_key in grid_params.wgsl) beside its input index, for the radix sort
// (src/gpu/radix_sort.rs) to sort by key; grid_build.wgsl's `gather` then fetches the spheres in
// that order, and the search finds runs of cells in the sorted keys (grid_cells_sorted.wgsl).
// No table spans the grid: the build costs by the spheres, not by the cells. Needs
// grid_params.wgsl prepended.

@group(0) @binding(0) var<uniform> params: GridParams;
@group(0) @binding(1) var<storage, read> spheres_in: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> keys: array<u32>;
@group(0) @binding(7) var<storage, read_write> ids: array<u32>;

@compute @workgroup_size(256)
fn key_spheres(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * params.row;
    if i >= params.n {
        return;
    }
    keys[i] = cell_key(spheres_in[i]);
    ids[i] = i;
}
