//! The brute-force oracle: every pair tested, O(n²). Tests trust it; fine up to ~20k spheres.

use crate::proxy::{collides, dist2};
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
