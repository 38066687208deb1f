//! Pictures: an RGBA image in memory, its legend, and PNG and animated-GIF files.

use super::colour::{unit, viridis};
use super::font::{draw_text, format_value, text_height, text_width};
use super::shade::{pack, unpack};
use crate::error::{Error, Result};
use crate::io::{AtomicFile, write_atomically};
use std::io::Write;
use std::path::{Path, PathBuf};

/// An 8-bit RGBA picture, rows from the top.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width·height` pixels, row by row, each `r | g << 8 | b << 16 | a << 24`.
    pub pixels: Vec<u32>,
}

/// How far [`Image::veil`] lightens what lies under the legend (0: not at all, 1: white).
const VEIL: f32 = 0.7;

/// Pixels per font pixel for a picture `height` pixels high.
fn text_scale(height: u32) -> u32 {
    (height / 180).clamp(1, 4)
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
}

impl Image {
    /// The colour of pixel `(x, y)` as `[r, g, b]` bytes.
    ///
    /// # Panics
    ///
    /// If `(x, y)` lies outside the picture.
    pub fn rgb(&self, x: u32, y: u32) -> [u8; 3] {
        let p = self.pixels[(y * self.width + x) as usize];
        [p as u8, (p >> 8) as u8, (p >> 16) as u8]
    }

    /// The bytes `r, g, b, a` of every pixel, row by row.
    pub fn rgba_bytes(&self) -> Vec<u8> {
        self.pixels.iter().flat_map(|p| p.to_le_bytes()).collect()
    }

    fn set(&mut self, x: i64, y: i64, colour: u32) {
        if x >= 0 && y >= 0 && (x as u32) < self.width && (y as u32) < self.height {
            self.pixels[(y as u32 * self.width + x as u32) as usize] = colour;
        }
    }

    /// Lightens the rectangle `x0..x1` × `y0..y1` (clipped), so that text on it stays legible.
    fn veil(&mut self, (x0, y0): (i64, i64), (x1, y1): (i64, i64)) {
        for y in y0.max(0)..y1.min(self.height as i64) {
            for x in x0.max(0)..x1.min(self.width as i64) {
                let i = (y as u32 * self.width + x as u32) as usize;
                let c = unpack(self.pixels[i]);
                self.pixels[i] = pack(c.map(|v| v + (0.97 - v) * VEIL));
            }
        }
    }

    /// Draws `legend` at the right edge on a light veil: the label, the maximum, a vertical
    /// colour bar and the minimum. Pictures smaller than 96×64 get no legend (it would hide the
    /// spheres).
    pub fn draw_legend(&mut self, legend: &Legend) {
        if self.width < 96 || self.height < 64 {
            return;
        }
        let scale = text_scale(self.height);
        let margin = (4 * scale) as i64;
        let line = (text_height(scale) + 2 * scale) as i64;
        let bar_w = (6 * scale) as i64;
        let bar_h = (self.height / 2) as i64;
        let right = self.width as i64 - margin;
        let ink = pack([0.08, 0.08, 0.1]);
        let top = (self.height as i64 - bar_h) / 2;
        let (max, min) = (format_value(legend.max), format_value(legend.min));
        let widest = [&legend.label, &max, &min]
            .iter()
            .map(|s| text_width(s, scale))
            .max()
            .unwrap_or(0) as i64;
        let pad = 2 * scale as i64;
        self.veil(
            (right - widest - pad, top - 2 * line - pad),
            (right + pad, top + bar_h + line + pad),
        );
        let text = |image: &mut Image, s: &str, y: i64| {
            let x = right - text_width(s, scale) as i64;
            draw_text(s, (x, y), scale, |px, py| image.set(px, py, ink));
        };
        text(self, &legend.label, top - 2 * line);
        text(self, &max, top - line);
        text(self, &min, top + bar_h + 2 * scale as i64);
        for dy in 0..bar_h {
            let u = 1.0 - dy as f32 / (bar_h - 1).max(1) as f32;
            let value = legend.min + (legend.max - legend.min) * u;
            let colour = pack(viridis(unit(value, (legend.min, legend.max))));
            for dx in 0..bar_w {
                let edge = dx == 0 || dx == bar_w - 1 || dy == 0 || dy == bar_h - 1;
                self.set(
                    right - bar_w + dx,
                    top + dy,
                    if edge { ink } else { colour },
                );
            }
        }
    }

    /// Writes `text` at the top left on a light veil (letters the font lacks show as boxes).
    /// Pictures smaller than 96×64 get no caption.
    pub fn draw_caption(&mut self, text: &str) {
        if self.width < 96 || self.height < 64 {
            return;
        }
        let scale = text_scale(self.height);
        let ink = pack([0.08, 0.08, 0.1]);
        let at = (4 * scale) as i64;
        let pad = 2 * scale as i64;
        self.veil(
            (at - pad, at - pad),
            (
                at + text_width(text, scale) as i64 + pad,
                at + text_height(scale) as i64 + pad,
            ),
        );
        draw_text(text, (at, at), scale, |x, y| self.set(x, y, ink));
    }

    /// Writes the picture as an 8-bit RGB PNG, atomically.
    pub fn write_png(&self, path: &Path) -> Result<()> {
        let rgb: Vec<u8> = self
            .pixels
            .iter()
            .flat_map(|&p| unpack(p).map(|c| (c * 255.0).round() as u8))
            .collect();
        write_atomically(path, |out| {
            let mut encoder = png::Encoder::new(out, self.width, self.height);
            encoder.set_color(png::ColorType::Rgb);
            encoder.set_depth(png::BitDepth::Eight);
            encoder.set_compression(png::Compression::High);
            let mut writer = encoder.write_header().map_err(std::io::Error::other)?;
            writer
                .write_image_data(&rgb)
                .map_err(std::io::Error::other)?;
            writer.finish().map_err(std::io::Error::other)
        })
    }
}

/// Reads a PNG written by [`Image::write_png`] (8-bit RGB or RGBA) back into an [`Image`].
pub fn read_png(path: &Path) -> Result<Image> {
    let bad = |msg: String| Error::Parse {
        path: path.to_owned(),
        line: None,
        msg,
    };
    let file = std::fs::File::open(path).map_err(|error| Error::Io {
        path: path.to_owned(),
        error,
    })?;
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .map_err(|e| bad(e.to_string()))?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| bad("image too large".into()))?;
    let mut buf = vec![0; size];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| bad(e.to_string()))?;
    let channels = match (info.color_type, info.bit_depth) {
        (png::ColorType::Rgb, png::BitDepth::Eight) => 3,
        (png::ColorType::Rgba, png::BitDepth::Eight) => 4,
        other => return Err(bad(format!("unsupported PNG format {other:?}"))),
    };
    let pixels = buf[..info.buffer_size()]
        .chunks_exact(channels)
        .map(|c| c[0] as u32 | (c[1] as u32) << 8 | (c[2] as u32) << 16 | 255 << 24)
        .collect();
    Ok(Image {
        width: info.width,
        height: info.height,
        pixels,
    })
}

/// An animated GIF (looping forever) written frame by frame: each frame is quantised to its own
/// 256-colour palette and written out as it is added, so memory does not grow with the number of
/// frames. The file is written through an [`AtomicFile`]: it appears, whole, at
/// [`Gif::finish`]; dropped before that (an error, a killed run), it leaves no file.
pub struct Gif {
    path: PathBuf,
    encoder: gif::Encoder<AtomicFile>,
    size: (u16, u16),
    frames: usize,
}

impl Gif {
    /// Starts the GIF `path` of frames `width`×`height` pixels (at most 65535 per side). Fails,
    /// naming `path`, where its folder is missing or not writable.
    pub fn create(path: &Path, width: u32, height: u32) -> Result<Self> {
        let (Ok(w), Ok(h)) = (u16::try_from(width), u16::try_from(height)) else {
            return Err(Error::InvalidConfig {
                what: path.display().to_string(),
                reason: format!("a GIF is at most 65535 pixels per side, not {width}x{height}"),
            });
        };
        let gif_error = |e: gif::EncodingError| Error::Io {
            path: path.to_owned(),
            error: std::io::Error::other(e),
        };
        let file = AtomicFile::create(path)?;
        let mut encoder = gif::Encoder::new(file, w, h, &[]).map_err(gif_error)?;
        encoder
            .set_repeat(gif::Repeat::Infinite)
            .map_err(gif_error)?;
        Ok(Self {
            path: path.to_owned(),
            encoder,
            size: (w, h),
            frames: 0,
        })
    }

    /// Adds `image` as the next frame, shown for `delay_cs` hundredths of a second; it must have
    /// the size the GIF was created with. The frame is on disk (in the unfinished file) when this
    /// returns.
    pub fn add(&mut self, image: &Image, delay_cs: u16) -> Result<()> {
        let (w, h) = self.size;
        if (image.width, image.height) != (w.into(), h.into()) {
            return Err(Error::Usage(format!(
                "{}: GIF frames must share one size: {}x{} in a {w}x{h} GIF",
                self.path.display(),
                image.width,
                image.height
            )));
        }
        let mut rgba = image.rgba_bytes();
        let mut frame = gif::Frame::from_rgba_speed(w, h, &mut rgba, 10);
        frame.delay = delay_cs;
        let io = |error| Error::Io {
            path: self.path.clone(),
            error,
        };
        self.encoder
            .write_frame(&frame)
            .map_err(|e| io(std::io::Error::other(e)))?;
        self.encoder.get_mut().flush().map_err(io)?;
        self.frames += 1;
        Ok(())
    }

    /// The number of frames added.
    pub fn len(&self) -> usize {
        self.frames
    }

    /// Whether no frame was added.
    pub fn is_empty(&self) -> bool {
        self.frames == 0
    }

    /// The file the GIF becomes.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Ends the animation and puts the file in place.
    pub fn finish(self) -> Result<()> {
        let file = self.encoder.into_inner().map_err(|e| Error::Io {
            path: self.path.clone(),
            error: std::io::Error::other(e),
        })?;
        file.commit()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_png_round_trips() {
        let image = Image {
            width: 3,
            height: 2,
            pixels: vec![
                0xff00_00ff,
                0xff00_ff00,
                0xffff_0000,
                0xff10_2030,
                0xffff_ffff,
                0xff00_0000,
            ],
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.png");
        image.write_png(&path).unwrap();
        assert_eq!(read_png(&path).unwrap(), image);
    }

    #[test]
    fn the_legend_draws_the_colour_map() {
        let mut image = Image {
            width: 200,
            height: 100,
            pixels: vec![pack([1.0; 3]); 200 * 100],
        };
        image.draw_legend(&Legend {
            label: "radius [m]".into(),
            min: 0.0005,
            max: 0.0006,
        });
        // The bar: 6 px wide at the right margin of 4, from y = 25 to 74.
        let near = |p: [u8; 3], want: [f32; 3]| {
            (0..3).all(|k| (p[k] as f32 - want[k] * 255.0).abs() <= 16.0)
        };
        assert!(
            near(image.rgb(192, 26), viridis(1.0)),
            "{:?}",
            image.rgb(192, 26)
        );
        assert!(
            near(image.rgb(192, 73), viridis(0.0)),
            "{:?}",
            image.rgb(192, 73)
        );
        let ink = image
            .pixels
            .iter()
            .filter(|&&p| p == pack([0.08, 0.08, 0.1]))
            .count();
        assert!(ink > 200, "{ink} pixels of text and frame");
    }

    #[test]
    fn a_gif_is_written_frame_by_frame_and_appears_only_when_finished() {
        let dir = tempfile::tempdir().unwrap();
        let temp_size = || -> u64 {
            let temps: Vec<u64> = std::fs::read_dir(dir.path())
                .unwrap()
                .map(|e| e.unwrap())
                .filter(|e| e.file_name().to_string_lossy().starts_with(".mochi-"))
                .map(|e| e.metadata().unwrap().len())
                .collect();
            assert_eq!(temps.len(), 1, "one unfinished GIF");
            temps[0]
        };
        let image = |shade: f32, width: u32| Image {
            width,
            height: 8,
            pixels: (0..width * 8)
                .map(|i| pack([i as f32 / (width * 8) as f32, shade, 0.5]))
                .collect(),
        };
        let path = dir.path().join("run.gif");
        let mut gif = Gif::create(&path, 16, 8).unwrap();
        let mut sizes = vec![temp_size()];
        for k in 0..3 {
            gif.add(&image(k as f32 / 3.0, 16), 10).unwrap();
            sizes.push(temp_size());
        }
        assert!(
            sizes.windows(2).all(|w| w[1] > w[0]),
            "every frame is on disk once added: {sizes:?}"
        );
        assert!(!path.exists());
        assert!(gif.add(&image(0.0, 8), 10).is_err());
        gif.finish().unwrap();
        let mut decoder = gif::DecodeOptions::new()
            .read_info(std::fs::File::open(&path).unwrap())
            .unwrap();
        let mut frames = 0;
        while decoder.read_next_frame().unwrap().is_some() {
            frames += 1;
        }
        assert_eq!(frames, 3);

        // Dropped unfinished: no file, no temporary file.
        let other = dir.path().join("other.gif");
        let mut gif = Gif::create(&other, 16, 8).unwrap();
        gif.add(&image(0.5, 16), 10).unwrap();
        drop(gif);
        assert!(!other.exists());
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["run.gif"]);
        assert!(Gif::create(&dir.path().join("missing/run.gif"), 16, 8).is_err());
    }
}
