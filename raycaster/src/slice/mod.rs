//! Axis-aligned slices of a volume (multi-planar reformatting, MPR): one plane of
//! voxels read through the volume's samples — mapped or in RAM, linear or
//! bricked — and its greyscale image under a value window.
//!
//! Only the slice's voxels are read: a slice of a mapped 30 GB file touches the
//! pages holding that plane, nothing else.

use std::fmt;

mod layout;

pub use layout::{AnatomicalPlane, PlaneLayout};

use crate::render::RgbImage;
use crate::volume::{Sample, TypedVolume, Volume, VolumeData};

/// An axis of the volume's voxel grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Axis {
    /// The first axis (the slowest in linear files).
    X,
    /// The second axis.
    Y,
    /// The third (the slice axis of CT-like data; world up).
    Z,
}

impl Axis {
    /// Every axis.
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

    /// The axis's index (x 0, y 1, z 2).
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }

    /// The axis's name (`x`, `y`, `z`).
    pub fn name(self) -> &'static str {
        ["x", "y", "z"][self.index()]
    }

    /// The two other axes: the slice's columns and rows.
    pub fn in_plane(self) -> [usize; 2] {
        match self {
            Axis::X => [1, 2],
            Axis::Y => [0, 2],
            Axis::Z => [0, 1],
        }
    }
}

/// Why a slice cannot be taken.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SliceError {
    /// The index lies outside the volume along the axis.
    #[error("slice index {index} is outside the volume along {axis} (0..={last})", axis = axis.name())]
    Index {
        /// The axis.
        axis: Axis,
        /// The index asked for.
        index: u32,
        /// The last index along the axis.
        last: u32,
    },
    /// A window whose low end is not below its high end, or not finite.
    #[error("window {0},{1} must have finite lo < hi")]
    Window(f32, f32),
}

/// One slice of a volume: its raw values (u8 samples widened to u16), row by row.
///
/// Its [`PlaneLayout`] says which in-plane axis runs along the columns and
/// which along the rows, and which way each grows: in voxel order
/// ([`Slice::extract`]) columns run along the first in-plane axis
/// ([`Axis::in_plane`]: y for x slices, x otherwise), rows along the second (z
/// for x and y slices, y for z slices), its largest coordinate in the top row,
/// so that +z (world up) points up in x and y slices.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Slice {
    /// The axis the slice is perpendicular to.
    pub axis: Axis,
    /// Its index along that axis.
    pub index: u32,
    /// Where the in-plane axes run in the image.
    pub layout: PlaneLayout,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Raw values, `width × height`, rows from the top.
    pub values: Vec<u16>,
}

impl fmt::Display for Axis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl Slice {
    /// Slice `index` of `volume` perpendicular to `axis`, in voxel order
    /// ([`PlaneLayout::voxel_order`]).
    pub fn extract(volume: &Volume, axis: Axis, index: u32) -> Result<Slice, SliceError> {
        Self::extract_laid_out(volume, axis, index, PlaneLayout::voxel_order(axis))
    }

    /// Slice `index` of `volume` perpendicular to `axis`, laid out by `layout`
    /// (whose axes must be `axis`'s two in-plane axes, e.g.
    /// [`PlaneLayout::patient`]).
    pub fn extract_laid_out(
        volume: &Volume,
        axis: Axis,
        index: u32,
        layout: PlaneLayout,
    ) -> Result<Slice, SliceError> {
        let mut in_plane = [layout.columns, layout.rows];
        in_plane.sort_unstable();
        assert_eq!(in_plane, axis.in_plane(), "a layout of another plane");
        let dims = volume.dims();
        let a = axis.index();
        if index >= dims[a] {
            return Err(SliceError::Index {
                axis,
                index,
                last: dims[a] - 1,
            });
        }
        let values = match volume.data() {
            VolumeData::U8(data) => plane(&data, axis, index, &layout),
            VolumeData::U16(data) => plane(&data, axis, index, &layout),
        };
        Ok(Slice {
            axis,
            index,
            layout,
            width: dims[layout.columns],
            height: dims[layout.rows],
            values,
        })
    }

    /// The smallest and largest value in the slice.
    pub fn range(&self) -> [u16; 2] {
        self.values
            .iter()
            .fold([u16::MAX, 0], |[lo, hi], &v| [lo.min(v), hi.max(v)])
    }

    /// The slice as a greyscale image: `window` `[lo, hi]` (raw values) maps to
    /// black..white, values outside it clamp; `None` windows the slice's own
    /// value range (a flat slice shows mid-grey).
    pub fn to_image(&self, window: Option<[f32; 2]>) -> Result<RgbImage, SliceError> {
        let [lo, hi] = match window {
            Some([lo, hi]) => {
                if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                    return Err(SliceError::Window(lo, hi));
                }
                [lo, hi]
            }
            None => self.range().map(f32::from),
        };
        // (In f64: `hi − lo` of a window of ±3e38 overflows f32, and the
        // slice came out black.)
        let (lo, width) = (f64::from(lo), f64::from(hi) - f64::from(lo));
        let grey = |v: u16| -> u8 {
            if width > 0.0 {
                let g = (f64::from(v) - lo) / width;
                (g.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
            } else {
                128
            }
        };
        let data = self
            .values
            .iter()
            .flat_map(|&v| {
                let g = grey(v);
                [g, g, g]
            })
            .collect();
        Ok(RgbImage::new(self.width, self.height, data))
    }
}

/// The longest side [`Slice::to_square_image`] stretches a slice to.
pub const MAX_SQUARE_SIDE: u32 = 8192;

impl Slice {
    /// [`Self::to_image`] with square pixels: `spacing` is the voxel spacing
    /// along the slice's columns and rows ([`PlaneLayout`]), and the axis of
    /// the larger one is stretched, interpolating linearly between its voxels,
    /// so that a pixel stands for the same length both ways (a coronal slice
    /// of a CT scan with 5 mm between its 48 slices and 0.7 mm pixels is 48
    /// voxels but about 340 pixels high). The stretched side stops at
    /// [`MAX_SQUARE_SIDE`] (or the voxel count, if larger). A spacing that is
    /// not positive and finite both ways stretches nothing (the image is
    /// [`Self::to_image`]'s).
    pub fn to_square_image(
        &self,
        window: Option<[f32; 2]>,
        spacing: [f32; 2],
    ) -> Result<RgbImage, SliceError> {
        let image = self.to_image(window)?;
        let [su, sv] = spacing;
        if !(su > 0.0 && sv > 0.0 && su.is_finite() && sv.is_finite()) || su == sv {
            return Ok(image);
        }
        let stretch = |side: u32, factor: f32| -> u32 {
            let wanted = (f64::from(side) * f64::from(factor)).round();
            wanted.min(f64::from(MAX_SQUARE_SIDE.max(side))) as u32
        };
        let (w, h) = (self.width, self.height);
        let (width, height) = if sv > su {
            (w, stretch(h, sv / su))
        } else {
            (stretch(w, su / sv), h)
        };
        Ok(resample(&image, width, height))
    }
}

/// `image` resized to `width × height` (each no smaller than the image's),
/// interpolating linearly between pixel centres.
fn resample(image: &RgbImage, width: u32, height: u32) -> RgbImage {
    let (w, h) = (image.width(), image.height());
    // Where output pixel `i` of `n` lies among `m` source pixels: the two it
    // falls between and its weight on the second.
    let source = |i: u32, n: u32, m: u32| -> (u32, u32, f32) {
        let p = ((i as f32 + 0.5) * m as f32 / n as f32 - 0.5).clamp(0.0, (m - 1) as f32);
        let below = p as u32;
        (below, (below + 1).min(m - 1), p - below as f32)
    };
    let mut data = Vec::with_capacity(width as usize * height as usize * 3);
    for y in 0..height {
        let (y0, y1, fy) = source(y, height, h);
        for x in 0..width {
            let (x0, x1, fx) = source(x, width, w);
            let [a, b, c, d] =
                [(x0, y0), (x1, y0), (x0, y1), (x1, y1)].map(|(x, y)| image.pixel(x, y));
            for ch in 0..3 {
                let top = f32::from(a[ch]) + (f32::from(b[ch]) - f32::from(a[ch])) * fx;
                let bottom = f32::from(c[ch]) + (f32::from(d[ch]) - f32::from(c[ch])) * fx;
                data.push((top + (bottom - top) * fy + 0.5) as u8);
            }
        }
    }
    RgbImage::new(width, height, data)
}

/// The plane's values, rows from the top, laid out by `layout` (see [`Slice`]).
fn plane<T: Sample>(
    data: &TypedVolume<'_, T>,
    axis: Axis,
    index: u32,
    layout: &PlaneLayout,
) -> Vec<u16> {
    let dims = data.dims();
    let (u, v) = (layout.columns, layout.rows);
    let (width, height) = (dims[u], dims[v]);
    let mut out = Vec::with_capacity(width as usize * height as usize);
    for row in 0..height {
        for col in 0..width {
            let mut voxel = [0u32; 3];
            voxel[axis.index()] = index;
            voxel[u] = layout.column(col, width);
            voxel[v] = layout.row(row, height);
            out.push(data.voxel(voxel).to_u16());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_pixels_stretch_the_axis_with_the_larger_spacing() {
        // Columns 0, 100, 200; rows from the top 10 apart.
        let slice = Slice {
            axis: Axis::Y,
            index: 0,
            layout: PlaneLayout::voxel_order(Axis::Y),
            width: 3,
            height: 2,
            values: vec![0, 100, 200, 10, 110, 210],
        };
        let plain = slice.to_image(Some([0.0, 255.0])).unwrap();
        assert_eq!(
            slice
                .to_square_image(Some([0.0, 255.0]), [1.0, 1.0])
                .unwrap(),
            plain
        );
        // Rows 4 times as far apart as columns: 8 rows, interpolated between.
        let tall = slice
            .to_square_image(Some([0.0, 255.0]), [0.5, 2.0])
            .unwrap();
        assert_eq!((tall.width(), tall.height()), (3, 8));
        let column: Vec<u8> = (0..8).map(|y| tall.pixel(1, y)[0]).collect();
        assert_eq!(column, [100, 100, 101, 104, 106, 109, 110, 110]);
        // Columns farther apart: wider, the rows' values kept.
        let wide = slice
            .to_square_image(Some([0.0, 255.0]), [3.0, 1.0])
            .unwrap();
        assert_eq!((wide.width(), wide.height()), (9, 2));
        assert_eq!(
            (
                wide.pixel(0, 0)[0],
                wide.pixel(4, 0)[0],
                wide.pixel(8, 1)[0]
            ),
            (0, 100, 210)
        );
        // An absurd ratio stops at the largest side.
        let capped = slice.to_square_image(None, [1.0, 1e4]).unwrap();
        assert_eq!((capped.width(), capped.height()), (3, MAX_SQUARE_SIDE));
    }
    use crate::volume::{Content, Format, Header, Layout, SampleType};

    fn volume() -> Volume {
        let dims = [5, 4, 3];
        let header = Header::new(
            dims,
            [1.0; 3],
            Layout::Linear,
            SampleType::U16,
            Content::Scalar,
            Format::Extended,
        );
        let mut samples = Vec::new();
        for x in 0..5u16 {
            for y in 0..4u16 {
                for z in 0..3u16 {
                    samples.push(100 * x + 10 * y + z);
                }
            }
        }
        Volume::from_samples("slices", &header, &samples).unwrap()
    }

    #[test]
    fn slices_put_columns_and_rows_on_the_other_axes_top_row_highest() {
        let v = volume();
        let z = Slice::extract(&v, Axis::Z, 2).unwrap();
        assert_eq!((z.width, z.height), (5, 4));
        // Top row: y = 3; column x.
        assert_eq!(&z.values[..5], &[32, 132, 232, 332, 432]);
        let x = Slice::extract(&v, Axis::X, 4).unwrap();
        assert_eq!((x.width, x.height), (4, 3));
        assert_eq!(&x.values[..4], &[402, 412, 422, 432]);
        let y = Slice::extract(&v, Axis::Y, 1).unwrap();
        assert_eq!(y.values[y.values.len() - 1], 410);
        assert_eq!(y.range(), [10, 412]);
        assert_eq!(
            Slice::extract(&v, Axis::Y, 4),
            Err(SliceError::Index {
                axis: Axis::Y,
                index: 4,
                last: 3
            })
        );
    }

    #[test]
    fn windows_map_to_grey_and_clamp() {
        let v = volume();
        let z = Slice::extract(&v, Axis::Z, 0).unwrap();
        let image = z.to_image(Some([0.0, 100.0])).unwrap();
        // Top row, x = 0: value 30 → 77; x ≥ 1: ≥ 130 → white.
        assert_eq!(image.pixel(0, 0), [77; 3]);
        assert_eq!(image.pixel(1, 0), [255; 3]);
        let own = z.to_image(None).unwrap();
        assert_eq!(own.pixel(0, 3), [0; 3]);
        assert_eq!(own.pixel(4, 0), [255; 3]);
        assert!(z.to_image(Some([5.0, 5.0])).is_err());
        // The widest windows f32 holds: every value lies about halfway (their
        // width overflowed f32, and the slice was black).
        let widest = z.to_image(Some([-3e38, 3e38])).unwrap();
        assert_eq!(widest.pixel(0, 0), [128; 3]);
        assert_eq!(widest.pixel(4, 0), [128; 3]);
    }
}
