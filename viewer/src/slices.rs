//! Slice views (MPR): three orthogonal slices through a crosshair point, read
//! from the volume with [`raycaster::slice`] and drawn with the crosshair's lines.
//!
//! Slices of a large volume are read from the finest pyramid level whose slices
//! are at most [`MAX_SLICE_EDGE`] voxels on a side (a slice of a 3072³ file reads
//! a 384² plane of its level 3), so they show at once; the crosshair is kept in
//! full-resolution voxels.

use raycaster::render::RgbImage;
use raycaster::session::SliceWindow;
use raycaster::slice::{Axis, PlaneLayout, Slice, SliceError};
use raycaster::volume::{ValueUnits, Volume};
use raycaster::windows::NAMED_WINDOWS;

use crate::navigation::WHEEL_NOTCH;

/// The largest slice side read (larger volumes use a coarser pyramid level).
pub(crate) const MAX_SLICE_EDGE: u32 = 512;

/// A crosshair line is one image pixel thick per this many pixels of the
/// image's side (a 512-pixel slice shown 150 pixels wide keeps its lines).
const LINE_SPAN: u32 = 128;

/// The colour of each axis's slice and of the crosshair line showing it: x red,
/// y green, z blue.
pub(crate) const AXIS_COLOURS: [[u8; 3]; 3] = [[230, 70, 70], [70, 200, 90], [80, 140, 255]];

/// The slice views' names, by axis (x, y, z), for a volume not placed in the
/// patient.
pub(crate) const VIEW_NAMES: [&str; 3] = ["sagittal (x)", "coronal (y)", "axial (z)"];

/// The slice views' names for `volume`: the anatomical plane each axis's slices
/// lie in for a volume placed in the patient, [`VIEW_NAMES`] otherwise.
pub(crate) fn view_names(volume: &Volume) -> [String; 3] {
    Axis::ALL.map(
        |axis| match PlaneLayout::patient(axis, volume.orientation()).1 {
            Some(plane) => format!("{} ({axis})", plane.name()),
            None => VIEW_NAMES[axis.index()].to_string(),
        },
    )
}

/// The last window choice: the window set by right-dragging on a slice.
pub(crate) const CUSTOM_WINDOW: &str = "custom (right-drag a slice)";

/// The window choices: the fitted window, the named windows, then the custom one.
pub(crate) fn window_names() -> Vec<String> {
    std::iter::once("fitted".to_string())
        .chain(NAMED_WINDOWS.iter().map(|w| w.name.to_string()))
        .chain(std::iter::once(CUSTOM_WINDOW.to_string()))
        .collect()
}

/// Window choice `index` ([`window_names`]) as a session holds it; `custom` is
/// the window of the last choice (set by a right-drag).
pub(crate) fn session_window(index: usize, custom: [f32; 2]) -> SliceWindow {
    match index {
        0 => SliceWindow::Fitted,
        i => match NAMED_WINDOWS.get(i - 1) {
            Some(w) => SliceWindow::Named(w.name.into()),
            None => SliceWindow::Values(custom),
        },
    }
}

/// The window choice ([`window_names`]) of a session's window: 0 for the fitted
/// one or a name no longer known, the last for set values.
pub(crate) fn window_index(window: &SliceWindow) -> usize {
    match window {
        SliceWindow::Fitted => 0,
        SliceWindow::Named(name) => NAMED_WINDOWS
            .iter()
            .position(|w| w.name == name)
            .map_or(0, |i| i + 1),
        SliceWindow::Values(_) => NAMED_WINDOWS.len() + 1,
    }
}

/// Free window/level: `base` changed by a drag of `dx`, `dy` (fractions of the
/// slice view's width and height) over data whose values span `span`. Dragging
/// right widens the window (less contrast), dragging down lowers its centre (a
/// brighter picture), each by `span` per view; the width stays positive.
pub(crate) fn dragged_window(base: [f32; 2], dx: f32, dy: f32, span: f32) -> [f32; 2] {
    let (dx, dy) = (dx.clamp(-4.0, 4.0), dy.clamp(-4.0, 4.0));
    let span = if span.is_finite() && span > 0.0 {
        span
    } else {
        1.0
    };
    let width = (base[1] - base[0] + dx * span).max(span * 0.002);
    let centre = (base[0] + base[1]) / 2.0 - dy * span;
    [centre - width / 2.0, centre + width / 2.0]
}

/// The stored-value window of choice `index` ([`window_names`]): 0 the fitted
/// domain (`fitted`, else the sample type's range), then the named windows
/// converted through the file's units.
pub(crate) fn window(index: usize, fitted: [f32; 2], units: &ValueUnits) -> [f32; 2] {
    match index.checked_sub(1).and_then(|i| NAMED_WINDOWS.get(i)) {
        Some(w) => units.stored_range(w.range()),
        None => fitted,
    }
}

/// What to say when window choice `index` is a named CT window (in Hounsfield
/// units) and `volume` holds values that do not look like CT (stored samples
/// without units, or values in units of their own): the window then applies
/// to those values as they are
/// (`raycaster slice --window` warns the same way). `None` otherwise.
pub(crate) fn named_window_note(index: usize, volume: &Volume) -> Option<String> {
    let named = index.checked_sub(1).and_then(|i| NAMED_WINDOWS.get(i))?;
    raycaster::windows::ct_window_misreads(volume).then(|| {
        let [lo, hi] = named.range();
        let (holds, values) = if volume.value_units().is_identity() {
            ("values without units", "stored values")
        } else {
            (
                "values not said to be Hounsfield units (no air in them)",
                "its values",
            )
        };
        format!(
            "the {} window is a CT window in Hounsfield units, and this volume holds {holds}: \
             it shows {values} {lo} to {hi} (right-drag a slice for a window of its own)",
            named.name
        )
    })
}

/// A window as people read it, in the file's units: `-1350 HU .. 150 HU`.
/// A window dragged by hand reads to a thousandth of its width or finer
/// (`-1163 .. 1340`, not `-1162.8672 .. 1340.0078`).
pub(crate) fn describe_window([lo, hi]: [f32; 2], units: &ValueUnits) -> String {
    let (lo, hi) = (units.value(f64::from(lo)), units.value(f64::from(hi)));
    let span = (hi - lo).abs();
    let unit = if span.is_finite() && span > 0.0 {
        10f64.powf(span.log10().floor() - 3.0)
    } else {
        1.0
    };
    let rounded = |v: f64| (v / unit).round() * unit;
    format!(
        "{} .. {}",
        units.format(rounded(lo)),
        units.format(rounded(hi))
    )
}

/// The pyramid level slices of `volume` are read from: the finest whose sides
/// are all at most [`MAX_SLICE_EDGE`] (the coarsest when none is).
pub(crate) fn slice_level(volume: &Volume) -> usize {
    (0..volume.level_count())
        .find(|&k| volume.level(k).dims().iter().all(|&d| d <= MAX_SLICE_EDGE))
        .unwrap_or(volume.level_count() - 1)
}

/// The crosshair: a voxel of the full-resolution volume.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Crosshair {
    /// The voxel.
    pub voxel: [u32; 3],
    dims: [u32; 3],
}

impl Crosshair {
    /// The centre of a volume of `dims` voxels.
    pub(crate) fn centre(dims: [u32; 3]) -> Crosshair {
        Crosshair {
            voxel: dims.map(|d| d.saturating_sub(1) / 2),
            dims,
        }
    }

    /// Voxel `voxel` of a volume of `dims` voxels, moved inside it.
    pub(crate) fn at(voxel: [u32; 3], dims: [u32; 3]) -> Crosshair {
        Crosshair {
            voxel: [0, 1, 2].map(|a| voxel[a].min(dims[a].saturating_sub(1))),
            dims,
        }
    }

    /// Moves along `axis` by `steps` voxels, staying inside the volume.
    pub(crate) fn step(&mut self, axis: Axis, steps: i64) {
        let a = axis.index();
        let last = i64::from(self.dims[a].saturating_sub(1));
        self.voxel[a] = (i64::from(self.voxel[a]) + steps).clamp(0, last) as u32;
    }

    /// Moves to the point clicked in the image of a slice laid out by
    /// `layout`, at image pixel `(col, row)` of an image of `size` (columns,
    /// rows) read from a level whose voxels span `scale` full-resolution
    /// voxels; the slice's own index stays.
    pub(crate) fn click(
        &mut self,
        layout: &PlaneLayout,
        [col, row]: [f32; 2],
        [width, height]: [u32; 2],
        scale: u32,
    ) {
        let pixel = |i: f32| i.floor().max(0.0) as u32;
        let to_voxel = |i: u32, last: u32| -> u32 { (i * scale + scale / 2).min(last) };
        let (u, v) = (layout.columns, layout.rows);
        let along_u = layout.column(pixel(col).min(width.saturating_sub(1)), width);
        let along_v = layout.row(pixel(row).min(height.saturating_sub(1)), height);
        self.voxel[u] = to_voxel(along_u, self.dims[u].saturating_sub(1));
        self.voxel[v] = to_voxel(along_v, self.dims[v].saturating_sub(1));
    }
}

/// The part of an axis of `len` pixels a zoom of `zoom` shows, centred on
/// `centre` as far as the ends allow: its first pixel and its length. A part
/// smaller than the axis has an odd length, so the centre pixel lies in its
/// middle (an even one left it half a pixel off).
pub(crate) fn zoom_span(len: u32, centre: u32, zoom: f32) -> (u32, u32) {
    let zoom = if zoom.is_finite() { zoom.max(1.0) } else { 1.0 };
    let count = ((len as f32 / zoom).round() as u32).clamp(1, len.max(1));
    let count = if count < len && count.is_multiple_of(2) {
        count + 1
    } else {
        count
    };
    let start = centre
        .saturating_sub(count / 2)
        .min(len.saturating_sub(count));
    (start, count)
}

/// How the slice views lay out a slice of `volume` perpendicular to `axis`:
/// as radiologists read it for a volume placed in the patient
/// ([`PlaneLayout::patient`]), voxel order otherwise.
pub(crate) fn slice_layout(volume: &Volume, axis: Axis) -> PlaneLayout {
    PlaneLayout::patient(axis, volume.orientation()).0
}

/// The slice of `volume` (level `level` of it) perpendicular to `axis` through
/// the crosshair, laid out by [`slice_layout`], windowed by `window` (stored
/// values), with the crosshair's two
/// other slices drawn as lines in their axes' colours, zoomed by `zoom` (≥ 1)
/// about the crosshair. Returns the image and where its top-left pixel lies in
/// the whole slice (column, row).
pub(crate) fn slice_image(
    volume: &Volume,
    level: usize,
    axis: Axis,
    crosshair: &Crosshair,
    window: [f32; 2],
    zoom: f32,
) -> Result<(RgbImage, [u32; 2]), SliceError> {
    let data = volume.level(level);
    let scale = 1u32 << level;
    let at = |a: usize| (crosshair.voxel[a] / scale).min(data.dims()[a].saturating_sub(1));
    let layout = slice_layout(volume, axis);
    let slice = Slice::extract_laid_out(data, axis, at(axis.index()), layout)?;
    let image = slice.to_image(Some(window))?;
    let (w, h) = (image.width(), image.height());
    let mut rgb = image.data().to_vec();
    let (u, v) = (layout.columns, layout.rows);
    let col = layout.column(at(u).min(w - 1), w);
    let row = layout.row(at(v).min(h - 1), h);
    // The part shown, zoomed about the crosshair.
    let (x0, cw) = zoom_span(w, col.min(w - 1), zoom);
    let (y0, ch) = zoom_span(h, row, zoom);
    // Lines stay visible when the view shows the part smaller than it is, and
    // thin when zoomed in: a line is one pixel per LINE_SPAN pixels of the
    // shown part's side thick.
    let thick = |len: u32| len.div_ceil(LINE_SPAN).max(1);
    for x in col.min(w - 1)..(col.min(w - 1) + thick(cw)).min(w) {
        for y in 0..h {
            let i = ((y * w + x) * 3) as usize;
            rgb[i..i + 3].copy_from_slice(&AXIS_COLOURS[u]);
        }
    }
    for y in row..(row + thick(ch)).min(h) {
        for x in 0..w {
            let i = ((y * w + x) * 3) as usize;
            rgb[i..i + 3].copy_from_slice(&AXIS_COLOURS[v]);
        }
    }
    if (cw, ch) == (w, h) {
        return Ok((RgbImage::new(w, h, rgb), [0, 0]));
    }
    let mut cropped = Vec::with_capacity((cw * ch * 3) as usize);
    for y in y0..y0 + ch {
        let start = ((y * w + x0) * 3) as usize;
        cropped.extend_from_slice(&rgb[start..start + (cw * 3) as usize]);
    }
    Ok((RgbImage::new(cw, ch, cropped), [x0, y0]))
}

/// Turns a view's wheel deltas into whole slice steps ([`WHEEL_NOTCH`] each): a mouse's notch is one
/// step, a touchpad's many small deltas add up to steps rather than each
/// being one, and turning back starts afresh.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct WheelSteps {
    rest: f32,
}

impl WheelSteps {
    /// The whole steps `delta` completes (positive up), the rest kept.
    pub(crate) fn steps(&mut self, delta: f32) -> i64 {
        if !delta.is_finite() || delta == 0.0 {
            return 0;
        }
        if self.rest != 0.0 && self.rest.signum() != delta.signum() {
            self.rest = 0.0;
        }
        self.rest += delta;
        let steps = (self.rest / WHEEL_NOTCH).trunc().clamp(-1e6, 1e6);
        self.rest -= steps * WHEEL_NOTCH;
        steps as i64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wheel_notches_are_steps_and_small_deltas_add_up() {
        let mut wheel = WheelSteps::default();
        assert_eq!(wheel.steps(60.0), 1);
        assert_eq!(wheel.steps(-60.0), -1);
        assert_eq!(wheel.steps(180.0), 3);
        // A touchpad: 7 deltas of 20 are two steps, 20 left over.
        let steps: i64 = (0..7).map(|_| wheel.steps(20.0)).sum();
        assert_eq!(steps, 2);
        // Turning back drops the rest: a notch down is one step down.
        assert_eq!(wheel.steps(-60.0), -1);
        assert_eq!(wheel.steps(-30.0), 0);
        assert_eq!((wheel.steps(f32::NAN), wheel.steps(0.0)), (0, 0));
        assert_eq!(wheel.steps(-30.0), -1);
    }

    /// The gradient scene of `dims` voxels written to a linear u8 file in `dir`.
    fn gradient_file(dir: &std::path::Path, dims: [u32; 3]) -> Volume {
        let volume = raycaster::synth::SceneKind::Gradient.build(dims, 1);
        let path = dir.join("gradient.vol");
        let header = raycaster::volume::Header::new(
            dims,
            [1.0; 3],
            raycaster::volume::Layout::Linear,
            raycaster::volume::SampleType::U8,
            raycaster::volume::Content::Scalar,
            raycaster::volume::Format::Extended,
        );
        raycaster::generate::generate(
            volume.as_ref(),
            &header,
            &path,
            &Default::default(),
            &raycaster::job::Job::silent(),
        )
        .unwrap();
        Volume::open(&path).unwrap()
    }

    #[test]
    fn clicks_move_the_other_axes() {
        let mut c = Crosshair::centre([100, 80, 60]);
        assert_eq!(c.voxel, [49, 39, 29]);
        // An axial (z) slice in voxel order: columns x, rows y from the top.
        c.click(
            &PlaneLayout::voxel_order(Axis::Z),
            [10.0, 0.0],
            [100, 80],
            1,
        );
        assert_eq!(c.voxel, [10, 79, 29]);
        // A coronal slice of level 1 (voxels of 2): columns x, rows z.
        c.click(&PlaneLayout::voxel_order(Axis::Y), [5.0, 29.0], [50, 30], 2);
        assert_eq!(c.voxel, [11, 79, 1]);
        // Columns mirrored (x growing to the left), rows from the top down.
        let mirrored = PlaneLayout {
            columns: 0,
            grows_right: false,
            rows: 1,
            grows_up: false,
        };
        c.click(&mirrored, [10.0, 0.0], [100, 80], 1);
        assert_eq!(c.voxel, [89, 0, 1]);
        c.step(Axis::Z, -5);
        assert_eq!(c.voxel[2], 0);
        c.step(Axis::X, 1000);
        assert_eq!(c.voxel[0], 99);
    }

    #[test]
    fn windows_convert_through_the_units() {
        let hu = ValueUnits::new(1.0, -32768.0, "HU").unwrap();
        assert_eq!(window(0, [1.0, 2.0], &hu), [1.0, 2.0]);
        let lung = NAMED_WINDOWS.iter().position(|w| w.name == "lung").unwrap();
        let w = window(lung + 1, [1.0, 2.0], &hu);
        assert_eq!(w, [32768.0 - 1350.0, 32768.0 + 150.0]);
        assert_eq!(describe_window(w, &hu), "-1350 HU .. 150 HU");
        // A window dragged by hand: to a thousandth of its width.
        assert_eq!(
            describe_window([31605.133, 34108.008], &hu),
            "-1163 HU .. 1340 HU"
        );
        let plain = ValueUnits::new(1.0, 0.0, "").unwrap();
        assert_eq!(
            describe_window([0.12341, 0.62347], &plain),
            "0.1234 .. 0.6235"
        );
        assert_eq!(window_names().len(), NAMED_WINDOWS.len() + 2);
        assert_eq!(window_names().last().unwrap(), CUSTOM_WINDOW);
    }

    #[test]
    fn ct_windows_on_values_without_units_are_said_to_apply_to_stored_values() {
        let dir = tempfile::tempdir().unwrap();
        let volume = gradient_file(dir.path(), [8, 8, 8]);
        let lung = NAMED_WINDOWS.iter().position(|w| w.name == "lung").unwrap() + 1;
        let note = named_window_note(lung, &volume).unwrap();
        assert!(
            note.starts_with("the lung window is a CT window in Hounsfield units"),
            "{note}"
        );
        assert!(note.contains("stored values -1350 to 150"), "{note}");
        // The fitted window and the custom one say nothing.
        assert_eq!(named_window_note(0, &volume), None);
        assert_eq!(named_window_note(window_names().len() - 1, &volume), None);
        // CT values (signed 16-bit, kept with their offset) take it as meant.
        let mut bytes = b"NRRD0004\ntype: short\ndimension: 3\nsizes: 4 4 4\n\
endian: little\nencoding: raw\n\n"
            .to_vec();
        for i in 0..64i16 {
            bytes.extend_from_slice(&(i * 40 - 1024).to_le_bytes());
        }
        let path = dir.path().join("ct.nrrd");
        std::fs::write(&path, bytes).unwrap();
        let ct = raycaster::import::open(&path)
            .unwrap()
            .to_volume_noting(
                raycaster::import::DEFAULT_IN_MEMORY_LIMIT,
                &raycaster::job::Job::silent(),
            )
            .unwrap()
            .0;
        assert!(!ct.value_units().is_identity());
        assert_eq!(named_window_note(lung, &ct), None);
    }

    #[test]
    fn window_choices_and_session_windows_map_both_ways() {
        let custom = [1.0, 2.0];
        for index in 0..window_names().len() {
            assert_eq!(window_index(&session_window(index, custom)), index);
        }
        assert_eq!(session_window(0, custom), SliceWindow::Fitted);
        assert_eq!(
            session_window(window_names().len() - 1, custom),
            SliceWindow::Values(custom)
        );
        assert_eq!(window_index(&SliceWindow::Named("gone".into())), 0);
    }

    #[test]
    fn dragging_widens_and_moves_the_window() {
        let base = [100.0, 200.0];
        assert_eq!(dragged_window(base, 0.0, 0.0, 1000.0), base);
        // Right a tenth of the view: 100 wider about the same centre.
        assert_eq!(dragged_window(base, 0.1, 0.0, 1000.0), [50.0, 250.0]);
        // Down a tenth: the centre 100 lower.
        assert_eq!(dragged_window(base, 0.0, 0.1, 1000.0), [0.0, 100.0]);
        // Far left: the width stays positive.
        let narrow = dragged_window(base, -1.0, 0.0, 1000.0);
        assert!(narrow[1] > narrow[0] && (narrow[1] - narrow[0] - 2.0).abs() < 1e-3);
        let odd = dragged_window(base, f32::NAN.max(0.0), 0.0, f32::NAN);
        assert_eq!(odd, base);
    }

    #[test]
    fn slices_show_the_crosshair() {
        let dir = tempfile::tempdir().unwrap();
        let volume = gradient_file(dir.path(), [20, 16, 12]);
        assert_eq!(slice_level(&volume), 0);
        let c = Crosshair::centre(volume.dims());
        let (image, at) = slice_image(&volume, 0, Axis::Z, &c, [0.0, 255.0], 1.0).unwrap();
        assert_eq!(at, [0, 0]);
        assert_eq!((image.width(), image.height()), (20, 16));
        let px = |x: u32, y: u32| {
            let i = ((y * 20 + x) * 3) as usize;
            [image.data()[i], image.data()[i + 1], image.data()[i + 2]]
        };
        // The x line (red) at column 9, the y line (green) at row 15 − 7.
        assert_eq!(px(9, 0), AXIS_COLOURS[0]);
        assert_eq!(px(0, 8), AXIS_COLOURS[1]);
        // Zoomed 2×: 11 × 9 pixels (odd: the crosshair in the middle) about
        // the crosshair (column 9, row 8), which lies at (5, 4) of them.
        let (zoomed, at) = slice_image(&volume, 0, Axis::Z, &c, [0.0, 255.0], 2.0).unwrap();
        assert_eq!((zoomed.width(), zoomed.height()), (11, 9));
        assert_eq!(at, [4, 4]);
        let i = ((4 * 11 + 5) * 3) as usize;
        assert_eq!(zoomed.data()[i..i + 3], AXIS_COLOURS[1]);
        let i = 5 * 3; // row 0, column 5
        assert_eq!(zoomed.data()[i..i + 3], AXIS_COLOURS[0]);
    }

    /// A NRRD volume of `dims` u16 voxels placed in RAS space (x grows to the
    /// patient's right, y anterior, z superior), opened as the viewer opens it.
    fn ras_volume(dir: &std::path::Path, dims: [u32; 3]) -> Volume {
        let mut bytes = format!(
            "NRRD0004\ntype: unsigned short\ndimension: 3\nsizes: {} {} {}\n\
             space: right-anterior-superior\nspace directions: (1,0,0) (0,1,0) (0,0,1)\n\
             space origin: (0,0,0)\nendian: little\nencoding: raw\n\n",
            dims[0], dims[1], dims[2]
        )
        .into_bytes();
        for i in 0..dims.iter().product::<u32>() {
            bytes.extend_from_slice(&((i * 7 % 1000) as u16).to_le_bytes());
        }
        let path = dir.join("ras.nrrd");
        std::fs::write(&path, bytes).unwrap();
        raycaster::import::open(&path)
            .unwrap()
            .to_volume_noting(
                raycaster::import::DEFAULT_IN_MEMORY_LIMIT,
                &raycaster::job::Job::silent(),
            )
            .unwrap()
            .0
    }

    /// A volume placed in RAS space shows each slice mirrored left to right
    /// against voxel order (the patient's right on the left; anterior on the
    /// left in sagittal slices), the crosshair's lines where its voxel lies in
    /// that picture, and a click on their crossing keeps the crosshair.
    #[test]
    fn oriented_slices_read_as_radiologists_and_clicks_land_where_lines_are() {
        let dir = tempfile::tempdir().unwrap();
        let dims = [20, 12, 9];
        let volume = ras_volume(dir.path(), dims);
        assert!(volume.orientation().is_some());
        assert_eq!(view_names(&volume)[2], "axial (z)");
        let c = Crosshair::at([3, 4, 5], dims);
        for axis in Axis::ALL {
            let layout = slice_layout(&volume, axis);
            assert_eq!([layout.columns, layout.rows], axis.in_plane(), "{axis}");
            assert!(!layout.grows_right && layout.grows_up, "{axis}");
            let (image, _) = slice_image(&volume, 0, axis, &c, [0.0, 1000.0], 1.0).unwrap();
            let (w, h) = (image.width(), image.height());
            let (u, v) = (layout.columns, layout.rows);
            // Mirrored columns: voxel coordinate c along u is column w − 1 − c.
            let (col, row) = (w - 1 - c.voxel[u], h - 1 - c.voxel[v]);
            let px = |x: u32, y: u32| {
                let i = ((y * w + x) * 3) as usize;
                [image.data()[i], image.data()[i + 1], image.data()[i + 2]]
            };
            let away = if row == 0 { h - 1 } else { 0 };
            assert_eq!(
                px(col, away),
                AXIS_COLOURS[u],
                "{axis}: the line along the columns"
            );
            assert_eq!(
                px(0, row),
                AXIS_COLOURS[v],
                "{axis}: the line along the rows"
            );
            let mut clicked = Crosshair::centre(dims);
            clicked.voxel[axis.index()] = c.voxel[axis.index()];
            clicked.click(&layout, [col as f32 + 0.5, row as f32 + 0.5], [w, h], 1);
            assert_eq!(clicked.voxel, c.voxel, "{axis}");
        }
        // The wheel's way into the screen (RAS): up z toward the head in the
        // axial view (seen from the feet), down y toward the back in the
        // coronal one, up x toward the right in the sagittal one.
        let toward = Axis::ALL.map(|axis| {
            slice_layout(&volume, axis).index_grows_toward_viewer(axis, volume.orientation())
        });
        assert_eq!(toward, [false, true, false]);
        // The axial slice as voxel order would show it, mirrored.
        let plain = Slice::extract(&volume, Axis::Z, 5).unwrap();
        let read =
            Slice::extract_laid_out(&volume, Axis::Z, 5, slice_layout(&volume, Axis::Z)).unwrap();
        for row in 0..12 {
            for col in 0..20 {
                assert_eq!(
                    read.values[(row * 20 + col) as usize],
                    plain.values[(row * 20 + 19 - col) as usize]
                );
            }
        }
        assert_ne!(read.values, plain.values);
    }

    #[test]
    fn crosshair_lines_thicken_on_large_slices() {
        let dir = tempfile::tempdir().unwrap();
        let volume = gradient_file(dir.path(), [600, 300, 4]);
        let c = Crosshair::centre(volume.dims());
        let (image, _) = slice_image(&volume, 0, Axis::Z, &c, [0.0, 255.0], 1.0).unwrap();
        let px = |x: u32, y: u32| {
            let i = ((y * 600 + x) * 3) as usize;
            [image.data()[i], image.data()[i + 1], image.data()[i + 2]]
        };
        // 600 columns: the x line (column 299) is 5 pixels wide; 300 rows: the
        // y line (row 299 − 149 = 150) is 3 pixels high.
        for x in 299..304 {
            assert_eq!(px(x, 10), AXIS_COLOURS[0], "column {x}");
        }
        assert_ne!(px(304, 10), AXIS_COLOURS[0]);
        for y in 150..153 {
            assert_eq!(px(10, y), AXIS_COLOURS[1], "row {y}");
        }
        assert_ne!(px(10, 153), AXIS_COLOURS[1]);
        // Zoomed 8×: 75 × 39 pixels shown, and lines one pixel thick (not the
        // whole slice's 5 and 3, which the view would blow up eightfold).
        let (zoomed, at) = slice_image(&volume, 0, Axis::Z, &c, [0.0, 255.0], 8.0).unwrap();
        let (zw, zh) = (zoomed.width(), zoomed.height());
        assert_eq!((zw, zh), (75, 39));
        let zpx = |x: u32, y: u32| {
            let i = ((y * zw + x) * 3) as usize;
            [zoomed.data()[i], zoomed.data()[i + 1], zoomed.data()[i + 2]]
        };
        let (col, row) = (299 - at[0], 150 - at[1]);
        let away = if row > 2 { 0 } else { zh - 1 };
        assert_eq!(zpx(col, away), AXIS_COLOURS[0]);
        assert_ne!(zpx(col + 1, away), AXIS_COLOURS[0]);
        assert_eq!(zpx(0, row), AXIS_COLOURS[1]);
        assert_ne!(zpx(0, row + 1), AXIS_COLOURS[1]);
    }

    #[test]
    fn zoom_spans_stay_inside() {
        assert_eq!(zoom_span(100, 50, 1.0), (0, 100));
        assert_eq!(zoom_span(100, 50, 4.0), (38, 25));
        assert_eq!(zoom_span(100, 2, 4.0), (0, 25));
        assert_eq!(zoom_span(100, 99, 4.0), (75, 25));
        assert_eq!(zoom_span(3, 1, 100.0), (1, 1));
        assert_eq!(zoom_span(10, 5, f32::NAN), (0, 10));
        // An even share grows to odd: the centre pixel in the middle.
        assert_eq!(zoom_span(48, 23, 2.0), (11, 25));
        let (start, count) = zoom_span(512, 300, 8.0);
        assert_eq!((start, count), (268, 65));
        assert_eq!(300 - start, count / 2);
    }
}
