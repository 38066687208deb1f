//! The proxy-sphere rule of the method (docs: `../shared/docs/method.md`), on `f32`.
//!
//! This file is the reference: the WGSL and CUDA versions of the rule copy it line for line
//! (keep them in sync with it). Distances are compared squared, and `d2` is computed the same way
//! for both orders of a pair, so the rule is symmetric bit for bit.

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

/// Squared distance between two centres, as a dot product of their difference.
///
/// Negating the difference is exact, so `dist2(a, b) == dist2(b, a)` bit for bit.
#[inline(always)]
pub fn dist2(c_i: [f32; 3], c_j: [f32; 3]) -> f32 {
    let dx = c_i[0] - c_j[0];
    let dy = c_i[1] - c_j[1];
    let dz = c_i[2] - c_j[2];
    dx * dx + dy * dy + dz * dz
}

/// Relative width of the rounding band of [`near_boundary`]: plain and fused evaluations of
/// [`dist2`] differ by less than 6 ulps.
const ROUNDING_BAND: f32 = 16.0 * f32::EPSILON;

/// True when the squared distance of the two centres lies within rounding of a threshold of the
/// rule: (r_i + r_j)², (2·r_i)² or (2·r_j)².
///
/// GPU compilers may fuse `a·b + c` into one rounding (WGSL cannot forbid it, and does not promise
/// that `fma` is fused either), so devices may decide such a pair differently from this file, by
/// an ulp. Every other pair is decided identically everywhere, and every backend reports each
/// pair it keeps exactly once.
pub fn near_boundary(c_i: [f32; 3], r_i: f32, c_j: [f32; 3], r_j: f32) -> bool {
    let d2 = dist2(c_i, c_j);
    let s = r_i + r_j;
    [s * s, 4.0 * r_i * r_i, 4.0 * r_j * r_j]
        .iter()
        .any(|&t| (d2 - t).abs() <= t * ROUNDING_BAND)
}

/// Rule 1, the narrow phase: spheres at squared distance `d2` touch or overlap.
#[inline(always)]
pub fn collides(d2: f32, r_i: f32, r_j: f32) -> bool {
    let s = r_i + r_j;
    d2 <= s * s
}

/// The whole filter of a candidate found by the point ray of sphere `i` in the box of sphere `j`
/// (`mochi` mode): rules 1–3 of the method. Exactly one of `keep(i, j)` and `keep(j, i)` holds for
/// every colliding pair, and neither for any other pair.
#[inline(always)]
pub fn keep(i: u32, c_i: [f32; 3], r_i: f32, j: u32, c_j: [f32; 3], r_j: f32) -> bool {
    if i == j {
        return false;
    }
    let d2 = dist2(c_i, c_j);
    let proxy_j = 2.0 * r_j;
    let proxy_i = 2.0 * r_i;
    collides(d2, r_i, r_j) && d2 <= proxy_j * proxy_j && (j > i || d2 > proxy_i * proxy_i)
}

/// The filter of `nns` mode: every box has the same size, so both rays see the pair and the
/// smaller index keeps it.
#[inline(always)]
pub fn keep_nns(i: u32, c_i: [f32; 3], r_i: f32, j: u32, c_j: [f32; 3], r_j: f32) -> bool {
    j > i && collides(dist2(c_i, c_j), r_i, r_j)
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
        let gap = f32::from_bits(2.0f32.to_bits() + 1);
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
        let touching = f32::from_bits(2.0f32.to_bits() + 1);
        assert!(near_boundary([0.0; 3], 1.0, [touching, 0.0, 0.0], 1.0));
        assert!(near_boundary([0.0; 3], 1.0, [2.0, 0.0, 0.0], 1.0));
        assert!(!near_boundary([0.0; 3], 1.0, [1.9, 0.0, 0.0], 1.0));
        assert!(!near_boundary([0.0; 3], 1.0, [5.0, 0.0, 0.0], 1.0));
        // The proxy boundary of the larger sphere (d = 2·r_j) counts too.
        assert!(near_boundary([0.0; 3], 0.1, [4.0, 0.0, 0.0], 2.0));
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
