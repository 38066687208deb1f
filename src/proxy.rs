//! The proxy-sphere rule of the method (docs: `../shared/docs/method.md`), on `f32`.
//!
//! This file is the reference: the WGSL and CUDA versions of the rule copy it line for line
//! (keep them in sync with it). Distances are compared squared after scaling both sides by a
//! power of two (exact, and no square underflows), computed the same way for both orders of a
//! pair, so the rule is symmetric bit for bit.

/// How large the box of each sphere is.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Default,
    clap::ValueEnum,
    serde::Serialize,
    serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum ProxyMode {
    /// The paper's proxy spheres: the box of sphere j has half-width 2·r_j.
    #[default]
    Mochi,
    /// The older fixed-radius reduction: every box has half-width 2·r_max.
    Nns,
}

impl ProxyMode {
    /// Name as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ProxyMode::Mochi => "mochi",
            ProxyMode::Nns => "nns",
        }
    }

    /// The value of `mode` in the device programs: `MODE_MOCHI`/`MODE_NNS` of `wgsl/proxy.wgsl`
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

/// The power of two that brings `t` (0 < t < 2^127) into [1, 2); 2^127 for every `t` below
/// 2^-126 (which brings it to at least 2^-22).
///
/// Built from the biased exponent e of `t` (0..=253 here), as the float of exponent 254 − e: a
/// normal, finite power of two. The rule's thresholds, sums and doubles of radii of at most
/// [`crate::MAX_MAGNITUDE`], stay below 4·10¹⁸ (e ≤ 188).
#[inline(always)]
pub fn unit_scale(t: f32) -> f32 {
    f32::from_bits((254 - (t.to_bits() >> 23)) << 23)
}

/// Thresholds from this one up are compared unscaled ([`within`]): 2^-40.
///
/// Their squares (at least 2^-80) are normal, and so is every square that can matter next to
/// them: a component square that underflows is below 2^-126, less than half an ulp of any partial
/// sum it meets near t², so it changes no decision; radii of at most [`crate::MAX_MAGNITUDE`] keep
/// every square far below `f32::MAX`. Below it the squares may leave the normal range, and
/// [`within_scaled`] scales them back first.
pub const UNSCALED_FROM: f32 = 9.094_947e-13;

/// Whether a difference `d` of centres is at most `t` (> 0) long: |d|² ≤ t², compared as plain
/// `f32` squares where `t` ≥ [`UNSCALED_FROM`] (nearly always: one branch, uniform across a GPU's
/// threads), else by [`within_scaled`]. Both forms decide alike wherever both are defined.
/// Symmetric bit for bit: `d` and `−d` give the same squares.
#[inline(always)]
pub fn within(d: [f32; 3], t: f32) -> bool {
    if t >= UNSCALED_FROM {
        d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= t * t
    } else {
        within_scaled(d, t)
    }
}

/// [`within`] with both sides scaled by the same power of two ([`unit_scale`] of `t`) before
/// squaring.
///
/// Scaling by a power of two is exact, so this decides as unscaled `f32` arithmetic without
/// underflow would: squares of radii down to the smallest subnormal never vanish, and a
/// component that does underflow after scaling is below 2^-126·t, too small to change the
/// rounded sum near t². A component that overflows makes the left side infinite: far apart,
/// correctly.
#[inline(always)]
pub fn within_scaled(d: [f32; 3], t: f32) -> bool {
    let k = unit_scale(t);
    let (x, y, z, u) = (d[0] * k, d[1] * k, d[2] * k, t * k);
    x * x + y * y + z * z <= u * u
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
        // Tiny radii: nothing underflows to a band around zero.
        assert!(near_boundary(
            [0.0; 3],
            1e-30,
            [1.2e-30, 1.6e-30, 0.0],
            1e-30
        ));
        assert!(!near_boundary([0.0; 3], 1e-30, [1e-25, 1e-25, 0.0], 1e-30));
    }

    #[test]
    fn tiny_and_huge_radii_decide_as_without_underflow() {
        // A gap of 10^5 radii: the squares (1e-50, 4e-60) underflow unscaled.
        let (a, b) = (([0.0; 3], 1e-30), ([1e-25, 0.0, 0.0], 1e-30));
        assert_eq!(reports(a, b), (false, false));
        assert!(!collides(a.0, a.1, b.0, b.1));
        // Touching to the ulp at 2^-100 and at the smallest subnormal radius.
        for r in [2f32.powi(-100), f32::from_bits(1)] {
            let d = r + r;
            assert!(collides([0.0; 3], r, [0.0, d, 0.0], r), "{r:e}");
            assert!(!collides([0.0; 3], r, [0.0, d.next_up(), 0.0], r), "{r:e}");
        }
        // A proxy boundary far below the larger radius: only the small sphere's proxy decides.
        let (small, big) = (2f32.powi(-90), 1.0);
        let inside = ([0.0, 0.0, 2.0 * small], small);
        let outside = ([0.0, 0.0, (2.0 * small).next_up()], small);
        assert_eq!(reports(([0.0; 3], big), inside), (true, false));
        assert_eq!(reports(([0.0; 3], big), outside), (false, true));
        // At the coordinate limit: no overflow to infinity, touching is still touching.
        let m = crate::spheres::MAX_MAGNITUDE;
        assert_eq!(
            reports(([-m, 0.0, 0.0], m), ([m, 0.0, 0.0], m)),
            (true, false)
        );
        assert!(!collides([-m; 3], 1e-30, [m; 3], 1e-30));
    }

    #[test]
    fn unit_scale_brings_every_threshold_near_one() {
        for t in [
            f32::from_bits(1),
            1e-40,
            1.2e-38,
            1e-30,
            0.75,
            1.0,
            3.0,
            4e18,
        ] {
            let u = t * unit_scale(t);
            assert!((2f32.powi(-22)..2.0).contains(&u), "{t:e} scaled to {u:e}");
            if t >= f32::MIN_POSITIVE {
                assert!(u >= 1.0, "{t:e} scaled to {u:e}");
            }
        }
    }

    #[test]
    fn the_unscaled_threshold_is_two_to_the_minus_forty() {
        assert_eq!(UNSCALED_FROM, 2f32.powi(-40));
    }

    #[test]
    fn unscaled_and_scaled_comparisons_decide_alike_from_the_threshold_up() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let mut near = 0;
        for _ in 0..200_000 {
            // Thresholds from 2^-40 to 2^62, differences around them (some on the boundary).
            let t =
                UNSCALED_FROM * 2f32.powi(rng.random_range(0..102)) * rng.random_range(1.0..2.0);
            let mut d: [f32; 3] = std::array::from_fn(|_| rng.random_range(-1.2..1.2) * t);
            if rng.random_bool(0.3) {
                // A tiny component beside large ones: its square may underflow unscaled.
                d[rng.random_range(0..3)] = rng.random_range(-1.0..1.0) * 1e-25 * t;
            }
            if rng.random_bool(0.2) {
                d = [t, 0.0, 0.0];
            }
            near += usize::from(within_scaled(d, t));
            assert_eq!(within(d, t), within_scaled(d, t), "{d:?} {t:e}");
        }
        assert!(near > 50_000, "{near}");
    }

    #[test]
    fn the_rule_is_symmetric_bit_for_bit() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
        for _ in 0..10_000 {
            let scale = 10f32.powi(rng.random_range(-35..15));
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
