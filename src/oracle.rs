//! The brute-force oracle: every pair tested, O(n²). Tests trust it; fine up to ~20k spheres.

use crate::proxy::{collides, near_boundary};
use crate::spheres::SphereSet;
use crate::types::Pair;
use rayon::prelude::*;

/// Every colliding pair of `spheres`, sorted, each once with `i < j`.
pub fn brute_force_pairs(spheres: &SphereSet) -> Vec<Pair> {
    let c = spheres.centers();
    let r = spheres.radii();
    (0..spheres.len())
        .into_par_iter()
        .flat_map_iter(|i| {
            (i + 1..spheres.len())
                .filter(move |&j| collides(c[i], r[i], c[j], r[j]))
                .map(move |j| Pair::new(i as u32, j as u32))
        })
        .collect()
}

/// Pairs in which `got` and the oracle's `want` differ. With `fused` (a backend whose device
/// compiler may fuse multiply-adds: the wgpu ones), pairs within rounding of a threshold of the
/// rule off the axes ([`crate::proxy::near_boundary`]) are left out: such a GPU may decide them
/// the other way. Without it, every difference counts. Empty means `got` is exact.
pub fn differences(got: &[Pair], want: &[Pair], spheres: &SphereSet, fused: bool) -> Vec<Pair> {
    use std::collections::HashSet;
    let (c, r) = (spheres.centers(), spheres.radii());
    let got: HashSet<_> = got.iter().copied().collect();
    let want: HashSet<_> = want.iter().copied().collect();
    let mut off: Vec<Pair> = got
        .symmetric_difference(&want)
        .copied()
        .filter(|p| {
            let (i, j) = (p.i as usize, p.j as usize);
            !(fused && near_boundary(c[i], r[i], c[j], r[j]))
        })
        .collect();
    off.sort_unstable();
    off
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_touching_and_skips_apart() {
        let s = SphereSet::new(
            vec![[0.0; 3], [2.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0; 3]],
            vec![1.0, 1.0, 1.0, 0.1],
        )
        .unwrap();
        assert_eq!(
            brute_force_pairs(&s),
            vec![Pair::new(0, 1), Pair::new(0, 3)]
        );
    }

    #[test]
    fn differences_allow_only_fused_rounding_off_the_axes() {
        // 0–1 touch along x (exact in any arithmetic); 2–3 touch to rounding on a diagonal.
        let s = SphereSet::new(
            vec![
                [0.0; 3],
                [2.0, 0.0, 0.0],
                [10.0, 0.0, 0.0],
                [11.2, 1.6, 0.0],
            ],
            vec![1.0, 1.0, 1.0, 1.0],
        )
        .unwrap();
        let want = brute_force_pairs(&s);
        assert_eq!(want, vec![Pair::new(0, 1), Pair::new(2, 3)]);
        for fused in [false, true] {
            assert_eq!(differences(&want, &want, &s, fused), vec![]);
            assert_eq!(differences(&[], &want, &s, fused).len(), 2 - fused as usize);
        }
        assert_eq!(
            differences(&[Pair::new(0, 2)], &[], &s, true),
            vec![Pair::new(0, 2)]
        );
    }
}
