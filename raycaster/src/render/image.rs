//! 8-bit RGB images: PNG output and input, and comparison with a diff image.

use crate::files::human_bytes;
use std::io::{BufReader, BufWriter};
use std::path::Path;

/// The side of the largest image [`RgbImage::load_png`] reads (the largest
/// frame `raycaster render` writes).
const MAX_LOAD_SIDE: u64 = 16384;

/// Pixels of the largest image read.
const MAX_LOAD_PIXELS: u64 = MAX_LOAD_SIDE * MAX_LOAD_SIDE;

/// An 8-bit RGB image, rows from the top.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RgbImage {
    width: u32,
    height: u32,
    data: Vec<u8>,
}

/// Why an image cannot be read or written.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// File system error.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// PNG encoding or decoding failed.
    #[error("{path}: {message}")]
    Png {
        /// The file.
        path: std::path::PathBuf,
        /// What the PNG codec said.
        message: String,
    },
}

impl RgbImage {
    /// An image from its pixels (`width·height·3` bytes).
    ///
    /// # Panics
    /// If `data` has the wrong length.
    pub fn new(width: u32, height: u32, data: Vec<u8>) -> Self {
        assert_eq!(data.len(), width as usize * height as usize * 3, "RGB size");
        RgbImage {
            width,
            height,
            data,
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The RGB bytes, rows from the top.
    pub fn data(&self) -> &[u8] {
        &self.data
    }

    /// The pixel at `(x, y)`.
    ///
    /// # Panics
    ///
    /// Where `(x, y)` lies outside the image (`x ≥ width` or `y ≥ height`),
    /// as a slice index out of bounds does.
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) lies outside the {}×{} image",
            self.width,
            self.height
        );
        let i = (y as usize * self.width as usize + x as usize) * 3;
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    /// Whether every pixel is grey (its three channels equal).
    pub fn is_grey(&self) -> bool {
        self.data
            .chunks_exact(3)
            .all(|p| p[0] == p[1] && p[1] == p[2])
    }

    /// Writes the image as PNG to `path`, atomically (a temporary file beside it
    /// and a rename), so a failed write never leaves a partial file. An image
    /// whose pixels are all grey ([`Self::is_grey`]: slices, grey transfer
    /// functions) is written as an 8-bit greyscale PNG, a third of the pixel
    /// data, which reads back as the same RGB.
    pub fn save_png(&self, path: &Path) -> Result<(), ImageError> {
        let io = |source| ImageError::Io {
            path: path.to_path_buf(),
            source,
        };
        let png_err = |e: png::EncodingError| ImageError::Png {
            path: path.to_path_buf(),
            message: e.to_string(),
        };
        let tmp = crate::volume::temp_file_beside(path).map_err(io)?;
        {
            let mut encoder =
                png::Encoder::new(BufWriter::new(tmp.as_file()), self.width, self.height);
            let grey = self.is_grey();
            encoder.set_color(if grey {
                png::ColorType::Grayscale
            } else {
                png::ColorType::Rgb
            });
            encoder.set_depth(png::BitDepth::Eight);
            // fdeflate: several times faster than the default level for
            // rendered frames (smooth backgrounds), files a little larger.
            encoder.set_compression(png::Compression::Fast);
            let mut writer = encoder.write_header().map_err(png_err)?;
            if grey {
                let levels: Vec<u8> = self.data.iter().step_by(3).copied().collect();
                writer.write_image_data(&levels).map_err(png_err)?;
            } else {
                writer.write_image_data(&self.data).map_err(png_err)?;
            }
            writer.finish().map_err(png_err)?;
        }
        tmp.persist(path).map_err(|e| io(e.error))?;
        Ok(())
    }

    /// Reads a PNG as 8-bit RGB: any colour type and depth (palette and grey
    /// images expanded, 16-bit samples cut to their high byte, alpha dropped).
    pub fn load_png(path: &Path) -> Result<RgbImage, ImageError> {
        let file = crate::files::open_regular(path).map_err(|source| ImageError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let png_err = |message: String| ImageError::Png {
            path: path.to_path_buf(),
            message,
        };
        let mut decoder = png::Decoder::new(BufReader::new(file));
        // The decoder allocates what the header says: bounded (a lying header
        // is an error, not an abort for lack of memory).
        decoder.set_limits(png::Limits {
            bytes: (MAX_LOAD_PIXELS * 8) as usize,
        });
        decoder.set_transformations(png::Transformations::normalize_to_color8());
        let mut reader = decoder
            .read_info()
            .map_err(|e| png_err(plain_png_error(&e.to_string())))?;
        let (width, height) = (reader.info().width, reader.info().height);
        if u64::from(width) * u64::from(height) > MAX_LOAD_PIXELS {
            return Err(png_err(format!(
                "the image is {width}×{height} pixels, more than the {MAX_LOAD_SIDE}×{MAX_LOAD_SIDE} read"
            )));
        }
        let size = reader
            .output_buffer_size()
            .ok_or_else(|| png_err("image too large".into()))?;
        // (Reserved, not allocated outright: what the process may not take is
        // an error, not an abort.)
        let too_large = |bytes: usize| {
            png_err(format!(
                "decoding it needs {} of memory, more than this process can allocate",
                human_bytes(bytes as u64)
            ))
        };
        let mut buf = Vec::new();
        buf.try_reserve_exact(size).map_err(|_| too_large(size))?;
        buf.resize(size, 0);
        let info = reader
            .next_frame(&mut buf)
            .map_err(|e| png_err(plain_png_error(&e.to_string())))?;
        // (After the transformations: 8 bits, no palette.)
        let (channels, grey) = match info.color_type {
            png::ColorType::Grayscale => (1, true),
            png::ColorType::GrayscaleAlpha => (2, true),
            png::ColorType::Rgb => (3, false),
            png::ColorType::Rgba => (4, false),
            png::ColorType::Indexed => {
                return Err(png_err("a palette image the decoder did not expand".into()));
            }
        };
        let pixels = buf[..info.buffer_size()].chunks_exact(channels);
        let mut data = Vec::new();
        data.try_reserve_exact(pixels.len() * 3)
            .map_err(|_| too_large(size + pixels.len() * 3))?;
        data.extend(pixels.flat_map(|px| {
            if grey {
                [px[0]; 3]
            } else {
                [px[0], px[1], px[2]]
            }
        }));
        Ok(RgbImage::new(info.width, info.height, data))
    }

    /// The largest per-channel difference to `other` (`None` when sizes differ).
    pub fn max_difference(&self, other: &RgbImage) -> Option<u8> {
        (self.width == other.width && self.height == other.height).then(|| {
            self.data
                .iter()
                .zip(&other.data)
                .map(|(a, b)| a.abs_diff(*b))
                .max()
                .unwrap_or(0)
        })
    }

    /// Peak signal-to-noise ratio to `other` in dB over all channels of 8-bit
    /// values: `10·log10(255² / MSE)`; `∞` for identical images, `None` when the
    /// sizes differ.
    pub fn psnr(&self, other: &RgbImage) -> Option<f64> {
        if self.width != other.width || self.height != other.height {
            return None;
        }
        let sum: f64 = self
            .data
            .iter()
            .zip(&other.data)
            .map(|(a, b)| (f64::from(*a) - f64::from(*b)).powi(2))
            .sum();
        let mse = sum / self.data.len().max(1) as f64;
        Some(if mse == 0.0 {
            f64::INFINITY
        } else {
            10.0 * (255.0f64 * 255.0 / mse).log10()
        })
    }

    /// Number of channel values differing by more than `tolerance`.
    pub fn count_differences(&self, other: &RgbImage, tolerance: u8) -> usize {
        self.data
            .iter()
            .zip(&other.data)
            .filter(|(a, b)| a.abs_diff(**b) > tolerance)
            .count()
    }

    /// A diff image: per-channel absolute difference, amplified ×8 to be visible.
    pub fn diff(&self, other: &RgbImage) -> RgbImage {
        let data = self
            .data
            .iter()
            .zip(&other.data)
            .map(|(a, b)| a.abs_diff(*b).saturating_mul(8))
            .collect();
        RgbImage::new(self.width, self.height, data)
    }
}

/// The PNG decoder's error text without its debug dumps: `ChunkType { type:
/// IDAT, critical: true, … }` is said as `IDAT` (a damaged file printed them).
fn plain_png_error(text: &str) -> String {
    const DUMP: &str = "ChunkType { type: ";
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(at) = rest.find(DUMP) {
        out.push_str(&rest[..at]);
        let after = &rest[at + DUMP.len()..];
        let name_end = after.find([',', ' ', '}']).unwrap_or(after.len());
        out.push_str(&after[..name_end]);
        rest = after.find('}').map_or("", |end| &after[end + 1..]);
    }
    out.push_str(rest);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_errors_name_chunks_without_debug_dumps() {
        assert_eq!(
            plain_png_error(
                "CRC error: expected 0x1 have 0x2 while decoding ChunkType { type: IDAT, critical: true, private: false, reserved: false, safecopy: false } chunk."
            ),
            "CRC error: expected 0x1 have 0x2 while decoding IDAT chunk."
        );
        assert_eq!(
            plain_png_error("Invalid PNG signature."),
            "Invalid PNG signature."
        );
    }

    #[test]
    fn png_round_trip_and_diff() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.png");
        let img = RgbImage::new(3, 2, (0..18).map(|i| i * 10).collect());
        img.save_png(&path).unwrap();
        let back = RgbImage::load_png(&path).unwrap();
        assert_eq!(back, img);
        let mut other = img.clone();
        other.data[4] += 3;
        assert_eq!(img.max_difference(&other), Some(3));
        assert_eq!(img.count_differences(&other, 2), 1);
        assert_eq!(img.diff(&other).data[4], 24);
        assert!(RgbImage::load_png(&dir.path().join("none.png")).is_err());
        assert!(img.save_png(&dir.path().join("no/dir/a.png")).is_err());
    }

    /// A grey image is written as a greyscale PNG (it was 8-bit RGB) and reads
    /// back as the same pixels; one coloured pixel keeps the file RGB.
    #[test]
    fn a_grey_image_is_written_as_a_greyscale_png() {
        let dir = tempfile::tempdir().unwrap();
        let colour_type = |path: &Path| {
            let decoder = png::Decoder::new(BufReader::new(std::fs::File::open(path).unwrap()));
            decoder.read_info().unwrap().info().color_type
        };
        let grey = RgbImage::new(4, 3, (0..12u8).flat_map(|v| [v * 20; 3]).collect());
        assert!(grey.is_grey());
        let path = dir.path().join("grey.png");
        grey.save_png(&path).unwrap();
        assert_eq!(colour_type(&path), png::ColorType::Grayscale);
        assert_eq!(RgbImage::load_png(&path).unwrap(), grey);

        let mut tinted = grey.clone();
        tinted.data[7] += 1;
        assert!(!tinted.is_grey());
        let path = dir.path().join("tinted.png");
        tinted.save_png(&path).unwrap();
        assert_eq!(colour_type(&path), png::ColorType::Rgb);
        assert_eq!(RgbImage::load_png(&path).unwrap(), tinted);
    }

    /// Grey, 16-bit, palette and 1-bit PNGs (what other tools write) read as
    /// the RGB they show (before: "unsupported PNG format (Rgba, Sixteen)").
    #[test]
    fn every_png_colour_type_and_depth_reads_as_rgb() {
        let dir = tempfile::tempdir().unwrap();
        let write = |name: &str, colour, depth, palette: Option<&[u8]>, data: &[u8]| {
            let path = dir.path().join(name);
            let file = std::fs::File::create(&path).unwrap();
            let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), 2, 1);
            encoder.set_color(colour);
            encoder.set_depth(depth);
            if let Some(p) = palette {
                encoder.set_palette(p.to_vec());
            }
            let mut writer = encoder.write_header().unwrap();
            writer.write_image_data(data).unwrap();
            writer.finish().unwrap();
            RgbImage::load_png(&path).unwrap().data
        };
        use png::{BitDepth::*, ColorType::*};
        assert_eq!(
            write("g.png", Grayscale, Eight, None, &[7, 200]),
            [7, 7, 7, 200, 200, 200]
        );
        assert_eq!(
            write("ga.png", GrayscaleAlpha, Eight, None, &[7, 0, 200, 255]),
            [7, 7, 7, 200, 200, 200]
        );
        assert_eq!(
            write(
                "rgba16.png",
                Rgba,
                Sixteen,
                None,
                &[1, 0, 2, 0, 3, 0, 4, 0, 9, 9, 8, 8, 7, 7, 6, 6]
            ),
            [1, 2, 3, 9, 8, 7]
        );
        assert_eq!(
            write(
                "p.png",
                Indexed,
                Eight,
                Some(&[10, 20, 30, 40, 50, 60]),
                &[1, 0]
            ),
            [40, 50, 60, 10, 20, 30]
        );
        assert_eq!(
            write("bw.png", Grayscale, One, None, &[0b0100_0000]),
            [0, 0, 0, 255, 255, 255]
        );
    }

    #[test]
    fn psnr_follows_the_mean_squared_error() {
        let img = RgbImage::new(2, 2, vec![100; 12]);
        assert_eq!(img.psnr(&img), Some(f64::INFINITY));
        // One channel off by 12: MSE = 144/12 = 12.
        let mut other = img.clone();
        other.data[0] = 112;
        let want = 10.0 * (255.0f64 * 255.0 / 12.0).log10();
        assert!((img.psnr(&other).unwrap() - want).abs() < 1e-9);
        // Every channel off by 255: 0 dB.
        let black = RgbImage::new(2, 2, vec![0; 12]);
        let white = RgbImage::new(2, 2, vec![255; 12]);
        assert!(black.psnr(&white).unwrap().abs() < 1e-9);
        assert_eq!(img.psnr(&RgbImage::new(1, 2, vec![0; 6])), None);
    }
}
