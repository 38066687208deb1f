//! The proxy-sphere rule of the method (docs/method.md, "Proxy spheres and the rule"), on `f32`.
//!
//! This file is the reference: the WGSL and CUDA versions of the rule copy it line for line
//! (keep them in sync with it). Distances are compared squared, computed the same way for both
//! orders of a pair, so the rule is symmetric bit for bit. The accepted radii
//! ([`crate::MIN_RADIUS`] up to [`crate::MAX_MAGNITUDE`]) keep every threshold's square a normal
//! `f32`, so no square that can change a decision underflows or overflows.

/// How large the box of each sphere is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum ProxyMode {
    /// The paper's proxy spheres: the box of sphere j has half-width 2·r_j.
    #[default]
    Mochi,
    /// The older fixed-radius reduction: every box has half-width 2·r_max.
    Nns,
}

crate::names::named!(ProxyMode { Mochi => "mochi", Nns => "nns" });

impl ProxyMode {
    /// The value of `mode` in the device programs: `MODE_MOCHI`/`MODE_NNS` of `wgsl/core/proxy.wgsl`
    /// and `MOCHI_MODE_MOCHI`/`MOCHI_MODE_NNS` of `optix/device.cuh` (checked by
    /// `tests/shaders.rs`).
    pub fn code(self) -> u32 {
        match self {
            ProxyMode::Mochi => 0,
            ProxyMode::Nns => 1,
        }
    }

    /// Half-width of the box of a sphere of radius `r_j` in a set whose largest radius is `r_max`.
    #[inline]
    pub fn box_half_width(self, r_j: f32, r_max: f32) -> f32 {
        match self {
            ProxyMode::Mochi => 2.0 * r_j,
            ProxyMode::Nns => 2.0 * r_max,
        }
    }

    /// Side of a grid cell that holds every partner of a sphere within its 27-cell stencil:
    /// 2·r_max (the proxy of the largest sphere) or 4·r_max (the fixed-radius box).
    #[inline]
    pub fn cell_size(self, r_max: f32) -> f32 {
        match self {
            ProxyMode::Mochi => 2.0 * r_max,
            ProxyMode::Nns => 4.0 * r_max,
        }
    }
}

/// Difference of two centres, `c_i − c_j`.
///
/// Negating it is exact, so every rule below decides `(a, b)` and `(b, a)` on the same numbers.
#[inline(always)]
pub fn diff(c_i: [f32; 3], c_j: [f32; 3]) -> [f32; 3] {
    [c_i[0] - c_j[0], c_i[1] - c_j[1], c_i[2] - c_j[2]]
}

/// Relative padding of every backend's proxy boxes: a few ulps of f32, so a box test never
/// rejects a point that the rule accepts.
pub(crate) const BOX_PADDING: f32 = 4.0 * f32::EPSILON;

/// Whether a difference `d` of centres is at most `t` long: |d|² ≤ t² in `f32`.
///
/// Every threshold of the rule is at least 2·[`crate::MIN_RADIUS`], so t² is a normal number far
/// above `f32::MIN_POSITIVE`; a component whose square underflows (or that a GPU flushes to zero)
/// counts for less than 2^-70 of t², far below rounding. Thresholds and differences of at most
/// 2·[`crate::MAX_MAGNITUDE`] keep every square finite. Symmetric bit for bit: `d` and `−d` give
/// the same squares.
#[inline(always)]
pub fn within(d: [f32; 3], t: f32) -> bool {
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= t * t
}

/// Relative width of the rounding band of [`near_boundary`]: plain and fused evaluations of
/// [`within`] differ by less than 6 ulps.
const ROUNDING_BAND: f64 = 16.0 * f32::EPSILON as f64;

/// True when the centres differ in more than one coordinate and their distance lies within
/// rounding of a threshold of the rule: r_i + r_j, 2·r_i or 2·r_j (compared squared, in `f64`,
/// which neither underflows nor overflows here).
///
/// GPU compilers may fuse `a·b + c` into one rounding (WGSL cannot forbid it, and does not promise
/// that `fma` is fused either), so devices may decide such a pair differently from this file, by
/// an ulp. With one nonzero component there is nothing to fuse (x·x + 0 rounds once either way).
/// Every other pair is decided identically everywhere, and every backend reports each pair it
/// keeps exactly once.
pub fn near_boundary(c_i: [f32; 3], r_i: f32, c_j: [f32; 3], r_j: f32) -> bool {
    let d = diff(c_i, c_j);
    if d.iter().filter(|&&x| x != 0.0).count() <= 1 {
        return false;
    }
    let d2: f64 = d.iter().map(|&x| (x as f64).powi(2)).sum();
    let s = (r_i + r_j) as f64;
    let (p_i, p_j) = (2.0 * r_i as f64, 2.0 * r_j as f64);
    [s * s, p_i * p_i, p_j * p_j]
        .iter()
        .any(|&t| (d2 - t).abs() <= t * ROUNDING_BAND)
}

/// Rule 1, the narrow phase: the spheres touch or overlap (|c_i − c_j| ≤ r_i + r_j).
#[inline(always)]
pub fn collides(c_i: [f32; 3], r_i: f32, c_j: [f32; 3], r_j: f32) -> bool {
    within(diff(c_i, c_j), r_i + r_j)
}

/// The whole filter of a candidate found by the point ray of sphere `i` in the box of sphere `j`
/// (`mochi` mode): rules 1–3 of the method. Exactly one of `keep(i, j)` and `keep(j, i)` holds for
/// every colliding pair, and neither for any other pair.
#[inline(always)]
pub fn keep(i: u32, c_i: [f32; 3], r_i: f32, j: u32, c_j: [f32; 3], r_j: f32) -> bool {
    if i == j {
        return false;
    }
    let d = diff(c_i, c_j);
    within(d, r_i + r_j) && within(d, 2.0 * r_j) && (j > i || !within(d, 2.0 * r_i))
}

/// The filter of `nns` mode: every box has the same size, so both rays see the pair and the
/// smaller index keeps it.
#[inline(always)]
pub fn keep_nns(i: u32, c_i: [f32; 3], r_i: f32, j: u32, c_j: [f32; 3], r_j: f32) -> bool {
    j > i && collides(c_i, r_i, c_j, r_j)
}

/// The filter of `mode` (see [`keep`] and [`keep_nns`]).
#[inline(always)]
pub fn keep_in(
    mode: ProxyMode,
    i: u32,
    c_i: [f32; 3],
    r_i: f32,
    j: u32,
    c_j: [f32; 3],
    r_j: f32,
) -> bool {
    match mode {
        ProxyMode::Mochi => keep(i, c_i, r_i, j, c_j, r_j),
        ProxyMode::Nns => keep_nns(i, c_i, r_i, j, c_j, r_j),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reports(a: ([f32; 3], f32), b: ([f32; 3], f32)) -> (bool, bool) {
        (
            keep(0, a.0, a.1, 1, b.0, b.1),
            keep(1, b.0, b.1, 0, a.0, a.1),
        )
    }

    #[test]
    fn each_colliding_pair_is_kept_by_exactly_one_ray() {
        let big = ([0.0, 0.0, 0.0], 120.0);
        // Small sphere inside the big proxy, the big centre outside the small proxy:
        // only the small sphere's ray (index 1 here) keeps it.
        assert_eq!(reports(big, ([100.0, 0.0, 0.0], 1.0)), (false, true));
        // Equal radii: both rays see each other, the smaller index keeps it.
        assert_eq!(
            reports(([0.0; 3], 1.0), ([2.0, 0.0, 0.0], 1.0)),
            (true, false)
        );
        // Exactly touching is a collision.
        assert_eq!(
            reports(([0.0; 3], 0.5), ([0.0, 1.0, 0.0], 0.5)),
            (true, false)
        );
        // Coincident centres.
        assert_eq!(reports(([1.0; 3], 0.5), ([1.0; 3], 3.0)), (true, false));
        // Apart by one ulp more than touching.
        let gap = 2.0f32.next_up();
        assert_eq!(
            reports(([0.0; 3], 1.0), ([gap, 0.0, 0.0], 1.0)),
            (false, false)
        );
        assert!(
            !keep(3, [0.0; 3], 1.0, 3, [0.0; 3], 1.0),
            "never with itself"
        );
    }

    #[test]
    fn near_boundary_flags_only_pairs_within_rounding_of_a_threshold() {
        let touching = 1.6f32.next_up();
        assert!(near_boundary([0.0; 3], 1.0, [touching, 1.2, 0.0], 1.0));
        assert!(near_boundary([0.0; 3], 1.0, [1.6, 1.2, 0.0], 1.0));
        assert!(!near_boundary([0.0; 3], 1.0, [1.5, 1.2, 0.0], 1.0));
        assert!(!near_boundary([0.0; 3], 1.0, [5.0, 1.2, 0.0], 1.0));
        // On an axis nothing is fused: no allowance.
        assert!(!near_boundary([0.0; 3], 1.0, [2.0, 0.0, 0.0], 1.0));
        assert!(!near_boundary(
            [0.0; 3],
            1.0,
            [0.0, 0.0, 2.0f32.next_up()],
            1.0
        ));
        // The proxy boundary of the larger sphere (d = 2·r_j) counts too.
        assert!(near_boundary([0.0; 3], 0.1, [2.4, 3.2, 0.0], 2.0));
        // The smallest radii: nothing underflows to a band around zero.
        let r = crate::MIN_RADIUS;
        assert!(near_boundary([0.0; 3], r, [1.2 * r, 1.6 * r, 0.0], r));
        assert!(!near_boundary([0.0; 3], r, [1e5 * r, 1e5 * r, 0.0], r));
    }

    #[test]
    fn radii_at_both_ends_of_the_range_decide_exactly() {
        let r = crate::MIN_RADIUS;
        // A gap of 10^5 radii is no contact (with radii of 1e-30 its square would underflow to 0).
        let (a, b) = (([0.0; 3], r), ([1e5 * r, 0.0, 0.0], r));
        assert_eq!(reports(a, b), (false, false));
        // Touching to the ulp at the smallest radius, along an axis and off it.
        let d = r + r;
        assert!(collides([0.0; 3], r, [0.0, d, 0.0], r));
        assert!(!collides([0.0; 3], r, [0.0, d.next_up(), 0.0], r));
        assert!(collides(
            [0.0; 3],
            r,
            [0.6 * d, 0.8 * d, 0.0].map(|x| x * 0.999),
            r
        ));
        // A proxy boundary far below the larger radius: only the small sphere's proxy decides.
        let inside = ([0.0, 0.0, 2.0 * r], r);
        let outside = ([0.0, 0.0, (2.0 * r).next_up()], r);
        assert_eq!(reports(([0.0; 3], 1.0), inside), (true, false));
        assert_eq!(reports(([0.0; 3], 1.0), outside), (false, true));
        // At the coordinate limit: no overflow to infinity, touching is still touching.
        let m = crate::MAX_MAGNITUDE;
        assert_eq!(
            reports(([-m, 0.0, 0.0], m), ([m, 0.0, 0.0], m)),
            (true, false)
        );
        assert!(!collides([-m; 3], r, [m; 3], r));
    }

    #[test]
    fn the_rule_is_symmetric_bit_for_bit() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
        for _ in 0..10_000 {
            let scale = 10f32.powi(rng.random_range(-11..15));
            let c = |rng: &mut rand_pcg::Pcg64| {
                std::array::from_fn(|_| rng.random_range(-scale..scale))
            };
            let (a, b): ([f32; 3], [f32; 3]) = (c(&mut rng), c(&mut rng));
            let (r_a, r_b) = (
                rng.random_range(0.01..1.0) * scale,
                rng.random_range(0.01..1.0) * scale,
            );
            assert_eq!(collides(a, r_a, b, r_b), collides(b, r_b, a, r_a));
            let d = diff(a, b);
            assert_eq!(d.map(|x| -x), diff(b, a));
            if collides(a, r_a, b, r_b) {
                let (ab, ba) = (keep(0, a, r_a, 1, b, r_b), keep(1, b, r_b, 0, a, r_a));
                assert!(ab != ba, "{a:?} {r_a:e} {b:?} {r_b:e}");
            }
        }
    }

    #[test]
    fn nns_keeps_the_same_pairs_by_index() {
        let (a, b) = (([0.0; 3], 120.0), ([100.0, 0.0, 0.0], 1.0));
        assert!(keep_nns(0, a.0, a.1, 1, b.0, b.1));
        assert!(!keep_nns(1, b.0, b.1, 0, a.0, a.1));
        assert_eq!(ProxyMode::Nns.cell_size(1.0), 4.0);
        assert_eq!(ProxyMode::Mochi.box_half_width(1.0, 5.0), 2.0);
    }
}
