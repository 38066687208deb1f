//! The brute-force oracle: every pair tested, O(n²). Tests trust it; fine up to ~20k spheres.

use crate::proxy::{collides, dist2, near_boundary};
use crate::spheres::{Pair, SphereSet};
use rayon::prelude::*;

/// Every colliding pair of `spheres`, sorted, each once with `i < j`.
pub fn brute_force_pairs(spheres: &SphereSet) -> Vec<Pair> {
    let c = spheres.centers();
    let r = spheres.radii();
    (0..spheres.len())
        .into_par_iter()
        .flat_map_iter(|i| {
            (i + 1..spheres.len())
                .filter(move |&j| collides(dist2(c[i], c[j]), r[i], r[j]))
                .map(move |j| Pair::new(i as u32, j as u32))
        })
        .collect()
}

/// Pairs in which `got` and the oracle's `want` differ, leaving out those within rounding of a
/// threshold of the rule ([`crate::proxy::near_boundary`]), which a GPU that fuses multiply-adds
/// may decide the other way. Empty means `got` is exact.
pub fn differences_off_boundary(got: &[Pair], want: &[Pair], spheres: &SphereSet) -> Vec<Pair> {
    use std::collections::HashSet;
    let (c, r) = (spheres.centers(), spheres.radii());
    let got: HashSet<_> = got.iter().copied().collect();
    let want: HashSet<_> = want.iter().copied().collect();
    let mut off: Vec<Pair> = got
        .symmetric_difference(&want)
        .copied()
        .filter(|p| {
            let (i, j) = (p.i as usize, p.j as usize);
            !near_boundary(c[i], r[i], c[j], r[j])
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
}
