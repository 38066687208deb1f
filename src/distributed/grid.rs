//! The box cut into a grid of boxes, one a rank: slabs along its longest axis where they do
//! best, else cuts along two or three axes (a recursive bisection's boxes where the ranks are a
//! power of two), whichever grid of the ranks has the least inner face area (the ghosts a step
//! exchanges grow with it). Each axis keeps its own faces ([`Slabs`]), so a rank's box is the
//! product of one slab of each axis, and balancing moves each axis's faces by the work along
//! it.

use super::slabs::Slabs;
use crate::error::Result;

/// A grid of boxes over the box, one a rank: rank r is box (i, j, k) with
/// r = i + n₀·(j + n₁·k), n the boxes along each axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// The cuts along x, y and z (one slab along an axis not cut).
    pub axes: [Slabs; 3],
}

impl Grid {
    /// `ranks` boxes over the box `lo..hi`: the grid n₀ × n₁ × n₂ = `ranks` of equal boxes
    /// whose inner faces have the least area, and of those the one that cuts the fewest axes,
    /// then the longest axes the most (so 2 ranks, or a long box, get slabs along its longest
    /// axis).
    pub fn cut(lo: [f64; 3], hi: [f64; 3], ranks: usize) -> Result<Self> {
        // Checks the box and the ranks as one slab would.
        Slabs::along_longest(lo, hi, ranks)?;
        let length: [f64; 3] = std::array::from_fn(|a| hi[a] - lo[a]);
        let mut longest = [0, 1, 2];
        longest.sort_by(|&a, &b| length[b].total_cmp(&length[a]));
        let area = |n: [usize; 3]| -> f64 {
            (0..3)
                .map(|a| (n[a] - 1) as f64 * length[(a + 1) % 3] * length[(a + 2) % 3])
                .sum()
        };
        let mut best: Option<([usize; 3], f64)> = None;
        for n0 in (1..=ranks).filter(|d| ranks.is_multiple_of(*d)) {
            for n1 in (1..=ranks / n0).filter(|d| (ranks / n0).is_multiple_of(*d)) {
                let n = [n0, n1, ranks / n0 / n1];
                let cost = area(n);
                let better = match best {
                    None => true,
                    Some((b, c)) => {
                        let cut = |n: [usize; 3]| n.iter().filter(|&&k| k > 1).count();
                        let along = |n: [usize; 3]| longest.map(|a| n[a]);
                        let close = (cost - c).abs() <= 1e-9 * c.abs().max(cost.abs());
                        match close {
                            false => cost < c,
                            true => {
                                (cut(n), std::cmp::Reverse(along(n)))
                                    < (cut(b), std::cmp::Reverse(along(b)))
                            }
                        }
                    }
                };
                if better {
                    best = Some((n, cost));
                }
            }
        }
        let (n, _) = best.expect("1 x 1 x ranks divides the ranks");
        Ok(Self {
            axes: std::array::from_fn(|a| Slabs::along(a, (lo[a], hi[a]), n[a])),
        })
    }

    /// The boxes along each axis.
    pub fn counts(&self) -> [usize; 3] {
        self.axes.each_ref().map(Slabs::ranks)
    }

    /// The ranks (boxes).
    pub fn ranks(&self) -> usize {
        self.counts().iter().product()
    }

    /// The rank of box `(i, j, k)`.
    fn rank_of(&self, at: [usize; 3]) -> usize {
        let n = self.counts();
        at[0] + n[0] * (at[1] + n[1] * at[2])
    }

    /// The rank of the box next to `rank`'s by `d` boxes along each axis (each of -1, 0, 1),
    /// where there is one.
    pub fn neighbour(&self, rank: usize, d: [i32; 3]) -> Option<usize> {
        let n = self.counts();
        let at = [rank % n[0], (rank / n[0]) % n[1], rank / (n[0] * n[1])];
        let mut next = [0; 3];
        for a in 0..3 {
            next[a] = at[a]
                .checked_add_signed(d[a] as isize)
                .filter(|&i| i < n[a])?;
        }
        Some(self.rank_of(next))
    }

    /// The box of `rank` as it owns centres: `lo <= x < hi` along every axis, the outer sides
    /// open (infinite).
    pub fn bounds_of(&self, rank: usize) -> ([f64; 3], [f64; 3]) {
        let n = self.counts();
        let at = [rank % n[0], (rank / n[0]) % n[1], rank / (n[0] * n[1])];
        let (mut lo, mut hi) = ([0.0; 3], [0.0; 3]);
        for (a, axis) in self.axes.iter().enumerate() {
            (lo[a], hi[a]) = axis.sides(at[a]);
        }
        (lo, hi)
    }

    /// The rank whose box holds `x` (a centre beyond the box: the nearest box's; one on a
    /// face: the box above it).
    pub fn owner(&self, x: [f64; 3]) -> usize {
        self.rank_of(self.axes.each_ref().map(|s| s.owner(x)))
    }

    /// The ranks other than `owner` whose box lies within `halo` of `x` along every axis (the
    /// ranks that hold the sphere at `x` as a ghost; a box within `halo` of it is among them),
    /// in order.
    pub fn ghost_ranks(&self, x: [f64; 3], owner: usize, halo: f64) -> Vec<usize> {
        let mut ranks = self.ranks_within(x, halo);
        ranks.retain(|&r| r != owner);
        ranks
    }

    /// The one rank whose box lies within `halo` of `x`, where only one does (a point deep in
    /// its box).
    pub fn alone_within(&self, x: [f64; 3], halo: f64) -> Option<usize> {
        let mut at = [0; 3];
        for (a, axis) in self.axes.iter().enumerate() {
            let mut within = axis.within(x, halo);
            at[a] = within.next()?;
            if within.next().is_some() {
                return None;
            }
        }
        Some(self.rank_of(at))
    }

    /// The ranks whose box lies within `halo` of `x` along every axis (its owner's among
    /// them), in order.
    pub fn ranks_within(&self, x: [f64; 3], halo: f64) -> Vec<usize> {
        let [a, b, c] = self
            .axes
            .each_ref()
            .map(|s| s.within(x, halo).collect::<Vec<_>>());
        let mut ranks = Vec::new();
        for &k in &c {
            for &j in &b {
                for &i in &a {
                    ranks.push(self.rank_of([i, j, k]));
                }
            }
        }
        ranks
    }

    /// The same grid, the faces of each axis cut moved so that each of its slabs holds an
    /// equal part of `work[axis]` (a histogram along it, [`Slabs::bin`]).
    pub fn balanced(&self, work: &[Vec<f64>; 3]) -> Grid {
        Grid {
            axes: std::array::from_fn(|a| self.axes[a].balanced(&work[a])),
        }
    }

    /// Whether every face of this grid lies within `by` of the same face of `other` (a grid of
    /// as many boxes along each axis).
    pub fn moved_within(&self, other: &Grid, by: f64) -> bool {
        (self.axes.iter().zip(&other.axes)).all(|(a, b)| {
            a.faces.len() == b.faces.len()
                && (a.faces.iter().zip(&b.faces)).all(|(x, y)| (x - y).abs() <= by)
        })
    }

    /// The width of the thinnest box along an axis that is cut (infinite where none is) \[m\].
    pub fn thinnest(&self) -> f64 {
        self.axes
            .iter()
            .filter(|s| s.ranks() > 1)
            .map(Slabs::thinnest)
            .fold(f64::INFINITY, f64::min)
    }

    /// The grid in words: "slabs along x" or "a 2 × 2 × 1 grid".
    pub fn describe(&self) -> String {
        let n = self.counts();
        let cut: Vec<usize> = (0..3).filter(|&a| n[a] > 1).collect();
        match cut[..] {
            [] => "one box".into(),
            [a] => format!("slabs along {}", ["x", "y", "z"][a]),
            _ => format!("a {} × {} × {} grid", n[0], n[1], n[2]),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_cuts_the_least_face_area_slabs_first() {
        let cube = |ranks| Grid::cut([0.0; 3], [1.0; 3], ranks).unwrap().counts();
        assert_eq!(cube(1), [1, 1, 1]);
        assert_eq!(cube(2), [2, 1, 1]);
        assert_eq!(cube(3), [3, 1, 1]);
        assert_eq!(cube(4), [2, 2, 1]);
        assert_eq!(cube(8), [2, 2, 2]);
        // A box twice as long along y: 4 slabs cut as much area as 2 x 2; slabs win.
        let long = Grid::cut([0.0; 3], [1.0, 2.0, 1.0], 4).unwrap();
        assert_eq!(long.counts(), [1, 4, 1]);
        assert_eq!(long.describe(), "slabs along y");
        assert!(Grid::cut([0.0; 3], [1.0; 3], 0).is_err());
    }

    #[test]
    fn each_centre_has_one_owner_and_the_boxes_near_it_hold_it_as_a_ghost() {
        let grid = Grid::cut([0.0; 3], [2.0, 2.0, 1.0], 4).unwrap();
        assert_eq!(grid.counts(), [2, 2, 1]);
        assert_eq!(grid.describe(), "a 2 × 2 × 1 grid");
        assert_eq!(grid.owner([0.5, 0.5, 0.5]), 0);
        assert_eq!(grid.owner([1.5, 0.5, 0.5]), 1);
        assert_eq!(grid.owner([0.5, 1.5, 0.5]), 2);
        assert_eq!(grid.owner([1.5, 1.5, 9.0]), 3);
        assert_eq!(grid.owner([-5.0, 7.0, 0.5]), 2);
        let x = [0.95, 0.95, 0.5];
        assert_eq!(grid.ghost_ranks(x, grid.owner(x), 0.1), [1, 2, 3]);
        let x = [0.95, 0.5, 0.5];
        assert_eq!(grid.ghost_ranks(x, grid.owner(x), 0.1), [1]);
        let x = [0.5, 0.5, 0.5];
        assert!(grid.ghost_ranks(x, grid.owner(x), 0.1).is_empty());
        assert_eq!(grid.thinnest(), 1.0);
        assert_eq!(grid.neighbour(0, [1, 1, 0]), Some(3));
        assert_eq!(grid.neighbour(3, [-1, 0, 0]), Some(2));
        assert_eq!(grid.neighbour(3, [1, 0, 0]), None);
        assert_eq!(grid.neighbour(0, [0, 0, -1]), None);
        // A rank's bounds hold exactly the centres it owns, the outer sides open.
        assert_eq!(
            grid.bounds_of(1).0,
            [1.0, f64::NEG_INFINITY, f64::NEG_INFINITY]
        );
        assert_eq!(grid.bounds_of(2).1, [1.0, f64::INFINITY, f64::INFINITY]);
        for x in [
            [0.5, 0.5, 0.5],
            [1.0, 1.0, 0.2],
            [-5.0, 7.0, 0.5],
            [1.5, 0.99, 9.0],
        ] {
            let inside =
                |(lo, hi): ([f64; 3], [f64; 3])| (0..3).all(|a| lo[a] <= x[a] && x[a] < hi[a]);
            let holding: Vec<usize> = (0..4).filter(|&r| inside(grid.bounds_of(r))).collect();
            assert_eq!(holding, [grid.owner(x)], "{x:?}");
        }
    }

    #[test]
    fn a_balanced_grid_moves_each_axis_by_its_work() {
        let grid = Grid::cut([0.0; 3], [1.0; 3], 4).unwrap();
        let mut x = vec![0.0; Slabs::BINS];
        x[..Slabs::BINS / 2].fill(1.0);
        let even = vec![1.0; Slabs::BINS];
        let balanced = grid.balanced(&[x, even.clone(), even]);
        assert_eq!(balanced.axes[0].faces, [0.0, 0.25, 1.0]);
        assert_eq!(balanced.axes[1].faces, [0.0, 0.5, 1.0]);
        assert_eq!(balanced.axes[2].faces, [0.0, 1.0]);
        assert!(balanced.moved_within(&grid, 0.25));
        assert!(!balanced.moved_within(&grid, 0.2));
        assert!(!grid.moved_within(&Grid::cut([0.0; 3], [1.0; 3], 2).unwrap(), 1.0));
    }
}
