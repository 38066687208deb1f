//! A 3×5 bitmap font of our own (`m` is 5 wide), just large enough for legends: digits, `.`,
//! `+`, `-`, `e`, brackets, `/` and the lower-case letters of the labels.

/// Width in columns of a glyph.
fn glyph_width(c: char) -> u32 {
    if c == 'm' { 5 } else { 3 }
}

/// Each glyph: five rows from the top, [`glyph_width`] bits each (the high bit is the left
/// column).
fn glyph(c: char) -> Option<[u8; 5]> {
    Some(match c {
        '0' => [0b111, 0b101, 0b101, 0b101, 0b111],
        '1' => [0b010, 0b110, 0b010, 0b010, 0b111],
        '2' => [0b111, 0b001, 0b111, 0b100, 0b111],
        '3' => [0b111, 0b001, 0b111, 0b001, 0b111],
        '4' => [0b101, 0b101, 0b111, 0b001, 0b001],
        '5' => [0b111, 0b100, 0b111, 0b001, 0b111],
        '6' => [0b111, 0b100, 0b111, 0b101, 0b111],
        '7' => [0b111, 0b001, 0b001, 0b010, 0b010],
        '8' => [0b111, 0b101, 0b111, 0b101, 0b111],
        '9' => [0b111, 0b101, 0b111, 0b001, 0b111],
        '.' => [0b000, 0b000, 0b000, 0b000, 0b010],
        '-' => [0b000, 0b000, 0b111, 0b000, 0b000],
        '+' => [0b000, 0b010, 0b111, 0b010, 0b000],
        '[' => [0b110, 0b100, 0b100, 0b100, 0b110],
        ']' => [0b011, 0b001, 0b001, 0b001, 0b011],
        '/' => [0b001, 0b001, 0b010, 0b100, 0b100],
        ' ' => [0; 5],
        'a' => [0b000, 0b011, 0b101, 0b101, 0b011],
        'd' => [0b001, 0b011, 0b101, 0b101, 0b011],
        'e' => [0b000, 0b011, 0b111, 0b100, 0b011],
        'i' => [0b010, 0b000, 0b010, 0b010, 0b010],
        'm' => [0b00000, 0b11110, 0b10101, 0b10101, 0b10101],
        'n' => [0b000, 0b110, 0b101, 0b101, 0b101],
        'o' => [0b000, 0b010, 0b101, 0b101, 0b010],
        'p' => [0b000, 0b110, 0b101, 0b110, 0b100],
        'r' => [0b000, 0b101, 0b110, 0b100, 0b100],
        's' => [0b000, 0b011, 0b110, 0b011, 0b110],
        't' => [0b010, 0b111, 0b010, 0b010, 0b001],
        'u' => [0b000, 0b101, 0b101, 0b101, 0b011],
        _ => return None,
    })
}

/// Width of `text` in pixels at `scale` (each glyph plus a gap of 1, times `scale`).
pub(crate) fn text_width(text: &str, scale: u32) -> u32 {
    let columns: u32 = text.chars().map(|c| glyph_width(c) + 1).sum();
    columns.saturating_sub(1) * scale
}

/// Height of a line of text in pixels at `scale`.
pub(crate) fn text_height(scale: u32) -> u32 {
    5 * scale
}

/// Calls `set(x, y)` for every lit pixel of `text` with its top left at `(x0, y0)`; characters
/// the font lacks are drawn as a box.
pub(crate) fn draw_text(
    text: &str,
    (x0, y0): (i64, i64),
    scale: u32,
    mut set: impl FnMut(i64, i64),
) {
    let scale = scale as i64;
    let mut left = x0;
    for c in text.chars() {
        let (rows, width) = match glyph(c) {
            Some(rows) => (rows, glyph_width(c) as i64),
            None => ([0b111, 0b101, 0b101, 0b101, 0b111], 3),
        };
        for (row, bits) in rows.iter().enumerate() {
            for col in 0..width {
                if bits & (1 << (width - 1 - col)) == 0 {
                    continue;
                }
                for dy in 0..scale {
                    for dx in 0..scale {
                        set(left + col * scale + dx, y0 + row as i64 * scale + dy);
                    }
                }
            }
        }
        left += (width + 1) * scale;
    }
}

/// `value` in at most four significant digits: plain for 0.01 ≤ |v| < 10⁴ (and 0), else as
/// `m.mme±x`.
pub(crate) fn format_value(value: f32) -> String {
    let a = value.abs();
    if a == 0.0 || (1e-2..1e4).contains(&a) {
        let decimals = if a == 0.0 {
            0
        } else {
            (3 - a.log10().floor() as i32).clamp(0, 5)
        };
        let text = format!("{value:.*}", decimals as usize);
        if text.contains('.') {
            text.trim_end_matches('0').trim_end_matches('.').to_owned()
        } else {
            text
        }
    } else {
        format!("{value:.2e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_format_short() {
        assert_eq!(format_value(0.0), "0");
        assert_eq!(format_value(1.5), "1.5");
        assert_eq!(format_value(12.34567), "12.35");
        assert_eq!(format_value(0.0005), "5.00e-4");
        assert_eq!(format_value(-2.5e6), "-2.50e6");
    }

    #[test]
    fn every_character_of_the_labels_and_numbers_has_a_glyph() {
        for c in "radius [m]speed [m/s]step 0123456789.-+e".chars() {
            assert!(glyph(c).is_some(), "{c:?}");
        }
        let mut lit = 0;
        draw_text("8", (0, 0), 2, |_, _| lit += 1);
        assert_eq!(lit, 13 * 4);
        assert_eq!(text_width("ab", 2), 14);
        assert_eq!(text_width("m", 1), 5);
    }
}
