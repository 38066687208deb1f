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
    /// (key, input index) scratch for the sort, kept to avoid reallocation.
    order: Vec<(u64, u32)>,
    /// The first sorted position of every cell key, one past the last cell included, where
    /// the layout has at most [`DENSE_CELLS_PER_SPHERE`] cells per sphere (the spheres then
    /// sorted by counting); else empty (sorted by radix, runs found by walking the keys).
    pub starts: Vec<u32>,
    /// Scratch of the counting sort, kept to avoid reallocation: the next place in each cell
    /// and the sorted (key, input index) entries.
    cursor: Vec<u32>,
    sorted: Vec<(u64, u32)>,
}

/// Cells per sphere up to which a grid keeps a table of cell starts ([`SortedGrid::starts`]).
const DENSE_CELLS_PER_SPHERE: u64 = 8;

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

        centers
            .par_iter()
            .enumerate()
            .map(|(i, c)| (cells.key(c, lo, nx, ny), i as u32))
            .collect_into_vec(&mut self.order);
        let all_cells = nx * ny * (cells.counts[2] + 2);
        if all_cells <= DENSE_CELLS_PER_SPHERE * (centers.len() as u64).max(1) {
            self.sort_by_counting(all_cells as usize);
        } else {
            self.starts.clear();
            radsort::sort_by_key(&mut self.order, |e| e.0);
        }

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

    /// Sorts `order` by key, stably, counting the spheres of each of the `cells` keys into
    /// [`Self::starts`] on the way: linear in spheres and cells.
    fn sort_by_counting(&mut self, cells: usize) {
        self.starts.clear();
        self.starts.resize(cells + 1, 0);
        for &(key, _) in &self.order {
            self.starts[key as usize + 1] += 1;
        }
        for k in 0..cells {
            self.starts[k + 1] += self.starts[k];
        }
        self.cursor.clone_from(&self.starts);
        self.sorted.resize(self.order.len(), (0, 0));
        for &entry in &self.order {
            let place = &mut self.cursor[entry.0 as usize];
            self.sorted[*place as usize] = entry;
            *place += 1;
        }
        std::mem::swap(&mut self.order, &mut self.sorted);
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
            (u as u64).min(self.counts[a] - 1) + 1
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
