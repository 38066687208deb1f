//! The box cut into slabs along one axis (its longest, for a run of slabs; each axis of a
//! [`Grid`](super::Grid)): which slab holds a centre, which lie within a halo of it, and where
//! the faces go to share out the work.

use crate::error::{Error, Result};

/// Slabs along one axis of the box (of equal width as cut; of equal work once balanced).
#[derive(Debug, Clone, PartialEq)]
pub struct Slabs {
    /// The axis they are cut along (0, 1, 2: x, y, z).
    pub axis: usize,
    /// The faces along the axis, from the box's low side to its high side: slab r lies
    /// between faces r and r + 1.
    pub faces: Vec<f64>,
}

impl Slabs {
    /// `ranks` slabs of equal width along the longest axis of the box `lo..hi` (the first
    /// such axis where two are as long).
    pub fn along_longest(lo: [f64; 3], hi: [f64; 3], ranks: usize) -> Result<Self> {
        let cut = lo.iter().zip(&hi).all(|(l, h)| l < h);
        if ranks == 0 || !cut {
            return Err(Error::Usage(format!(
                "cannot cut the box {lo:?}..{hi:?} into {ranks} slabs"
            )));
        }
        let axis = (0..3).fold(0, |a, b| if hi[b] - lo[b] > hi[a] - lo[a] { b } else { a });
        Ok(Self::along(axis, (lo[axis], hi[axis]), ranks))
    }

    /// `count` slabs (at least 1) of equal width along `axis` of a box from `lo` to `hi` on it.
    pub fn along(axis: usize, (lo, hi): (f64, f64), count: usize) -> Self {
        let count = count.max(1);
        let width = (hi - lo) / count as f64;
        let faces = (0..=count)
            .map(|k| match k == count {
                true => hi,
                false => lo + width * k as f64,
            })
            .collect();
        Self { axis, faces }
    }

    /// Bins a histogram of [`balanced`](Self::balanced) has.
    pub const BINS: usize = 1024;

    /// The bin of [`BINS`](Self::BINS) equal ones between the outer faces that holds `x`
    /// (a centre beyond them: the nearest end's).
    pub fn bin(&self, x: [f64; 3]) -> usize {
        let (lo, hi) = (self.faces[0], self.faces[self.ranks()]);
        let at = (x[self.axis] - lo) / (hi - lo) * Self::BINS as f64;
        (at.max(0.0) as usize).min(Self::BINS - 1)
    }

    /// The same number of slabs along the same axis, their inner faces moved so that each
    /// holds an equal part of `work` (the work in each [`bin`](Self::bin), spread evenly over
    /// it); the same slabs where there is none.
    pub fn balanced(&self, work: &[f64]) -> Slabs {
        let total: f64 = work.iter().sum();
        if total <= 0.0 || work.len() != Self::BINS {
            return self.clone();
        }
        let (lo, hi) = (self.faces[0], self.faces[self.ranks()]);
        let width = (hi - lo) / Self::BINS as f64;
        let mut faces = vec![lo];
        let (mut below, mut bin) = (0.0, 0);
        for k in 1..self.ranks() {
            let wanted = total * k as f64 / self.ranks() as f64;
            while bin < Self::BINS - 1 && below + work[bin] < wanted {
                below += work[bin];
                bin += 1;
            }
            let inside = match work[bin] > 0.0 {
                true => ((wanted - below) / work[bin]).clamp(0.0, 1.0),
                false => 0.0,
            };
            let face = lo + width * (bin as f64 + inside);
            faces.push(face.max(faces[k - 1]));
        }
        faces.push(hi);
        Slabs {
            axis: self.axis,
            faces,
        }
    }

    /// The slabs (ranks).
    pub fn ranks(&self) -> usize {
        self.faces.len() - 1
    }

    /// The width of the thinnest slab \[m\].
    pub fn thinnest(&self) -> f64 {
        self.faces
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(f64::INFINITY, f64::min)
    }

    /// The rank whose slab holds `x` (a centre beyond the box: the nearest slab's; one on a
    /// face: the slab above it).
    pub fn owner(&self, x: [f64; 3]) -> usize {
        let along = x[self.axis];
        // Faces 1..ranks are the inner ones: the owner is how many of them lie at or below.
        let inner = &self.faces[1..self.ranks()];
        inner.partition_point(|&face| face <= along)
    }

    /// The slabs that lie within `halo` of `x` along the axis (its own among them), in order.
    pub fn within(&self, x: [f64; 3], halo: f64) -> impl Iterator<Item = usize> {
        let along = x[self.axis];
        (0..self.ranks()).filter(move |&r| {
            let (below, above) = self.sides(r);
            along >= below - halo && along <= above + halo
        })
    }

    /// Where slab `r` begins and ends along the axis: its faces, but for the outer slabs'
    /// outer sides, which are open (they reach beyond the box).
    pub fn sides(&self, r: usize) -> (f64, f64) {
        let below = match r {
            0 => f64::NEG_INFINITY,
            _ => self.faces[r],
        };
        let above = match r + 1 == self.ranks() {
            true => f64::INFINITY,
            false => self.faces[r + 1],
        };
        (below, above)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slabs_cut_the_longest_axis_and_own_each_centre_once() {
        let slabs = Slabs::along_longest([0.0; 3], [1.0, 4.0, 2.0], 4).unwrap();
        assert_eq!(slabs.axis, 1);
        assert_eq!(slabs.faces, [0.0, 1.0, 2.0, 3.0, 4.0]);
        assert_eq!(slabs.owner([0.5, -3.0, 0.0]), 0);
        assert_eq!(slabs.owner([0.5, 0.99, 0.0]), 0);
        assert_eq!(slabs.owner([0.5, 1.0, 0.0]), 1);
        assert_eq!(slabs.owner([0.5, 3.5, 0.0]), 3);
        assert_eq!(slabs.owner([0.5, 9.0, 0.0]), 3);
        let ghosts = |y: f64| -> Vec<usize> {
            let x = [0.0, y, 0.0];
            let owner = slabs.owner(x);
            slabs.within(x, 0.1).filter(|&r| r != owner).collect()
        };
        assert_eq!(ghosts(0.5), Vec::<usize>::new());
        assert_eq!(ghosts(0.95), [1]);
        assert_eq!(ghosts(1.05), [0]);
        assert_eq!(ghosts(2.0), [1]);
        assert_eq!(ghosts(-5.0), Vec::<usize>::new());
        // Wider than a slab: beyond the next.
        let x = [0.0, 1.5, 0.0];
        let wide: Vec<usize> = slabs.within(x, 1.6).collect();
        assert_eq!(wide, [0, 1, 2, 3]);
        assert!(Slabs::along_longest([0.0; 3], [1.0; 3], 0).is_err());
        assert!(Slabs::along_longest([0.0; 3], [1.0, 0.0, 1.0], 2).is_err());
    }

    #[test]
    fn balanced_slabs_hold_equal_work() {
        let slabs = Slabs::along_longest([0.0; 3], [4.0, 1.0, 1.0], 4).unwrap();
        assert_eq!(slabs.bin([-1.0, 0.0, 0.0]), 0);
        assert_eq!(slabs.bin([1.0, 0.0, 0.0]), Slabs::BINS / 4);
        assert_eq!(slabs.bin([9.0, 0.0, 0.0]), Slabs::BINS - 1);
        // All the work in the lowest quarter, evenly: four slabs of it.
        let mut work = vec![0.0; Slabs::BINS];
        work[..Slabs::BINS / 4].fill(1.0);
        let balanced = slabs.balanced(&work);
        assert_eq!(balanced.axis, 0);
        assert_eq!(balanced.faces, [0.0, 0.25, 0.5, 0.75, 4.0]);
        // Twice the work in the upper half of the box: its faces there twice as close.
        let mut work = vec![1.0; Slabs::BINS];
        work[Slabs::BINS / 2..].fill(2.0);
        let faces = slabs.balanced(&work).faces;
        let expected = [0.0, 1.5, 2.5, 3.25, 4.0];
        for (f, e) in faces.iter().zip(expected) {
            assert!((f - e).abs() < 1e-9, "{faces:?}");
        }
        // No work: the same slabs; and work in one bin: slabs of no width there.
        assert_eq!(slabs.balanced(&vec![0.0; Slabs::BINS]), slabs);
        let mut work = vec![0.0; Slabs::BINS];
        work[10] = 3.0;
        let faces = slabs.balanced(&work).faces;
        assert!(faces.windows(2).all(|w| w[0] <= w[1]), "{faces:?}");
    }
}
