//! The pictures' text: DejaVu Sans (`assets/fonts/`, its licence beside it), embedded in the
//! binary and rasterised by `ab_glyph` into coverage, which the caller blends into the picture
//! (anti-aliased). One line at a time, laid out left to right with the font's advances and
//! kerning; a character the font lacks shows as its missing-glyph box.

use ab_glyph::{Font, FontRef, Glyph, PxScale, ScaleFont, point};
use std::sync::OnceLock;

/// The font file, as shipped (DejaVu Sans 2.37).
const DEJAVU_SANS: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// The parsed font, once.
fn font() -> &'static FontRef<'static> {
    static FONT: OnceLock<FontRef<'static>> = OnceLock::new();
    // The bytes are part of the binary, not input: the unit tests parse them.
    FONT.get_or_init(|| FontRef::try_from_slice(DEJAVU_SANS).expect("the embedded font parses"))
}

/// `text` laid out at `size` px (the font's ascent to descent): each glyph with its pen
/// position, the baseline at `y = 0` and the first glyph's origin at `x = 0`, and the advance
/// of the whole line \[px\].
fn layout(text: &str, size: f32) -> (Vec<Glyph>, f32) {
    let font = font().as_scaled(PxScale::from(size));
    let mut glyphs = Vec::with_capacity(text.len());
    let mut pen = 0.0;
    let mut previous = None;
    for c in text.chars() {
        let id = font.glyph_id(c);
        if let Some(before) = previous {
            pen += font.kern(before, id);
        }
        glyphs.push(id.with_scale_and_position(size, point(pen, 0.0)));
        pen += font.h_advance(id);
        previous = Some(id);
    }
    (glyphs, pen)
}

/// Width of `text` at `size` px, in whole pixels (its advance, rounded up).
pub(crate) fn text_width(text: &str, size: f32) -> u32 {
    layout(text, size).1.ceil() as u32
}

/// Height of a line of text at `size` px, from the top of the tallest letters to the bottom of
/// the deepest descender, in whole pixels.
pub(crate) fn line_height(size: f32) -> u32 {
    let font = font().as_scaled(PxScale::from(size));
    (font.ascent() - font.descent()).ceil() as u32
}

/// Calls `ink(x, y, coverage)` for every pixel that `text` at `size` px covers, with the top
/// of its line (see [`line_height`]) at `y0` and its left end at `x0`; `coverage` is in
/// (0, 1], the share of the pixel the letters cover.
pub(crate) fn draw_text(
    text: &str,
    (x0, y0): (i64, i64),
    size: f32,
    mut ink: impl FnMut(i64, i64, f32),
) {
    let ascent = font().as_scaled(PxScale::from(size)).ascent();
    let (glyphs, _) = layout(text, size);
    for mut glyph in glyphs {
        glyph.position.y += ascent;
        let Some(outline) = font().outline_glyph(glyph) else {
            continue; // a space, or a glyph without an outline
        };
        let min = outline.px_bounds().min;
        outline.draw(|x, y, coverage| {
            if coverage > 0.0 {
                let (x, y) = (x as i64 + min.x as i64, y as i64 + min.y as i64);
                ink(x0 + x, y0 + y, coverage.min(1.0));
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pixels `text` at `size` covers, as a `width`×`height` mask of coverage.
    fn mask(text: &str, size: f32) -> (u32, u32, Vec<f32>) {
        let (w, h) = (text_width(text, size), line_height(size));
        let mut cover = vec![0.0; (w * h) as usize];
        draw_text(text, (0, 0), size, |x, y, c| {
            assert!(
                (0..w as i64).contains(&x) && (0..h as i64).contains(&y),
                "{text:?}: ({x}, {y}) outside {w}x{h}"
            );
            cover[(y as u32 * w + x as u32) as usize] += c;
        });
        (w, h, cover)
    }

    #[test]
    fn the_embedded_font_has_every_character_of_the_labels() {
        for c in "radius [m] speed [m/s] height material step 0123456789.-+e ≥×⁰¹²³⁴⁵⁶⁷⁸⁹⁻ µ°·–"
            .chars()
            .filter(|c| !c.is_whitespace())
        {
            assert_ne!(font().glyph_id(c).0, 0, "{c:?} has no glyph");
        }
    }

    #[test]
    fn text_is_drawn_anti_aliased_inside_its_box() {
        let (w, h, cover) = mask("speed [m/s]", 20.0);
        assert!((61..160).contains(&w) && (20..=26).contains(&h), "{w}x{h}");
        let inked = cover.iter().filter(|&&c| c > 0.0).count();
        let partial = cover.iter().filter(|&&c| c > 0.05 && c < 0.95).count();
        assert!(inked > 150, "{inked} pixels inked");
        assert!(partial > inked / 5, "{partial} of {inked} partly covered");
        // Letters differ: "l" and "o" differ in shape as they do in width.
        let (_, _, l) = mask("l", 20.0);
        let (_, _, o) = mask("o", 20.0);
        assert_ne!(l, o);
        // Larger text covers more.
        let small: f32 = mask("8", 12.0).2.iter().sum();
        let large: f32 = mask("8", 24.0).2.iter().sum();
        assert!(large > 3.0 * small, "{small} {large}");
    }

    #[test]
    fn spaces_advance_without_ink() {
        let (_, _, cover) = mask(" ", 20.0);
        assert!(cover.iter().all(|&c| c == 0.0));
        assert!(text_width("a b", 20.0) > text_width("ab", 20.0));
        assert_eq!(text_width("", 20.0), 0);
    }
}
