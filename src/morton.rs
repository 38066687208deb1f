//! Morton (Z-order) keys of points, the one host encoder: 10 bits per axis over the points'
//! bounding box, x in the lowest bit of each bit triple. `morton_keys` in `wgsl/rq/rq_build.wgsl`
//! computes the same keys on the GPU (same quantisation in `f32`, same bit order).

use rayon::prelude::*;

/// Bits of a key per axis.
pub const AXIS_BITS: u32 = 10;

/// Bits of a key.
pub const KEY_BITS: u32 = 3 * AXIS_BITS;

/// Largest cell coordinate along an axis.
const MAX_CELL: f32 = ((1 << AXIS_BITS) - 1) as f32;

/// Spreads the low 10 bits of `v` to every third bit (bit `k` to bit `3k`).
pub fn spread(v: u32) -> u32 {
    let mut x = v & 0x3ff;
    x = (x | (x << 16)) & 0x0300_00ff;
    x = (x | (x << 8)) & 0x0300_f00f;
    x = (x | (x << 4)) & 0x030c_30c3;
    (x | (x << 2)) & 0x0924_9249
}

/// The key of the cell `q` (each coordinate below 1024): x, y, z in bits 0, 1, 2 of each triple.
pub fn key(q: [u32; 3]) -> u32 {
    spread(q[0]) | spread(q[1]) << 1 | spread(q[2]) << 2
}

/// The Morton grid over a bounding box: cells of `1 / scale` along each axis from `lo`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// Lower corner.
    pub lo: [f32; 3],
    /// 1023 / extent per axis (0 where the extent is 0).
    pub scale: [f32; 3],
}

impl Grid {
    /// The grid over the box `lo..=hi`.
    pub fn over(lo: [f32; 3], hi: [f32; 3]) -> Grid {
        Grid {
            lo,
            scale: std::array::from_fn(|a| {
                let extent = hi[a] - lo[a];
                if extent > 0.0 { MAX_CELL / extent } else { 0.0 }
            }),
        }
    }

    /// The grid over the bounding box of `points`.
    pub fn of(points: &[[f32; 3]]) -> Grid {
        let (lo, hi) = points.iter().fold(
            ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
            |(lo, hi), p| {
                (
                    std::array::from_fn(|a| lo[a].min(p[a])),
                    std::array::from_fn(|a| hi[a].max(p[a])),
                )
            },
        );
        Grid::over(lo, hi)
    }

    /// The key of `p`'s cell (points outside the box are clamped into it).
    pub fn key(&self, p: [f32; 3]) -> u32 {
        key(std::array::from_fn(|a| {
            ((p[a] - self.lo[a]) * self.scale[a]).clamp(0.0, MAX_CELL) as u32
        }))
    }
}

/// The indices of `points` in Morton order over their bounding box (ties by index), and the
/// key of each in that order.
pub fn order(points: &[[f32; 3]]) -> (Vec<u32>, Vec<u32>) {
    let grid = Grid::of(points);
    let mut keyed: Vec<(u32, u32)> = points
        .par_iter()
        .enumerate()
        .map(|(i, &p)| (grid.key(p), i as u32))
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(k, i)| (i, k)).unzip()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_puts_bit_k_at_bit_3k() {
        for k in 0..AXIS_BITS {
            assert_eq!(spread(1 << k), 1 << (3 * k));
        }
        assert_eq!(spread(u32::MAX), 0x0924_9249);
        assert_eq!(key([1023, 1023, 1023]), (1 << KEY_BITS) - 1);
        assert_eq!(key([1, 0, 0]), 1);
        assert_eq!(key([0, 1, 0]), 2);
        assert_eq!(key([0, 0, 1]), 4);
    }

    #[test]
    fn order_follows_the_z_curve_with_ties_by_index() {
        let points = [
            [1.0, 1.0, 1.0],
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
        ];
        let (order, keys) = order(&points);
        assert_eq!(order, vec![1, 3, 2, 0]);
        assert_eq!(keys, vec![0, 0, spread(1023), (1 << KEY_BITS) - 1]);
        assert_eq!(super::order(&[]), (vec![], vec![]));
    }
}
