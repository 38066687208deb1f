// The sorted-key binning of the wgpu-compute DEM step (dem_grid.wgsl's state and bindings,
// grid_cells_sorted.wgsl's search): `bin_keys` gives every sphere of set a its cell key beside
// its index, the radix sort (src/gpu/radix_sort.rs) sorts them by key, and `bin_gather` moves
// set a into the sorted set in that order. No table spans the grid, so the binning costs by
// the spheres, not by the cells. Appended after dem_grid.wgsl.

// Cell key and index of each sphere of set a, in set a's order (the sort's input).
@group(0) @binding(40) var<storage, read_write> sort_keys: array<u32>;
@group(0) @binding(42) var<storage, read_write> sort_order: array<u32>;

// Sorted-key binning, first pass: keys and indices to sort (and the step's counters).
@compute @workgroup_size(256)
fn bin_keys(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = index(gid);
    start_step(i);
    if i >= params.n {
        return;
    }
    sort_keys[i] = cell_key(pos_a[i]);
    sort_order[i] = i;
}

// Sorted-key binning, last pass (after the sort, `sort_order` bound to the sorted indices):
// set a → sorted set, with the resolve file's per-sphere state carried along (as bin_scatter
// does).
@compute @workgroup_size(256)
fn bin_gather(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = index(gid);
    if p >= params.n {
        return;
    }
    let i = sort_order[p];
    ids[p] = ids_a[i];
    pos[p] = pos_a[i];
    pos_lo[p] = pos_lo_a[i];
    vel[p] = vel_a[i];
    carry(i, p);
}
