// The middle step of the grids' counting sort: the cell counts scanned into the cell table, in two
// dispatches. Host side: src/engines/wgpu_compute/cell_table.rs. Needs grid_params.wgsl prepended
// and one of workgroup_scan_plain.wgsl or workgroup_scan_subgroups.wgsl (`SubgroupLanes`,
// `scan_kind`, `workgroup_scan`) appended, then workgroup_scan.wgsl.
//
// The table's cells + 1 entries are cut into blocks of `1 << params.block_shift` entries (at most
// MAX_BLOCKS blocks, each a whole number of TILEs). `reduce_blocks` sums each block's counts;
// `scan_cells` has workgroup b add up the sums of the blocks before it and scan its own block
// tile by tile: cell_start[k] = spheres in the cells before k (the last entry is n). It zeroes the
// counts it reads, so the next build needs no clear. Both move the table as vec4 (the buffers hold
// a multiple of 4 entries; entries past cells + 1 are zero counts and unused starts).

@group(0) @binding(0) var<uniform> params: GridParams;
@group(0) @binding(1) var<storage, read_write> counts: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read_write> block_sums: array<u32>;
@group(0) @binding(3) var<storage, read_write> cell_start: array<vec4<u32>>;

const WG: u32 = 256u;        // threads per workgroup
const TILE: u32 = 1024u;     // entries per tile: one vec4 per thread

// Table entries of `block`, in vec4 units: (first, end).
fn block_range(block: u32) -> vec2<u32> {
    let len4 = (params.cells + 4u) / 4u; // cells + 1 entries, rounded up
    let first = (block << params.block_shift) / 4u;
    return vec2(first, min(first + (1u << params.block_shift) / 4u, len4));
}

// The counts of table entries k..k+3 (vec4 index k) below `end`, zero past it.
fn tile_counts(k: u32, end: u32) -> vec4<u32> {
    if k < end {
        return counts[k];
    }
    return vec4(0u);
}

@compute @workgroup_size(256)
fn reduce_blocks(
    @builtin(local_invocation_index) t: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    lanes: SubgroupLanes,
) {
    let scan = scan_kind(t, lanes);
    let range = block_range(wid.x);
    // Four tiles' loads in flight at once where the block has them.
    var sums = vec4(0u);
    var k = range.x + t;
    for (; k + 3u * WG < range.y; k += 4u * WG) {
        sums += counts[k] + counts[k + WG] + counts[k + 2u * WG] + counts[k + 3u * WG];
    }
    for (; k < range.y; k += WG) {
        sums += counts[k];
    }
    let total = workgroup_scan(t, sums.x + sums.y + sums.z + sums.w, lanes, scan).y;
    if t == 0u {
        block_sums[wid.x] = total;
    }
}

@compute @workgroup_size(256)
fn scan_cells(
    @builtin(local_invocation_index) t: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    lanes: SubgroupLanes,
) {
    let scan = scan_kind(t, lanes);
    let block = wid.x;
    let range = block_range(block);
    // Each tile's counts are fetched a step ahead: the first's while the blocks before are
    // added up, the next's while this one is scanned.
    var c = tile_counts(range.x + t, range.y);
    var carried = 0u;
    for (var k = t; k < block; k += WG) {
        carried += block_sums[k];
    }
    var base = workgroup_scan(t, carried, lanes, scan).y;

    for (var tile = range.x; tile < range.y; tile += WG) {
        let k = tile + t;
        let next = tile_counts(k + WG, range.y);
        if k < range.y {
            counts[k] = vec4(0u);
        }
        let before = vec4(0u, c.x, c.x + c.y, c.x + c.y + c.z);
        let sum = before.w + c.w;
        let scanned = workgroup_scan(t, sum, lanes, scan);
        if k < range.y {
            cell_start[k] = vec4(base + scanned.x - sum) + before;
        }
        base += scanned.y;
        c = next;
    }
}
