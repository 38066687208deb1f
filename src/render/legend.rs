//! What is written over a picture: the colour legend at the right edge and a caption at the
//! top left, each on a light veil, in the embedded font ([`super::font`]) at a size that
//! follows the picture's height.

use super::colour::{unit, viridis};
use super::font::{draw_text, line_height, text_width};
use super::image::Image;

/// How far the veil lightens what lies under the text (0: not at all, 1: to [`PAPER`]).
const VEIL: f32 = 0.7;
/// The veil's colour.
const PAPER: [f32; 3] = [0.97; 3];
/// The text's and the colour bar's frame's colour.
const INK: [f32; 3] = [0.08, 0.08, 0.1];
/// Pictures smaller than this (width, height) get neither legend nor caption: they would hide
/// the spheres.
const SMALLEST: (u32, u32) = (96, 64);

/// Text size \[px\] (the font's ascent to descent) for a picture `height` pixels high: a 24th
/// of it, 16 px at 384 (capitals 10 px high), at least 10 px.
fn text_size(height: u32) -> f32 {
    (height as f32 / 24.0).clamp(10.0, 96.0)
}

/// What a colour legend shows: a label and the values at both ends of the colour map.
#[derive(Debug, Clone, PartialEq)]
pub struct Legend {
    /// The quantity and its unit, e.g. `radius [m]`.
    pub label: String,
    /// The value coloured as the bottom of the map.
    pub min: f32,
    /// The value coloured as the top of the map.
    pub max: f32,
    /// Whether some values lie above `max` (coloured as the top): it then reads `≥ max`.
    pub above: bool,
}

impl Image {
    /// Lightens the rectangle `x0..x1` × `y0..y1` (clipped), so that text on it stays legible.
    fn veil(&mut self, (x0, y0): (i64, i64), (x1, y1): (i64, i64)) {
        for y in y0..y1 {
            for x in x0..x1 {
                self.blend(x, y, PAPER, VEIL);
            }
        }
    }

    /// Writes `text` at `size` px with its top left at `at`, anti-aliased.
    fn write(&mut self, text: &str, at: (i64, i64), size: f32) {
        draw_text(text, at, size, |x, y, coverage| {
            self.blend(x, y, INK, coverage)
        });
    }

    /// Draws `legend` at the right edge on a light veil: the label, the maximum, a vertical
    /// colour bar half the picture's height and the minimum, right-aligned. Pictures smaller
    /// than 96×64 get no legend.
    pub fn draw_legend(&mut self, legend: &Legend) {
        if self.width < SMALLEST.0 || self.height < SMALLEST.1 {
            return;
        }
        let size = text_size(self.height);
        let line = line_height(size) as i64;
        let margin = (0.5 * size).round() as i64;
        let pad = (0.3 * size).round() as i64;
        let bar_w = (0.7 * size).round() as i64;
        let bar_h = (self.height / 2) as i64;
        let right = self.width as i64 - margin;
        let top = (self.height as i64 - bar_h) / 2;
        let max = match legend.above {
            true => format!("≥ {}", format_value(legend.max)),
            false => format_value(legend.max),
        };
        let min = format_value(legend.min);
        let widest = [&legend.label, &max, &min]
            .iter()
            .map(|s| text_width(s, size))
            .max()
            .unwrap_or(0) as i64;
        let widest = widest.max(bar_w);
        self.veil(
            (right - widest - pad, top - 2 * line - pad),
            (right + pad, top + bar_h + line + 2 * pad),
        );
        let mut text = |s: &str, y: i64| {
            let x = right - text_width(s, size) as i64;
            self.write(s, (x, y), size);
        };
        text(&legend.label, top - 2 * line);
        text(&max, top - line);
        text(&min, top + bar_h + pad);
        for dy in 0..bar_h {
            let u = 1.0 - dy as f32 / (bar_h - 1).max(1) as f32;
            let value = legend.min + (legend.max - legend.min) * u;
            let colour = viridis(unit(value, (legend.min, legend.max)));
            for dx in 0..bar_w {
                let edge = dx == 0 || dx == bar_w - 1 || dy == 0 || dy == bar_h - 1;
                let colour = if edge { INK } else { colour };
                self.blend(right - bar_w + dx, top + dy, colour, 1.0);
            }
        }
    }

    /// Writes `text` at the top left on a light veil. Pictures smaller than 96×64 get no
    /// caption.
    pub fn draw_caption(&mut self, text: &str) {
        if self.width < SMALLEST.0 || self.height < SMALLEST.1 {
            return;
        }
        let size = text_size(self.height);
        let at = (0.5 * size).round() as i64;
        let pad = (0.3 * size).round() as i64;
        self.veil(
            (at - pad, at - pad),
            (
                at + text_width(text, size) as i64 + pad,
                at + line_height(size) as i64 + pad,
            ),
        );
        self.write(text, (at, at), size);
    }
}

/// `value` in at most four significant digits: plain for 0.001 ≤ |v| < 10⁴ (and 0), else as
/// `m.mm×10ˣ`.
fn format_value(value: f32) -> String {
    let a = value.abs();
    if a == 0.0 || (1e-3..1e4).contains(&a) {
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
        let text = format!("{value:.2e}");
        let (mantissa, exponent) = text.split_once('e').unwrap_or((&text, ""));
        const SUPERSCRIPT: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
        let power: String = exponent
            .chars()
            .map(|c| match c.to_digit(10) {
                Some(d) => SUPERSCRIPT[d as usize],
                None => '⁻',
            })
            .collect();
        format!("{mantissa}×10{power}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::shade::pack;

    fn white(width: u32, height: u32) -> Image {
        Image {
            width,
            height,
            pixels: vec![pack([1.0; 3]); (width * height) as usize],
        }
    }

    /// Pixels of `image` darker than mid grey: ink, not veil or background.
    fn dark(image: &Image, x: std::ops::Range<u32>, y: std::ops::Range<u32>) -> usize {
        y.flat_map(|y| x.clone().map(move |x| (x, y)))
            .filter(|&(x, y)| image.rgb(x, y).iter().all(|&c| c < 128))
            .count()
    }

    #[test]
    fn values_format_short() {
        assert_eq!(format_value(0.0), "0");
        assert_eq!(format_value(1.5), "1.5");
        assert_eq!(format_value(12.34567), "12.35");
        assert_eq!(format_value(0.003), "0.003");
        assert_eq!(format_value(0.0005), "5.00×10⁻⁴");
        assert_eq!(format_value(-2.5e6), "-2.50×10⁶");
        assert_eq!(format_value(1.234e-12), "1.23×10⁻¹²");
    }

    #[test]
    fn the_legend_draws_the_colour_map_and_its_text() {
        let (w, h) = (240, 120);
        let legend = |label: &str| {
            let mut image = white(w, h);
            image.draw_legend(&Legend {
                label: label.into(),
                min: 0.0005,
                max: 0.0006,
                above: false,
            });
            image
        };
        let image = legend("radius [m]");
        // The bar: at the right margin (5 px at text size 10), from y = 30 to 89, 7 px wide.
        let near = |p: [u8; 3], want: [f32; 3]| {
            (0..3).all(|k| (p[k] as f32 - want[k] * 255.0).abs() <= 16.0)
        };
        let (x, top, bottom) = (w - 5 - 4, 31, 88);
        assert!(
            near(image.rgb(x, top), viridis(1.0)),
            "{:?}",
            image.rgb(x, top)
        );
        assert!(near(image.rgb(x, bottom), viridis(0.0)));
        // The text: ink above the bar (label and maximum) and below it (minimum), and none
        // left of the veil.
        assert!(dark(&image, 0..w, 0..30) > 60, "label and maximum");
        assert!(dark(&image, 0..w, 90..h) > 20, "minimum");
        assert_eq!(dark(&image, 0..w - 70, 0..h), 0);
        // Another label is other ink, in its own place.
        let other = legend("speed [m/s]");
        let differ = (0..30)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| image.rgb(x, y) != other.rgb(x, y))
            .count();
        assert!(differ > 40, "{differ} pixels differ");
    }

    #[test]
    fn the_caption_is_written_at_the_top_left_anti_aliased() {
        let mut image = white(200, 100);
        image.draw_caption("step 20000");
        let inked = dark(&image, 0..100, 0..20);
        assert!(inked > 40, "{inked} dark pixels");
        assert_eq!(
            dark(&image, 100..200, 0..100) + dark(&image, 0..200, 20..100),
            0
        );
        let greys = image
            .pixels
            .iter()
            .map(|&p| p & 0xff)
            .filter(|&c| c > 40 && c < 200)
            .count();
        assert!(
            greys > 20,
            "{greys} pixels between ink and veil: anti-aliased"
        );
        // Too small a picture gets none.
        let mut small = white(90, 60);
        small.draw_caption("step 1");
        assert_eq!(small, white(90, 60));
    }
}
