//! A rendered frame: per-pixel premultiplied RGBA and first-hit depth, plus stats.

use super::counters::FrameStats;
use super::error::RenderError;
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
    ///
    /// # Panics
    ///
    /// Where the system refuses the frame's memory ([`Self::try_empty`] says
    /// it as an error).
    pub fn empty(width: u32, height: u32, background: [f32; 3]) -> Frame {
        Frame::try_empty(width, height, background).unwrap_or_else(|e| panic!("{e}"))
    }

    /// [`Self::empty`], or an error where the system refuses the frame's
    /// memory (a frame of `width × height` pixels takes 20 bytes a pixel).
    pub fn try_empty(width: u32, height: u32, background: [f32; 3]) -> Result<Frame, RenderError> {
        let n = width as usize * height as usize;
        let bytes = (n as u64).saturating_mul(16 + 4);
        // Asked for first, then allocated as `vec!` does (zeroed pages the
        // system hands out as they are first written: a frame of which the
        // volume covers a corner touches little of its memory).
        if !crate::alloc_check::system_gives(bytes) {
            return Err(RenderError::FrameMemory {
                width,
                height,
                bytes,
            });
        }
        Ok(Frame {
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
        })
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame the system cannot hold is an error naming its size (an abort in
    /// the allocator, or a capacity-overflow panic, before).
    #[test]
    fn a_frame_too_large_for_memory_is_an_error() {
        let e = Frame::try_empty(u32::MAX, u32::MAX, [0.0; 3])
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("a 4294967295×4294967295 frame takes"), "{e}");
        let f = Frame::try_empty(3, 2, [0.0; 3]).unwrap();
        assert_eq!((f.rgba.len(), f.depth.len()), (6, 6));
        assert!(f.depth.iter().all(|d| d.is_infinite()));
    }
}
