//! Pictures: an RGBA image in memory, and PNG and animated-GIF files.

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

    /// Mixes `colour` into pixel `(x, y)` by `alpha` in [0, 1] (1: `colour` alone); pixels
    /// outside the picture are left alone.
    pub(super) fn blend(&mut self, x: i64, y: i64, colour: [f32; 3], alpha: f32) {
        if x >= 0 && y >= 0 && (x as u32) < self.width && (y as u32) < self.height {
            let i = (y as u32 * self.width + x as u32) as usize;
            let under = unpack(self.pixels[i]);
            self.pixels[i] = pack(std::array::from_fn(|k| {
                under[k] + (colour[k] - under[k]) * alpha
            }));
        }
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
