//! Positions that keep every step's displacement, however small (docs/method.md, "Positions
//! that never freeze").
//!
//! Each coordinate of a centre is a pair of `f32`: `hi`, the `f32` centre that detection, the
//! contacts and the walls use, and the residual `lo`; the position is `hi + lo` in exact
//! arithmetic. The pair is *normalised*: `hi` is the position rounded to `f32`, which is
//! `fl(hi + lo) == hi` (so |lo| ≤ ulp(hi)/2). A step adds its displacement d = dt·v by
//! [`advance`]: `t = fl(d + lo)`, then the error-free sum of `hi` and `t` ([`two_sum`]), whose
//! rounded sum is the new `hi` and whose rounding error, exact, the new `lo`. A displacement far
//! below the spacing of `f32` at `hi` so gathers in `lo` until it moves `hi`; what is lost is
//! `t`'s rounding alone, at most half an ulp of |t| ≤ |d| + ulp(hi)/2: for a slow sphere
//! (|d| < ulp(hi)/2) at most 2⁻²⁵ ulp(hi) a step, 2e-13 m at 100 m, where `f32` alone rounds
//! each step by up to 4e-6 m.
//!
//! Rust and NVRTC (no fast math) compute these additions as written, so the cpu and `mochi_advance`
//! in `optix/physics.cuh` run TwoSum itself. A Vulkan shader compiler may reassociate additions
//! (SPIR-V forbids it only for operations marked `NoContraction`, which WGSL cannot ask for) and
//! simplify TwoSum's error to 0 (Mesa's does: `(a + b) − a` is `b` to it), so
//! `advance_position` in `wgsl/dem/dem_params.wgsl` computes the same error from the bits of the
//! operands in integer arithmetic ([`sum_error_by_bits`], its twin here). Every backend then
//! gives the same pair from the same displacement.
//!
//! [`join`] and [`split`] convert between the pair and one `f64`. The sum is exact in `f64`
//! where the pair's bits span at most 53 (`lo` is 0, or its 24 bits end no lower than 2⁻²⁹
//! ulp(hi): |lo| ≥ ulp(hi)/64 always will), and then `split(join(hi, lo)) == (hi, lo)`;
//! otherwise `join` rounds it once, by less than 2⁻⁵³ of it (1e-14 m at 100 m), and `split`
//! gives the pair of that `f64`. Frames and Python hold the `f64`; checkpoints hold the pair
//! itself, so a resumed run goes on bit for bit.

/// The sum of `a` and `b` rounded to `f32` and its rounding error, exactly: `s + e == a + b` in
/// exact arithmetic (Knuth's TwoSum: six additions, no branch, for any order of magnitude).
#[inline(always)]
pub fn two_sum(a: f32, b: f32) -> (f32, f32) {
    let s = a + b;
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    (s, e)
}

/// The rounding error of the sum `s = a + b` of two finite `f32`, exactly, `(a + b) − s`, from
/// their bits in integer arithmetic, as the GPU steps compute it (`sum_error` in
/// `wgsl/dem/dem_params.wgsl`, which a shader compiler cannot simplify away). `a`, `b` and `s` are
/// whole multiples of 2^k, k the lower exponent of `a`'s and `b`'s last bits, and the error a
/// multiple below 2^25 of it (it is `f32`, at most half an ulp of `s`, or the smaller operand
/// itself), so their multiples summed modulo 2^32 give it. Equal to [`two_sum`]'s error but where
/// k is below −126 (operands of 1e-31 and less), where it is dropped.
pub fn sum_error_by_bits(a: f32, b: f32, s: f32) -> f32 {
    /// The exponent of the last bit of the significand.
    fn last_bit(x: f32) -> i32 {
        let field = ((x.to_bits() >> 23) & 0xff) as i32;
        field.max(1) - 150
    }
    /// x / 2^k modulo 2^32, as two's complement.
    fn multiple_of(x: f32, k: i32) -> u32 {
        let bits = x.to_bits();
        let field = (bits >> 23) & 0xff;
        let m = match field != 0 {
            true => (bits & 0x7f_ffff) | 0x80_0000,
            false => bits & 0x7f_ffff,
        };
        let shift = last_bit(x) - k;
        let v = match shift {
            0..32 => m << shift,
            -31..0 => m >> -shift,
            _ => 0,
        };
        match bits & 0x8000_0000 != 0 {
            true => 0u32.wrapping_sub(v),
            false => v,
        }
    }
    if a == 0.0 || b == 0.0 {
        return 0.0;
    }
    let k = last_bit(a).min(last_bit(b));
    if k < -126 {
        return 0.0;
    }
    let e = multiple_of(a, k)
        .wrapping_add(multiple_of(b, k))
        .wrapping_sub(multiple_of(s, k)) as i32;
    e as f32 * f32::from_bits(((k + 127) as u32) << 23)
}

/// Moves the coordinate `hi + lo` (normalised) by `d`: the displacement and the residual are
/// added first, then to `hi` without error ([`two_sum`]). The pair stays normalised.
#[inline(always)]
pub fn advance(hi: &mut f32, lo: &mut f32, d: f32) {
    let (s, e) = two_sum(*hi, d + *lo);
    *hi = s;
    *lo = e;
}

/// `hi + lo` in `f64`: exact where the pair's bits span at most 53 (module docs), else rounded
/// once (by less than 2⁻⁵³ of it). A centre of −0 with no residual stays −0.
#[inline]
pub fn join(hi: f32, lo: f32) -> f64 {
    match lo == 0.0 {
        true => hi as f64,
        false => hi as f64 + lo as f64,
    }
}

/// The normalised pair of `x`: `hi` is `x` rounded to `f32`, `lo` the rest rounded to `f32`
/// (`x − hi` is exact in `f64`), then the pair normalised again (where rounding the rest gave
/// exactly half an ulp of an odd `hi`, `fl(hi + lo)` would be the neighbour of `hi`).
#[inline]
pub fn split(x: f64) -> (f32, f32) {
    let hi = x as f32;
    let lo = (x - hi as f64) as f32;
    if lo == 0.0 {
        return (hi, 0.0); // −0 stays −0
    }
    // Fast2Sum (|hi| ≥ |lo|): the same exact sum, normalised.
    let s = hi + lo;
    (s, lo - (s - hi))
}

/// Whether `(hi, lo)` is normalised: `hi` is the pair's sum rounded to `f32`.
#[inline]
pub fn normalised(hi: f32, lo: f32) -> bool {
    hi + lo == hi
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A seeded source of `f32` values of either sign and magnitudes spread over `range`
    /// (their bits drawn at random), and of numbers uniform in [0, 1).
    fn values(seed: u64, range: (f32, f32)) -> (impl FnMut() -> f32, impl FnMut() -> f64) {
        let mut state = seed;
        let mut other = !seed;
        let next = move || loop {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let x = f32::from_bits((state >> 32) as u32);
            if x.is_finite() && (range.0..range.1).contains(&x.abs()) {
                return x;
            }
        };
        let unit = move || {
            other = other
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (other >> 40) as f64 / (1u64 << 24) as f64
        };
        (next, unit)
    }

    #[test]
    fn two_sum_is_exact() {
        let (mut next, _) = values(1, (0.0, 1e30));
        for _ in 0..100_000 {
            let (a, b) = (next(), next());
            let (s, e) = two_sum(a, b);
            assert_eq!(s, a + b);
            // Exact in f64 where the magnitudes are close enough for f64 to hold a + b.
            if (a.abs().max(b.abs()) as f64) < 1e7 * (a.abs().min(b.abs()) as f64).max(1e-30) {
                assert_eq!(s as f64 + e as f64, a as f64 + b as f64, "{a} + {b}");
            }
            assert!(normalised(s, e), "{a} + {b}");
        }
    }

    #[test]
    fn the_error_from_the_bits_is_two_sums() {
        // Operands of every magnitude, and the slow step's: a coordinate and a displacement
        // far below its spacing.
        let (mut next, mut unit) = values(4, (1e-30, 1e30));
        let (mut wide, _) = values(5, (0.0, 1e30));
        for k in 0..300_000 {
            let a = next();
            let b = match k % 3 {
                0 => next(),
                1 => a * (unit() as f32 - 0.5) * 1e-7,
                _ => -a * (1.0 + (unit() as f32 - 0.5) * 1e-6),
            };
            // Where an operand is below 2^-103 (its last bit below 2^-126) the error is dropped.
            let expected = |a: f32, b: f32, e: f32| match a.abs().min(b.abs()) < 2f32.powi(-103) {
                true => 0.0,
                false => e + 0.0,
            };
            let (s, e) = two_sum(a, b);
            let got = sum_error_by_bits(a, b, s);
            assert_eq!(got.to_bits(), expected(a, b, e).to_bits(), "{a} + {b}");
            let (c, d) = (wide(), wide());
            let (s, e) = two_sum(c, d);
            let got = sum_error_by_bits(c, d, s);
            assert_eq!(got.to_bits(), expected(c, d, e).to_bits(), "{c} + {d}");
        }
        assert_eq!(sum_error_by_bits(0.0, 1.5, 1.5), 0.0);
        assert_eq!(sum_error_by_bits(100.0, 1e-10, 100.0), 1e-10);
    }

    #[test]
    fn a_pair_survives_its_trip_through_f64() {
        // The pairs the integrator leaves: normalised sums of a coordinate and displacements of
        // up to a few of its ulps. Where f64 holds the sum exactly (most: |lo| ≥ ulp(hi)/64 is
        // enough), the split gives the pair back bit for bit; elsewhere the pair of the f64
        // nearest to the sum.
        // Coordinates whose residuals stay normal numbers (f32's normal range starts 24 bits
        // below the smallest coordinate here).
        let (mut next, mut unit) = values(2, (1e-20, 1e18));
        let mut exact = 0;
        for _ in 0..100_000 {
            let hi = next();
            let ulp = (hi.abs().next_up() - hi.abs()) as f64;
            let d = ulp * 3.0 * (2.0 * unit() - 1.0);
            let (mut a, mut b) = (hi, 0.0f32);
            advance(&mut a, &mut b, d as f32);
            assert!(normalised(a, b));
            let x = join(a, b);
            let (c, e) = split(x);
            if x - a as f64 == b as f64 {
                assert_eq!((c.to_bits(), e), (a.to_bits(), b), "{hi} + {d}");
                exact += 1;
            } else {
                assert_eq!(c, a, "{hi} + {d}");
                let off = (e as f64 - b as f64).abs();
                assert!(off <= x.abs() * 2f64.powi(-52), "{hi} + {d}: {off}");
            }
        }
        assert!(exact > 90_000, "{exact}");
    }

    #[test]
    fn a_split_pair_is_normalised_and_sums_to_the_value() {
        let (mut next, mut unit) = values(3, (1e-20, 1e30));
        for _ in 0..100_000 {
            let x = next() as f64 * (1.0 + unit() * 1e-6);
            let (hi, lo) = split(x);
            assert!(normalised(hi, lo), "{x}");
            assert_eq!(hi, x as f32, "{x}");
            assert!((join(hi, lo) - x).abs() <= x.abs() * 2f64.powi(-47), "{x}");
        }
        // Just below half an ulp past an odd f32: the rest rounds to half an ulp, and the pair
        // of that sum (a tie) is normalised to the even neighbour.
        let odd = 1.0f32.next_up();
        let half = (odd.next_up() - odd) as f64 / 2.0;
        let (hi, lo) = split(odd as f64 + half * (1.0 - 1e-12));
        assert!(normalised(hi, lo));
        assert_eq!((hi, join(hi, lo)), (odd.next_up(), odd as f64 + half));
    }

    #[test]
    fn slow_steps_far_out_add_up() {
        // 1 mm/s for 1e4 steps of 1e-7 s at 100 m: 1 µm, where f32 alone never moves (its
        // spacing there is 7.6 µm) and the pair keeps it to a millionth.
        let (mut hi, mut lo) = (100.0f32, 0.0f32);
        let d = 1e-7f32 * 1e-3f32;
        for _ in 0..10_000 {
            advance(&mut hi, &mut lo, d);
        }
        let moved = join(hi, lo) - 100.0;
        assert!((moved / 1e-6 - 1.0).abs() < 1e-3, "{moved}");
        let mut plain = 100.0f32;
        for _ in 0..10_000 {
            plain += d;
        }
        assert_eq!(plain, 100.0);
    }
}
