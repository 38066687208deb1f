//! The sorted proxy grid: spheres binned into cubic cells and reordered by cell key.
//!
//! Cells are at least as large as the grid's `cell_size` (the caller passes 2·r_max in `mochi`
//! mode, 4·r_max in `nns` mode), so every colliding pair lies in the same or in neighbouring
//! cells. Keys are linear, `x + nx·(y + ny·z)`, over a grid with one empty cell of margin on every
//! side, so the key of a neighbour is the key of the cell plus a constant: that is what lets the
//! query walk the sorted keys with pointers that only move forward. A layout of few cells per
//! sphere is sorted by counting instead, which leaves a table of each cell's first sphere.

use crate::error::{Result, try_push, try_resize, try_vec};
use crate::spheres::Spheres;
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
    /// (key, input index) entries of the radix sort, each range's sorted in its part; kept to
    /// avoid reallocation.
    order: Vec<(u64, u32)>,
    /// The first sorted position of every cell key, one past the last cell included, where
    /// the layout has at most [`DENSE_CELLS_PER_SPHERE`] cells per sphere (the spheres then
    /// sorted by counting); else empty (sorted by radix, runs found by walking the keys).
    pub starts: Vec<u32>,
    /// Scratch of the counting sort, kept to avoid reallocation: for each piece of the input,
    /// its (key within the range, input index) entries by range of cells
    /// ([`SortedGrid::sort_by_counting`]).
    ranges: Vec<Vec<Vec<[u32; 2]>>>,
    /// The same for the radix sort: (key, input index) entries by range of keys.
    wide: Vec<Vec<Vec<(u64, u32)>>>,
}

/// Cells per sphere up to which a grid keeps a table of cell starts ([`SortedGrid::starts`]).
const DENSE_CELLS_PER_SPHERE: u64 = 8;

/// Ranges of cells (or keys) per thread that the sorts place in parallel: enough that the
/// threads share the work evenly where the spheres crowd into few cells.
const RANGES_PER_THREAD: usize = 16;
/// Pieces of the input per thread that list their entries by range, and the fewest spheres a
/// piece has.
const PIECES_PER_THREAD: usize = 4;
const MIN_PIECE: usize = 4096;
/// Keys sampled per range of [`SortedGrid::sort_by_radix`] to place its boundaries.
const SAMPLES_PER_RANGE: usize = 32;

impl SortedGrid {
    /// Bins `spheres` into cells of side at least `cell_size`. Memory that cannot be had is
    /// [`crate::Error::OutOfMemory`], and leaves the grid to be binned again before it is searched.
    pub fn bin(&mut self, spheres: Spheres<'_>, cell_size: f32) -> Result<()> {
        match spheres.bounds() {
            Some((lo, hi)) => {
                let anchor = lo.map(f64::from);
                self.bin_within(
                    spheres.centers(),
                    spheres.radii(),
                    (lo, hi),
                    anchor,
                    cell_size,
                )
            }
            None => self.bin_within(&[], &[], ([0.0; 3], [0.0; 3]), [0.0; 3], cell_size),
        }
    }

    /// Bins spheres whose centres lie within `lo..=hi` (finite; centres outside are clamped to
    /// the nearest cell, which keeps the search exact, only slower) into the cells of a lattice
    /// with a corner at `anchor`: a sphere's cell is a function of its centre, the anchor and
    /// the cell size alone, whatever the bounds (so the order in which a sphere meets its
    /// neighbours is too, while the lattice has fewer than 2²¹ cells along each axis). Every
    /// allocation is fallible, as for [`Self::bin`].
    pub fn bin_within(
        &mut self,
        centers: &[[f32; 3]],
        radii: &[f32],
        (lo, hi): ([f32; 3], [f32; 3]),
        anchor: [f64; 3],
        cell_size: f32,
    ) -> Result<()> {
        let cells = cell_layout(lo, hi, anchor, cell_size);
        let [nx, ny] = [cells.counts[0] + 2, cells.counts[1] + 2];
        self.dims = [nx, ny];

        let all_cells = nx * ny * (cells.counts[2] + 2);
        let key = |c: &[f32; 3]| cells.key(c, nx, ny);
        match all_cells <= DENSE_CELLS_PER_SPHERE * (centers.len() as u64).max(1) {
            true => self.sort_by_counting(centers, radii, all_cells as usize, key),
            false => self.sort_by_radix(centers, radii, key),
        }
    }

    /// Sorts the spheres by `key`, stably, into [`Self::keys`], [`Self::ids`] and
    /// [`Self::spheres`], in parallel: no table of cells ([`Self::starts`] left empty). The
    /// keys are split into ranges at quantiles of a sample of them; each piece of the input
    /// lists its entries by range ([`Self::wide`]), then each range gathers its entries (the
    /// pieces in input order) into its part of [`Self::order`], sorts them there by radix
    /// (stably) and writes them out.
    fn sort_by_radix(
        &mut self,
        centers: &[[f32; 3]],
        radii: &[f32],
        key: impl Fn(&[f32; 3]) -> u64 + Sync,
    ) -> Result<()> {
        let n = centers.len();
        self.starts.clear();
        let wanted = RANGES_PER_THREAD * rayon::current_num_threads();
        let stride = (n / (wanted * SAMPLES_PER_RANGE)).max(1);
        let mut sample: Vec<u64> = centers.par_iter().step_by(stride).map(&key).collect();
        sample.sort_unstable();
        let mut splitters: Vec<u64> = (1..wanted)
            .filter_map(|k| sample.get(k * sample.len() / wanted).copied())
            .collect();
        splitters.dedup();
        let range_of = |key: u64| splitters.partition_point(|&s| s <= key);
        let ranges = splitters.len() + 1;
        list_by_range(&mut self.wide, centers, ranges, |i, c| {
            let key = key(c);
            (range_of(key), (key, i))
        })?;

        let sizes = range_sizes(&self.wide, ranges);
        try_resize(&mut self.order, n, (0, 0), || grid_of("sort entries", n))?;
        self.resize_sorted(n)?;
        let wide = &self.wide;
        split_by(&mut self.order, &sizes)
            .into_par_iter()
            .zip(split_by(&mut self.keys, &sizes))
            .zip(split_by(&mut self.ids, &sizes))
            .zip(split_by(&mut self.spheres, &sizes))
            .enumerate()
            .for_each(|(r, (((order, keys), ids), spheres))| {
                for (to, from) in order.iter_mut().zip(wide.iter().flat_map(|l| &l[r])) {
                    *to = *from;
                }
                radsort::sort_by_key(order, |e| e.0);
                for (at, &(key, i)) in order.iter().enumerate() {
                    let c = centers[i as usize];
                    keys[at] = key;
                    ids[at] = i;
                    spheres[at] = [c[0], c[1], c[2], radii[i as usize]];
                }
            });
        Ok(())
    }

    /// [`Self::keys`], [`Self::ids`] and [`Self::spheres`] sized for `n` spheres, fallibly.
    fn resize_sorted(&mut self, n: usize) -> Result<()> {
        try_resize(&mut self.keys, n, 0, || grid_of("cell keys", n))?;
        try_resize(&mut self.ids, n, 0, || grid_of("sphere indices", n))?;
        try_resize(&mut self.spheres, n, [0.0; 4], || {
            grid_of("sorted spheres", n)
        })
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
    ) -> Result<()> {
        let n = centers.len();
        let shift = cells
            .div_ceil(RANGES_PER_THREAD * rayon::current_num_threads())
            .next_power_of_two()
            .trailing_zeros();
        let ranges = cells.div_ceil(1 << shift);
        list_by_range(&mut self.ranges, centers, ranges, |i, c| {
            let key = key(c);
            (
                (key >> shift) as usize,
                [(key & ((1 << shift) - 1)) as u32, i],
            )
        })?;

        let sizes = range_sizes(&self.ranges, ranges);
        self.resize_sorted(n)?;
        try_resize(&mut self.starts, cells + 1, 0, || {
            grid_of("cell starts", cells + 1)
        })?;
        self.starts[cells] = n as u32;
        let spans: Vec<usize> = (0..ranges)
            .map(|r| (cells - (r << shift)).min(1 << shift))
            .collect();
        let firsts = sizes.iter().scan(0, |placed, &size| {
            *placed += size;
            Some(*placed - size)
        });
        let listed = &self.ranges;
        split_by(&mut self.keys, &sizes)
            .into_par_iter()
            .zip(split_by(&mut self.ids, &sizes))
            .zip(split_by(&mut self.spheres, &sizes))
            .zip(split_by(&mut self.starts[..cells], &spans))
            .zip(firsts.collect::<Vec<_>>())
            .enumerate()
            .try_for_each(|(r, ((((keys, ids), spheres), starts), placed))| {
                let first_cell = (r << shift) as u64;
                let entries = || listed.iter().flat_map(|l| &l[r]);
                starts.fill(0);
                for &[within, _] in entries() {
                    starts[within as usize] += 1;
                }
                let mut next = 0;
                let mut cursor: Vec<u32> = try_vec(starts.len(), || {
                    format!("the cpu grid's cursors for {} cells", starts.len())
                })?;
                cursor.extend(starts.iter_mut().map(|start| {
                    let here = next;
                    next += *start;
                    *start = here + placed as u32;
                    here
                }));
                for &[within, i] in entries() {
                    let place = &mut cursor[within as usize];
                    let at = *place as usize;
                    *place += 1;
                    let c = centers[i as usize];
                    keys[at] = first_cell + within as u64;
                    ids[at] = i;
                    spheres[at] = [c[0], c[1], c[2], radii[i as usize]];
                }
                Ok(())
            })
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

/// The grid's `what` for `n` items, in errors.
fn grid_of(what: &str, n: usize) -> String {
    format!("the cpu grid's {what} ({n})")
}

/// Lists the entries of `centers` by range, for a sort in parallel: `listed[k][r]` holds, in
/// input order, the entries `entry(i, c)` files under range `r` of the spheres of piece `k` of
/// the input (each piece on its own thread; the allocations of `listed` reused). Each list
/// grows fallibly.
fn list_by_range<E: Send>(
    listed: &mut Vec<Vec<Vec<E>>>,
    centers: &[[f32; 3]],
    ranges: usize,
    entry: impl Fn(u32, &[f32; 3]) -> (usize, E) + Sync,
) -> Result<()> {
    let n = centers.len();
    let piece = n
        .div_ceil(PIECES_PER_THREAD * rayon::current_num_threads())
        .max(MIN_PIECE);
    listed.resize_with(n.div_ceil(piece), Vec::new);
    listed.par_iter_mut().enumerate().try_for_each(|(k, mine)| {
        mine.resize_with(ranges, Vec::new);
        mine.iter_mut().for_each(Vec::clear);
        let first = k * piece;
        for (i, c) in centers[first..(first + piece).min(n)].iter().enumerate() {
            let (range, e) = entry((first + i) as u32, c);
            try_push(&mut mine[range], e, || {
                format!("the cpu grid's sort entries ({n} spheres)")
            })?;
        }
        Ok(())
    })
}

/// The entries of each of `ranges` ranges in `listed` (of [`list_by_range`]).
fn range_sizes<E>(listed: &[Vec<Vec<E>>], ranges: usize) -> Vec<usize> {
    (0..ranges)
        .map(|r| listed.iter().map(|mine| mine[r].len()).sum())
        .collect()
}

/// `all` cut into consecutive parts of `sizes` (which sum to at most its length).
fn split_by<'a, T>(all: &'a mut [T], sizes: &[usize]) -> Vec<&'a mut [T]> {
    let mut rest = all;
    sizes
        .iter()
        .map(|&size| {
            let (part, after) = std::mem::take(&mut rest).split_at_mut(size);
            rest = after;
            part
        })
        .collect()
}

/// The cells of a lattice that cover centres within `lo..=hi`.
struct CellLayout {
    inv_size: f64,
    /// The lattice's corner.
    anchor: [f64; 3],
    /// The lattice cell of the first cell along each axis.
    first: [i64; 3],
    /// Occupied-range cells per axis (margin excluded).
    counts: [u64; 3],
}

impl CellLayout {
    #[inline(always)]
    fn key(&self, c: &[f32; 3], nx: u64, ny: u64) -> u64 {
        let cell = |a: usize| {
            let u = ((c[a] as f64 - self.anchor[a]) * self.inv_size).floor() as i64;
            // Saturated where a centre lies beyond i64's cells (an exploding run's).
            (u.saturating_sub(self.first[a])).clamp(0, self.counts[a] as i64 - 1) as u64 + 1
        };
        cell(0) + nx * (cell(1) + ny * cell(2))
    }
}

fn cell_layout(lo: [f32; 3], hi: [f32; 3], anchor: [f64; 3], cell_size: f32) -> CellLayout {
    let extent = std::array::from_fn::<f64, 3, _>(|a| hi[a] as f64 - lo[a] as f64);
    let widest = extent.iter().copied().fold(0.0, f64::max);
    let mut size = cell_size as f64 * (1.0 + CELL_PADDING);
    // Larger cells stay exact (only slower); they keep the keys within 63 bits.
    size = size.max(widest / (MAX_AXIS_CELLS - 4) as f64);
    let inv_size = 1.0 / size;
    let lattice = |x: f32, a: usize| ((x as f64 - anchor[a]) * inv_size).floor() as i64;
    let first = std::array::from_fn(|a| lattice(lo[a], a));
    let counts = std::array::from_fn(|a| {
        let cells = lattice(hi[a], a).saturating_sub(first[a]).max(0) as u64;
        cells.min(MAX_AXIS_CELLS - 3) + 1
    });
    CellLayout {
        inv_size,
        anchor,
        first,
        counts,
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// `n` spheres with centres uniform in the cube `[0, side]³` and radii uniform in
    /// `radii`, from a fixed `seed`.
    pub(crate) fn random_set(
        n: usize,
        seed: u64,
        side: f32,
        radii: std::ops::Range<f32>,
    ) -> (Vec<[f32; 3]>, Vec<f32>) {
        let mut state = seed;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let centers = (0..n)
            .map(|_| [next() * side, next() * side, next() * side])
            .collect();
        let r = (0..n)
            .map(|_| radii.start + (radii.end - radii.start) * next())
            .collect();
        (centers, r)
    }

    #[test]
    fn both_sorts_in_pieces_and_ranges_are_a_stable_sort_by_cell() {
        // Enough spheres for several pieces of the input and many ranges of cells, some cells
        // holding several spheres (whose input order a stable sort keeps).
        let n = 20_000;
        let (centers, radii) = random_set(n, 99, 20.0, 0.2..0.5);
        let (lo, hi) = ([0.0; 3], [20.0; 3]);
        let mut counted = SortedGrid::default();
        counted
            .bin_within(&centers, &radii, (lo, hi), [-0.3, 0.1, 0.7], 1.0)
            .unwrap();
        assert!(
            !counted.starts.is_empty(),
            "a dense layout is sorted by counting"
        );
        assert!(n > 2 * MIN_PIECE, "several pieces");

        // The reference: a stable comparison sort of (key, input index) by key.
        let cells = cell_layout(lo, hi, [-0.3, 0.1, 0.7], 1.0);
        let [nx, ny] = counted.dims;
        let key = |c: &[f32; 3]| cells.key(c, nx, ny);
        let mut expected: Vec<(u64, u32)> = (0..n).map(|i| (key(&centers[i]), i as u32)).collect();
        expected.sort_by_key(|e| e.0);
        let keys: Vec<u64> = expected.iter().map(|e| e.0).collect();
        let ids: Vec<u32> = expected.iter().map(|e| e.1).collect();
        assert!(keys.windows(2).any(|k| k[0] == k[1]), "shared cells");

        let mut radix = SortedGrid::default();
        radix.sort_by_radix(&centers, &radii, key).unwrap();
        for grid in [&counted, &radix] {
            assert_eq!(grid.keys, keys);
            assert_eq!(grid.ids, ids);
            let spheres = ids.iter().map(|&i| {
                let c = centers[i as usize];
                [c[0], c[1], c[2], radii[i as usize]]
            });
            assert!(grid.spheres.iter().copied().eq(spheres));
        }
        for (cell, run) in counted.starts.windows(2).enumerate() {
            let first = keys.partition_point(|&k| k < cell as u64);
            let end = keys.partition_point(|&k| k <= cell as u64);
            assert_eq!(run, [first as u32, end as u32], "cell {cell}");
        }
        // Binned again, fewer and then no spheres: the kept scratch does not leak into them.
        radix
            .sort_by_radix(&centers[..10], &radii[..10], key)
            .unwrap();
        let mut few = expected[..0].to_vec();
        few.extend((0..10).map(|i| (key(&centers[i]), i as u32)));
        few.sort_by_key(|e| e.0);
        assert_eq!(radix.ids, few.iter().map(|e| e.1).collect::<Vec<_>>());
        radix.sort_by_radix(&[], &[], key).unwrap();
        assert!(radix.keys.is_empty() && radix.ids.is_empty() && radix.spheres.is_empty());
    }
}
