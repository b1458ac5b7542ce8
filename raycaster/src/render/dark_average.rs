//! A dark average frame, and the domain that would show it.
//!
//! The mean along a ray through a scan is mostly air: on a CT, means lie in the
//! lowest fifth of the default domain (−1000 to 2000 HU), where the transfer
//! function shows little, and the picture is nearly black. The means' range is
//! measured on a small preview of the coarsest level with an opaque grey ramp
//! (each pixel is then its ray's mean, normalised over the domain), so front
//! ends can name a domain that spans them (`raycaster render`'s warning, the
//! viewer's message line).

use super::{
    Camera, ControlPoint, Mode, ParallelOptions, RenderError, RenderSettings, RenderVolume,
    RgbImage, TransferFunction, render_parallel,
};
use crate::volume::Volume;

/// The brightness (of 255: the 99th percentile of the pixels' brightest
/// channels) below which an average frame counts as dark.
const DARK: u8 = 64;

/// The preview's width in pixels.
const PREVIEW_WIDTH: u32 = 64;

/// Means filling less than this share of the domain are worth a narrower one.
const NARROW: f32 = 0.5;

/// Where the rays' means of a dark average frame lie in its transfer
/// function's domain.
#[derive(Clone, Debug, PartialEq)]
pub struct DarkAverage {
    /// The share of the domain, from its low end, that holds the means.
    pub share: f32,
    /// The domain, in the volume's value units.
    pub domain: [f64; 2],
    /// A domain that spans the means (a little above the highest), in the
    /// volume's value units, outward to whole values.
    pub spanning: [f64; 2],
}

/// For an average frame `image` of `volume` under `settings` and `camera` that
/// is dark because its rays' means lie low in the transfer function's domain,
/// where they lie; `None` for any other frame.
pub fn dark_average(
    volume: &Volume,
    settings: &RenderSettings,
    camera: &Camera,
    image: &RgbImage,
) -> Result<Option<DarkAverage>, RenderError> {
    if settings.mode != Mode::Average || settings.segments.is_some() {
        return Ok(None);
    }
    // Over every pixel: a mostly black picture with a few bright rays is dark.
    if percentile(image.data().chunks_exact(3).map(brightest)).is_none_or(|b| b >= DARK) {
        return Ok(None);
    }
    let Some(share) = highest_mean(volume, settings, camera)? else {
        return Ok(None);
    };
    if share >= NARROW {
        return Ok(None);
    }
    let units = volume.value_units();
    let [lo, hi] = settings
        .transfer
        .domain
        .unwrap_or([0.0, f32::from(volume.sample_type().max_value())]);
    let value = |stored: f32| units.value(f64::from(stored));
    let top = lo + (hi - lo) * (share * 1.1).min(1.0);
    Ok(Some(DarkAverage {
        share,
        domain: [value(lo), value(hi)],
        spanning: [value(lo).floor(), value(top).ceil()],
    }))
}

/// The highest ray mean (the 99th percentile) of a small preview of
/// `volume`'s coarsest level, as a fraction of the domain; `None` when no ray's
/// mean lies in the domain.
fn highest_mean(
    volume: &Volume,
    settings: &RenderSettings,
    camera: &Camera,
) -> Result<Option<f32>, RenderError> {
    let height = (PREVIEW_WIDTH * camera.height() / camera.width().max(1)).max(1);
    let camera = camera.with_size(PREVIEW_WIDTH, height)?;
    let ramp = |value: f32| ControlPoint {
        value,
        color: [value; 3],
        alpha: 1.0,
    };
    // (Two points in order, opacities in range: always a function.)
    let mut transfer =
        TransferFunction::new(vec![ramp(0.0), ramp(1.0)]).expect("a ramp of two points");
    transfer.domain = settings.transfer.domain;
    let preview = RenderSettings {
        transfer,
        shading: None,
        early_termination: None,
        background: [0.0; 3],
        jitter: false,
        preintegrated: false,
        ..settings.clone()
    };
    let coarsest = volume.level(volume.level_count() - 1);
    let prepared = RenderVolume::new(coarsest, None)?;
    let frame = render_parallel(&prepared, &camera, &preview, &ParallelOptions::default())?;
    // Over the lit pixels: the rays that met the volume (and whose mean lies
    // in the domain).
    let image = frame.to_image();
    let lit = image
        .data()
        .chunks_exact(3)
        .map(brightest)
        .filter(|&b| b > 0);
    Ok(percentile(lit).map(|b| f32::from(b) / 255.0))
}

/// A pixel's brightest channel.
fn brightest(pixel: &[u8]) -> u8 {
    pixel.iter().copied().max().unwrap_or(0)
}

/// The 99th percentile of `values` (a few bright rays do not make a picture);
/// `None` for none.
fn percentile(values: impl Iterator<Item = u8>) -> Option<u8> {
    let mut values: Vec<u8> = values.collect();
    if values.is_empty() {
        return None;
    }
    let at = (values.len() - 1) * 99 / 100;
    Some(*values.select_nth_unstable(at).1)
}

#[cfg(test)]
mod tests {
    use super::percentile;

    #[test]
    fn the_percentile_leaves_out_a_few_bright_pixels() {
        let mut values = vec![10u8; 990];
        values.extend([250u8; 10]);
        assert_eq!(percentile(values.iter().copied()), Some(10));
        assert_eq!(percentile(std::iter::empty()), None);
        assert_eq!(percentile([7u8].into_iter()), Some(7));
    }
}
