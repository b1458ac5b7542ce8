//! A rendered frame: per-pixel premultiplied RGBA and first-hit depth, plus stats.

use super::counters::FrameStats;
use super::image::RgbImage;
use super::pixel::over_background;

/// The result of rendering one frame.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Premultiplied RGBA per pixel, row by row from the top, before the background.
    pub rgba: Vec<[f32; 4]>,
    /// First-hit depth per pixel (world distance along the ray), `∞` elsewhere.
    pub depth: Vec<f32>,
    /// The background the image is composited over.
    pub background: [f32; 3],
    /// What the frame cost.
    pub stats: FrameStats,
}

impl Frame {
    /// An empty frame (every pixel transparent) of `width × height`.
    pub fn empty(width: u32, height: u32, background: [f32; 3]) -> Frame {
        let n = width as usize * height as usize;
        Frame {
            width,
            height,
            rgba: vec![[0.0; 4]; n],
            depth: vec![f32::INFINITY; n],
            background,
            stats: FrameStats {
                width,
                height,
                ..FrameStats::default()
            },
        }
    }

    /// Index of pixel `(x, y)` in [`Self::rgba`] and [`Self::depth`], for
    /// `x < width` and `y < height` (not checked: an index past a row is
    /// the next row's).
    #[inline]
    pub fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }

    /// The frame composited over its background, 8 bits per channel.
    pub fn to_image(&self) -> RgbImage {
        let mut data = vec![0u8; self.rgba.len() * 3];
        for (out, &px) in data.chunks_exact_mut(3).zip(&self.rgba) {
            out.copy_from_slice(&over_background(px, self.background));
        }
        RgbImage::new(self.width, self.height, data)
    }
}
