//! Sabella's colouring (Sabella 1988, "A rendering algorithm for visualizing 3D
//! scalar fields"): per ray the peak value `M`, its depth `D`, the value-weighted
//! centroid depth `C` and the accumulated intensity `I`, mapped to hue,
//! saturation and value.
//!
//! The four numbers of each pixel are its *channels* ([`SabellaChannels`]):
//! rendered once, they can be mapped to colours again with another
//! [`SabellaMapping`] without casting a ray ([`SabellaChannels::map`]); a frame
//! rendered in [`Mode::Sabella`](super::Mode::Sabella) with that mapping gives the
//! same pixels, because the compositor resolves each pixel with the same function.

use super::camera::Camera;
use super::counters::FrameStats;
use super::error::RenderError;
use super::frame::Frame;
use super::parallel::{ParallelOptions, render_parallel};
use super::prepared::RenderVolume;
use super::sequential::render_sequential;
use super::settings::{Mode, RenderSettings};

/// Which depth of a ray sets the saturation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SabellaDepth {
    /// `D`: where the ray meets its peak value.
    #[default]
    Peak,
    /// `C`: the value-weighted mean depth of the ray's samples.
    Centroid,
}

impl SabellaDepth {
    /// The name on the command line and in scene files.
    pub fn name(self) -> &'static str {
        match self {
            SabellaDepth::Peak => "peak",
            SabellaDepth::Centroid => "centroid",
        }
    }

    /// The depth named `name` (`peak` or `centroid`).
    pub fn parse(name: &str) -> Option<SabellaDepth> {
        match name {
            "peak" => Some(SabellaDepth::Peak),
            "centroid" => Some(SabellaDepth::Centroid),
            _ => None,
        }
    }
}

/// How a pixel's channels `(M, D, C, I)` become a colour: hue from the peak
/// value `M`, saturation from the depth `D` or `C`, value from the intensity `I`
/// (HSV), premultiplied with opacity `I`, so that over black the pixel is exactly
/// the HSV colour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SabellaMapping {
    /// Which depth sets the saturation.
    pub depth: SabellaDepth,
    /// Hue in degrees of the lowest and the highest peak value (`M` = 0 and 1);
    /// in between linearly. Default: 240 (blue) to 0 (red).
    pub hue: [f32; 2],
    /// Saturation at depth 0 (where the ray enters the volume) and 1 (where it
    /// leaves); in between linearly. Default: 1 to 0.2 (far things wash out, the
    /// depth cue of Sabella's paper).
    pub saturation: [f32; 2],
}

impl Default for SabellaMapping {
    fn default() -> Self {
        SabellaMapping {
            depth: SabellaDepth::Peak,
            hue: [240.0, 0.0],
            saturation: [1.0, 0.2],
        }
    }
}

impl SabellaMapping {
    /// The premultiplied RGBA of a pixel with channels `[m, d, c, i]` (each in
    /// `[0, 1]`; see [`SabellaChannels`]).
    pub fn rgba(&self, [m, d, c, i]: [f32; 4]) -> [f32; 4] {
        let hue = self.hue[0] + (self.hue[1] - self.hue[0]) * m;
        let depth = match self.depth {
            SabellaDepth::Peak => d,
            SabellaDepth::Centroid => c,
        };
        let saturation = (self.saturation[0] + (self.saturation[1] - self.saturation[0]) * depth)
            .clamp(0.0, 1.0);
        let [r, g, b] = hsv_to_rgb(hue, saturation, i);
        [r, g, b, i]
    }
}

/// What the pixels of a frame in [`Mode::Sabella`](super::Mode::Sabella) hold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SabellaOutput {
    /// Colours by the mapping.
    Colours(SabellaMapping),
    /// The raw channels `(M, D, C, I)` in the frame's RGBA, for
    /// [`SabellaChannels`] (not an image to show).
    Channels,
}

impl Default for SabellaOutput {
    fn default() -> Self {
        SabellaOutput::Colours(SabellaMapping::default())
    }
}

/// RGB of hue `h` (degrees, any), saturation `s` and value `v` (in `[0, 1]`).
pub fn hsv_to_rgb(h: f32, s: f32, v: f32) -> [f32; 3] {
    let h = h.rem_euclid(360.0) / 60.0;
    let sector = (h.floor() as u32).min(5);
    let f = h - sector as f32;
    let p = v * (1.0 - s);
    let q = v * (1.0 - s * f);
    let t = v * (1.0 - s * (1.0 - f));
    match sector {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    }
}

/// A frame's Sabella channels, per pixel `[M, D, C, I]`:
/// - `M`: the ray's largest value, normalised over the transfer function's
///   domain (clamped to `[0, 1]`);
/// - `D`: the depth of the first sample with that value, and `C`: the mean depth
///   of the ray's samples weighted by their normalised values — depths are 0
///   where the ray enters the (cut) volume and 1 where it leaves it;
/// - `I`: the intensity accumulated front to back with the transfer function's
///   opacities (white emission–absorption, no early termination).
///
/// Pixels whose rays miss the volume are all zero.
#[derive(Clone, Debug, PartialEq)]
pub struct SabellaChannels {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// `[M, D, C, I]` per pixel, row by row from the top.
    pub channels: Vec<[f32; 4]>,
    /// What rendering the channels cost.
    pub stats: FrameStats,
}

impl SabellaChannels {
    /// Renders the channels of `volume` seen by `camera` with `settings` (its mode
    /// and Sabella output are replaced), in parallel with `options`, or with the
    /// sequential renderer when `options` is `None`.
    pub fn render(
        volume: &RenderVolume<'_>,
        camera: &Camera,
        settings: &RenderSettings,
        options: Option<&ParallelOptions>,
    ) -> Result<SabellaChannels, RenderError> {
        let mut settings = settings.clone();
        settings.mode = Mode::Sabella;
        settings.mode_parameters.sabella = SabellaOutput::Channels;
        let frame = match options {
            Some(options) => render_parallel(volume, camera, &settings, options)?,
            None => render_sequential(volume, camera, &settings)?,
        };
        Ok(SabellaChannels {
            width: frame.width,
            height: frame.height,
            channels: frame.rgba,
            stats: frame.stats,
        })
    }

    /// The frame of these channels coloured by `mapping` over `background`: the
    /// frame a render with that mapping gives, without casting a ray.
    pub fn map(&self, mapping: &SabellaMapping, background: [f32; 3]) -> Frame {
        let mut frame = Frame::empty(self.width, self.height, background);
        for (px, ch) in frame.rgba.iter_mut().zip(&self.channels) {
            *px = mapping.rgba(*ch);
        }
        frame.stats = self.stats;
        frame
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hsv_primaries_and_greys() {
        assert_eq!(hsv_to_rgb(0.0, 1.0, 1.0), [1.0, 0.0, 0.0]);
        assert_eq!(hsv_to_rgb(120.0, 1.0, 1.0), [0.0, 1.0, 0.0]);
        assert_eq!(hsv_to_rgb(240.0, 1.0, 0.5), [0.0, 0.0, 0.5]);
        assert_eq!(hsv_to_rgb(360.0, 1.0, 1.0), [1.0, 0.0, 0.0]);
        assert_eq!(hsv_to_rgb(77.0, 0.0, 0.25), [0.25; 3]);
    }

    #[test]
    fn mapping_takes_hue_from_the_peak_and_saturation_from_the_chosen_depth() {
        let peak = SabellaMapping::default();
        // Highest peak, near: saturated red at the intensity.
        assert_eq!(peak.rgba([1.0, 0.0, 1.0, 0.5]), [0.5, 0.0, 0.0, 0.5]);
        // Lowest peak: blue.
        assert_eq!(peak.rgba([0.0, 0.0, 0.0, 1.0]), [0.0, 0.0, 1.0, 1.0]);
        let centroid = SabellaMapping {
            depth: SabellaDepth::Centroid,
            ..peak
        };
        // Far centroid: washed out (saturation 0.2).
        let [r, g, b, _] = centroid.rgba([1.0, 0.0, 1.0, 1.0]);
        assert_eq!([r, g, b], hsv_to_rgb(0.0, 0.2, 1.0));
        assert_ne!(
            centroid.rgba([1.0, 0.0, 1.0, 1.0]),
            peak.rgba([1.0, 0.0, 1.0, 1.0])
        );
        assert_eq!(peak.rgba([0.3, 0.4, 0.5, 0.0]), [0.0; 4]);
    }
}
