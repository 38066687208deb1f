//! The sorted proxy grid: spheres binned into cubic cells and reordered by cell key.
//!
//! Cells are at least as large as the grid's `cell_size` (the caller passes 2·r_max in `mochi`
//! mode, 4·r_max in `nns` mode), so every colliding pair lies in the same or in neighbouring
//! cells. Keys are linear, `x + nx·(y + ny·z)`, over a grid with one empty cell of margin on every
//! side, so the key of a neighbour is the key of the cell plus a constant: that is what lets the
//! query walk the sorted keys with pointers that only move forward. A layout of few cells per
//! sphere is sorted by counting instead, which leaves a table of each cell's first sphere.

use crate::spheres::SphereSet;
use rayon::prelude::*;

/// Most cells along one axis (margin included): 3 × 21 bits keep every key below 2⁶³.
const MAX_AXIS_CELLS: u64 = 1 << 21;

/// Relative padding of the cell size, far above the rounding of `f32` distances and of the
/// `f64` cell coordinates, so that a pair the `f32` narrow phase accepts is never two cells apart.
const CELL_PADDING: f64 = 1.0 / (1u64 << 20) as f64;

/// Spheres sorted by cell.
#[derive(Debug, Default)]
pub(crate) struct SortedGrid {
    /// Cell key of each sorted sphere (non-decreasing).
    pub keys: Vec<u64>,
    /// `[x, y, z, r]` of each sorted sphere.
    pub spheres: Vec<[f32; 4]>,
    /// Input index of each sorted sphere.
    pub ids: Vec<u32>,
    /// Cells along x and y, margin included.
    dims: [u64; 2],
    /// (key, input index) scratch of the radix sort, kept to avoid reallocation.
    order: Vec<(u64, u32)>,
    /// The first sorted position of every cell key, one past the last cell included, where
    /// the layout has at most [`DENSE_CELLS_PER_SPHERE`] cells per sphere (the spheres then
    /// sorted by counting); else empty (sorted by radix, runs found by walking the keys).
    pub starts: Vec<u32>,
    /// Scratch of the counting sort, kept to avoid reallocation: for each piece of the input,
    /// its (key, input index) entries by range of cells ([`SortedGrid::sort_by_counting`]).
    ranges: Vec<Vec<Vec<[u32; 2]>>>,
}

/// Cells per sphere up to which a grid keeps a table of cell starts ([`SortedGrid::starts`]).
const DENSE_CELLS_PER_SPHERE: u64 = 8;

/// Ranges of cells per thread that [`SortedGrid::sort_by_counting`] places in parallel: enough
/// that the threads share the work evenly where the spheres crowd into few cells.
const RANGES_PER_THREAD: usize = 16;
/// Pieces of the input per thread that list their entries by range, and the fewest spheres a
/// piece has.
const PIECES_PER_THREAD: usize = 4;
const MIN_PIECE: usize = 4096;

impl SortedGrid {
    /// Bins `spheres` into cells of side at least `cell_size`.
    pub fn bin(&mut self, spheres: &SphereSet, cell_size: f32) {
        match spheres.bounds() {
            Some((lo, hi)) => {
                self.bin_within(spheres.centers(), spheres.radii(), lo, hi, cell_size)
            }
            None => self.bin_within(&[], &[], [0.0; 3], [0.0; 3], cell_size),
        }
    }

    /// Bins spheres whose centres lie within `lo..=hi` (finite; centres outside are clamped to
    /// the nearest cell, which keeps the search exact, only slower).
    pub fn bin_within(
        &mut self,
        centers: &[[f32; 3]],
        radii: &[f32],
        lo: [f32; 3],
        hi: [f32; 3],
        cell_size: f32,
    ) {
        let cells = cell_layout(lo, hi, cell_size);
        let [nx, ny] = [cells.counts[0] + 2, cells.counts[1] + 2];
        self.dims = [nx, ny];

        let all_cells = nx * ny * (cells.counts[2] + 2);
        let key = |c: &[f32; 3]| cells.key(c, lo, nx, ny);
        match all_cells <= DENSE_CELLS_PER_SPHERE * (centers.len() as u64).max(1) {
            true => self.sort_by_counting(centers, radii, all_cells as usize, key),
            false => self.sort_by_radix(centers, radii, key),
        }
    }

    /// Sorts the spheres by `key`, stably, into [`Self::keys`], [`Self::ids`] and
    /// [`Self::spheres`], by radix: no table of cells ([`Self::starts`] left empty).
    fn sort_by_radix(
        &mut self,
        centers: &[[f32; 3]],
        radii: &[f32],
        key: impl Fn(&[f32; 3]) -> u64 + Sync,
    ) {
        centers
            .par_iter()
            .enumerate()
            .map(|(i, c)| (key(c), i as u32))
            .collect_into_vec(&mut self.order);
        self.starts.clear();
        radsort::sort_by_key(&mut self.order, |e| e.0);

        let order = &self.order;
        order
            .par_iter()
            .map(|e| e.0)
            .collect_into_vec(&mut self.keys);
        order
            .par_iter()
            .map(|e| e.1)
            .collect_into_vec(&mut self.ids);
        order
            .par_iter()
            .map(|&(_, i)| {
                let c = centers[i as usize];
                [c[0], c[1], c[2], radii[i as usize]]
            })
            .collect_into_vec(&mut self.spheres);
    }

    /// Sorts the spheres by `key` (below `cells`), stably, into [`Self::keys`], [`Self::ids`]
    /// and [`Self::spheres`], counting the spheres of each cell into [`Self::starts`] on the
    /// way: linear in spheres and cells, in parallel. Each piece of the input lists its entries
    /// by range of cells ([`Self::ranges`]); then each range is counted and placed on its own,
    /// into the part of the output its cells own, taking the pieces in input order.
    fn sort_by_counting(
        &mut self,
        centers: &[[f32; 3]],
        radii: &[f32],
        cells: usize,
        key: impl Fn(&[f32; 3]) -> u64 + Sync,
    ) {
        let n = centers.len();
        let threads = rayon::current_num_threads();
        let shift = cells
            .div_ceil(RANGES_PER_THREAD * threads)
            .next_power_of_two()
            .trailing_zeros();
        let ranges = cells.div_ceil(1 << shift);
        let piece = n.div_ceil(PIECES_PER_THREAD * threads).max(MIN_PIECE);
        self.ranges.resize_with(n.div_ceil(piece), Vec::new);
        self.ranges
            .par_iter_mut()
            .enumerate()
            .for_each(|(k, listed)| {
                listed.resize_with(ranges, Vec::new);
                listed.iter_mut().for_each(Vec::clear);
                let first = k * piece;
                for (i, c) in centers[first..(first + piece).min(n)].iter().enumerate() {
                    let key = key(c);
                    let within = (key & ((1 << shift) - 1)) as u32;
                    listed[(key >> shift) as usize].push([within, (first + i) as u32]);
                }
            });

        self.keys.resize(n, 0);
        self.ids.resize(n, 0);
        self.spheres.resize(n, [0.0; 4]);
        self.starts.resize(cells + 1, 0);
        self.starts[cells] = n as u32;
        let mut parts = Vec::with_capacity(ranges);
        let (mut keys, mut ids, mut spheres) =
            (&mut self.keys[..], &mut self.ids[..], &mut self.spheres[..]);
        let mut starts = &mut self.starts[..cells];
        let mut placed = 0;
        for r in 0..ranges {
            let size: usize = self.ranges.iter().map(|listed| listed[r].len()).sum();
            let span = (1usize << shift).min(starts.len());
            let (k, rest_k) = std::mem::take(&mut keys).split_at_mut(size);
            let (i, rest_i) = std::mem::take(&mut ids).split_at_mut(size);
            let (s, rest_s) = std::mem::take(&mut spheres).split_at_mut(size);
            let (t, rest_t) = std::mem::take(&mut starts).split_at_mut(span);
            parts.push((r, placed, k, i, s, t));
            (keys, ids, spheres, starts) = (rest_k, rest_i, rest_s, rest_t);
            placed += size;
        }
        let listed = &self.ranges;
        parts
            .into_par_iter()
            .for_each(|(r, placed, keys, ids, spheres, starts)| {
                let first_cell = (r << shift) as u64;
                let entries = || listed.iter().flat_map(|l| &l[r]);
                starts.fill(0);
                for &[within, _] in entries() {
                    starts[within as usize] += 1;
                }
                let mut next = 0;
                let mut cursor: Vec<u32> = starts
                    .iter_mut()
                    .map(|start| {
                        let here = next;
                        next += *start;
                        *start = here + placed as u32;
                        here
                    })
                    .collect();
                for &[within, i] in entries() {
                    let place = &mut cursor[within as usize];
                    let at = *place as usize;
                    *place += 1;
                    let c = centers[i as usize];
                    keys[at] = first_cell + within as u64;
                    ids[at] = i;
                    spheres[at] = [c[0], c[1], c[2], radii[i as usize]];
                }
            });
    }

    /// Key distances from a cell to the first cell (x − 1) of each of its nine neighbour rows
    /// (y − 1 ..= y + 1, z − 1 ..= z + 1, its own included), as wrapping offsets: the margin
    /// keeps every sum non-negative.
    pub fn all_row_offsets(&self) -> [u64; 9] {
        let [nx, ny] = self.dims;
        let plane = nx * ny;
        std::array::from_fn(|k| {
            let (dy, dz) = ((k % 3) as u64, (k / 3) as u64);
            (dy * nx + dz * plane).wrapping_sub(nx + plane + 1)
        })
    }

    /// Key distances from a cell to the first cell (x − 1) of its four forward neighbour rows:
    /// (y+1, z), (y−1, z+1), (y, z+1), (y+1, z+1). Each row spans three keys from there.
    pub fn forward_row_offsets(&self) -> [u64; 4] {
        let [nx, ny] = self.dims;
        let plane = nx * ny;
        [nx - 1, plane - nx - 1, plane - 1, plane + nx - 1]
    }
}

/// Cell size and counts for centres within `lo..=hi`.
struct CellLayout {
    inv_size: f64,
    /// Occupied-range cells per axis (margin excluded).
    counts: [u64; 3],
}

impl CellLayout {
    #[inline(always)]
    fn key(&self, c: &[f32; 3], lo: [f32; 3], nx: u64, ny: u64) -> u64 {
        let cell = |a: usize| {
            let u = (c[a] as f64 - lo[a] as f64) * self.inv_size;
            (u as i64).clamp(0, self.counts[a] as i64 - 1) as u64 + 1
        };
        cell(0) + nx * (cell(1) + ny * cell(2))
    }
}

fn cell_layout(lo: [f32; 3], hi: [f32; 3], cell_size: f32) -> CellLayout {
    let extent = std::array::from_fn::<f64, 3, _>(|a| hi[a] as f64 - lo[a] as f64);
    let widest = extent.iter().copied().fold(0.0, f64::max);
    let mut size = cell_size as f64 * (1.0 + CELL_PADDING);
    // Larger cells stay exact (only slower); they keep the keys within 63 bits.
    size = size.max(widest / (MAX_AXIS_CELLS - 3) as f64);
    let counts = std::array::from_fn(|a| (extent[a] / size) as u64 + 1);
    CellLayout {
        inv_size: 1.0 / size,
        counts,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_counting_sort_in_pieces_and_ranges_is_the_stable_radix_sort() {
        // Enough spheres for several pieces of the input and many ranges of cells, some cells
        // holding several spheres (whose input order a stable sort keeps).
        let n = 20_000;
        let mut state = 99u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let centers: Vec<[f32; 3]> = (0..n)
            .map(|_| [next() * 20.0, next() * 20.0, next() * 20.0])
            .collect();
        let radii: Vec<f32> = (0..n).map(|_| 0.2 + 0.3 * next()).collect();
        let (lo, hi) = ([0.0; 3], [20.0; 3]);
        let mut counted = SortedGrid::default();
        counted.bin_within(&centers, &radii, lo, hi, 1.0);
        assert!(
            !counted.starts.is_empty(),
            "a dense layout is sorted by counting"
        );
        assert!(n > 2 * MIN_PIECE, "several pieces");

        let cells = cell_layout(lo, hi, 1.0);
        let [nx, ny] = counted.dims;
        let mut radix = SortedGrid::default();
        radix.sort_by_radix(&centers, &radii, |c| cells.key(c, lo, nx, ny));
        assert_eq!(counted.keys, radix.keys);
        assert_eq!(counted.ids, radix.ids);
        assert_eq!(counted.spheres, radix.spheres);
        assert!(
            counted.keys.windows(2).any(|k| k[0] == k[1]),
            "shared cells"
        );
        for (cell, run) in counted.starts.windows(2).enumerate() {
            let first = counted.keys.partition_point(|&k| k < cell as u64);
            let end = counted.keys.partition_point(|&k| k <= cell as u64);
            assert_eq!(run, [first as u32, end as u32], "cell {cell}");
        }
    }
}
