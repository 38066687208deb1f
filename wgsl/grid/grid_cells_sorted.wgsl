// Runs of cells in the sorted-key build (grid_sort.wgsl, dem_grid_sorted.wgsl): the spheres
// sorted by their table entries, which `cell_keys` holds in that order, so the spheres whose
// entries lie in first..end are one run of sorted positions, found by binary search. No table
// spans the grid. Twin: grid_cells_dense.wgsl (the same function over the dense table). Needs
// grid_params.wgsl (`params.n`).
//
// A run's start costs a binary search over all n keys (its first steps read the same few keys in
// every thread, so they hit the cache); its end, a few cells later, a galloping search from there.

@group(0) @binding(41) var<storage, read> cell_keys: array<u32>;

// First sorted position in lo..hi whose key is at least `key` (hi if none).
fn first_key_at_least(key: u32, lo: u32, hi: u32) -> u32 {
    var a = lo;
    var b = hi;
    while a < b {
        let mid = a + (b - a) / 2u;
        if cell_keys[mid] < key {
            a = mid + 1u;
        } else {
            b = mid;
        }
    }
    return a;
}

// First sorted position from `start` on whose key is at least `key`, where every key before
// `start` is below it: steps of 1, 2, 4, ... bound it, then a binary search finds it.
fn gallop_to_key(key: u32, start: u32) -> u32 {
    var lo = start;
    var hi = start;
    var step = 1u;
    while hi < params.n && cell_keys[hi] < key {
        lo = hi + 1u;
        hi = min(hi + step, params.n);
        step *= 2u;
    }
    return first_key_at_least(key, lo, hi);
}

fn cell_run(first: u32, end: u32) -> vec2<u32> {
    let a = first_key_at_least(first, 0u, params.n);
    return vec2(a, gallop_to_key(end, a));
}
