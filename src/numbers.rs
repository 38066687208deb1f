//! Numbers as people read them: measurements and derived values to a few significant digits
//! (`2.322e-5`, `308.6`), and `f32` values widened to `f64` through their shortest decimal (0.8,
//! not 0.800000011920929) for the files people read and edit (a run's `scene.toml`).
//! Machine-readable output (frames, JSON, CSV data, checkpoints' particles) keeps every bit and
//! does not come here.

/// `x` to `digits` significant digits (at least one), trailing zeros dropped: plain from 0.001
/// up to 1e15, an integer part keeping all its digits (`308.6`, `0.0125`, `12346` at four
/// digits), else in Rust's scientific notation (`2.322e-5`, `1e20`). Zero, infinities and NaN
/// as Rust writes them.
pub fn significant(x: f64, digits: usize) -> String {
    to_digits(x, digits, -3..15)
}

/// `x` to four significant digits, plain from 0.001 up to 1e5 and in scientific notation
/// beyond (`5.806e-5`, `0.003`, `1e7`, `-1`): how a message shows a measured, derived or given
/// value, a modulus or a limit readable at a glance.
pub fn shown(x: impl Into<f64>) -> String {
    to_digits(x.into(), 4, -3..5)
}

/// `x` to `digits` significant digits, trailing zeros dropped: plain where its decimal exponent
/// (after rounding) is in `plain`, an integer part keeping all its digits, else in Rust's
/// scientific notation.
fn to_digits(x: f64, digits: usize, plain: std::ops::Range<i32>) -> String {
    if x == 0.0 || !x.is_finite() {
        return x.to_string();
    }
    let digits = digits.max(1);
    // The exponent after rounding to `digits` (9.99996 at four digits is 1.000e1).
    let scientific = format!("{x:.prec$e}", prec = digits - 1);
    let (mantissa, exponent) = scientific
        .split_once('e')
        .expect("Rust's scientific notation has an exponent");
    let exponent: i32 = exponent.parse().expect("an integer exponent");
    if plain.contains(&exponent) {
        let decimals = (digits as i32 - 1 - exponent).max(0) as usize;
        without_trailing_zeros(&format!("{x:.decimals$}")).to_owned()
    } else {
        format!("{}e{exponent}", without_trailing_zeros(mantissa))
    }
}

/// `text` (a decimal) without the zeros that end its fraction, nor a `.` left bare.
fn without_trailing_zeros(text: &str) -> &str {
    match text.contains('.') {
        true => text.trim_end_matches('0').trim_end_matches('.'),
        false => text,
    }
}

/// `x` as the `f64` nearest its shortest decimal (`0.8_f32` gives 0.8, not 0.800000011920929),
/// where that `f64` rounds back to `x` (`as f32`, as a scene read back does); else, for the few
/// `f32` whose shortest decimal rounds twice to a neighbour (7.038531e-26), `x` exactly. Either
/// way `widened(x) as f32 == x` for every `f32` but NaN.
pub fn widened(x: f32) -> f64 {
    let shortest: f64 = x
        .to_string()
        .parse()
        .expect("Rust reads back the f32 it writes");
    match shortest as f32 == x {
        true => shortest,
        false => x as f64,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn significant_digits_are_plain_in_the_middle_and_scientific_at_the_ends() {
        assert_eq!(significant(2.3222333766170777e-5, 4), "2.322e-5");
        assert_eq!(significant(5e-6_f32 as f64, 4), "5e-6");
        assert_eq!(significant(1.25e-4, 4), "1.25e-4");
        assert_eq!(significant(308.5531, 4), "308.6");
        assert_eq!(significant(308.5531, 3), "309");
        assert_eq!(significant(12345.6, 4), "12346");
        assert_eq!(significant(0.0125, 4), "0.0125");
        assert_eq!(significant(0.001, 4), "0.001");
        assert_eq!(significant(9.99996, 4), "10");
        assert_eq!(significant(-0.5, 4), "-0.5");
        assert_eq!(significant(3e20, 4), "3e20");
        assert_eq!(significant(0.0, 4), "0");
        assert_eq!(significant(f64::INFINITY, 4), "inf");
        assert_eq!(significant(2.6, 0), "3");
    }

    #[test]
    fn shown_numbers_are_plain_up_to_1e5_and_scientific_beyond() {
        assert_eq!(shown(5.805583434051664e-5), "5.806e-5");
        assert_eq!(shown(3.0001628e-3_f32), "0.003");
        assert_eq!(shown(1e7), "1e7");
        assert_eq!(shown(12345.6), "12346");
        assert_eq!(shown(99999.7), "1e5");
        assert_eq!(shown(-1.0), "-1");
        assert_eq!(shown(500.0_f32), "500");
        assert_eq!(shown(f64::NAN), "NaN");
        assert_eq!(shown(f32::MAX), "3.403e38");
    }

    #[test]
    fn widened_f32_is_the_shortest_decimal_and_rounds_back() {
        assert_eq!(widened(0.8), 0.8);
        assert_eq!(widened(2.3222334e-5), 2.3222334e-5);
        assert_eq!(widened(-0.0).to_bits(), (-0.0f64).to_bits());
        assert_eq!(widened(f32::INFINITY), f64::INFINITY);
        // Its shortest decimal, read as f64 and rounded to f32, lands on the next f32.
        let twice = 7.038531e-26_f32;
        assert_ne!(twice.to_string().parse::<f64>().unwrap() as f32, twice);
        assert_eq!(widened(twice), twice as f64);
        // Every 4,099th f32 (a million, every exponent) rounds back.
        for bits in (0..u32::MAX).step_by(4099) {
            let x = f32::from_bits(bits);
            if !x.is_nan() {
                assert_eq!((widened(x) as f32).to_bits(), bits, "{x:e}");
            }
        }
    }
}
