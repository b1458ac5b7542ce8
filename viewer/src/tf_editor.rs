//! The transfer-function editor: control points for colour and opacity drawn over
//! the volume's histogram, edited with the mouse.
//!
//! The horizontal axis is the normalised value (the transfer function's domain);
//! the vertical axis shows opacity on a square-root scale so the small
//! per-step opacities of translucent materials stay editable.

use raycaster::render::{ControlPoint, PRESETS, TransferFunction};

/// Pick radius around a control point, in pixels.
const PICK_RADIUS: f32 = 8.0;
/// Height of the colour bar under the curve, in pixels.
const COLOR_BAR: u32 = 10;

/// The preset (its index into [`PRESETS`]) whose control points `tf` has, as
/// the pickers name a curve; `None`: a curve of its own (`custom`).
pub fn preset_of(tf: &TransferFunction) -> Option<usize> {
    PRESETS.iter().position(|(name, _)| {
        TransferFunction::preset(name).is_ok_and(|p| p.points() == tf.points())
    })
}

/// Undo steps kept (older ones are forgotten).
const UNDO_STEPS: usize = 100;

/// Editable control points plus what is drawn behind them.
#[derive(Clone, Debug)]
pub struct TfEditor {
    points: Vec<ControlPoint>,
    domain: Option<[f32; 2]>,
    gradient_ramp: Option<[f32; 2]>,
    selected: Option<usize>,
    dragging: bool,
    /// Histogram bins over the normalised value, scaled to `[0, 1]`.
    histogram: Vec<f32>,
    /// The functions before each edit, oldest first ([`Self::undo`]).
    undone: Vec<TransferFunction>,
    /// The functions undone, most recently undone last ([`Self::redo`]).
    redone: Vec<TransferFunction>,
    /// The function when the button went down (one press, drag and release
    /// is one edit).
    before_gesture: Option<TransferFunction>,
    /// The point whose colour the last edit set: further colours of it join
    /// that edit (a colour picker sends one per step of its drag).
    colouring: Option<usize>,
}

impl TfEditor {
    /// Edits `tf`, drawn over `histogram` (counts per bin over the domain).
    pub fn new(tf: &TransferFunction, histogram: &[u64]) -> TfEditor {
        let mut editor = TfEditor {
            points: Vec::new(),
            domain: None,
            gradient_ramp: None,
            selected: None,
            dragging: false,
            histogram: scale_histogram(histogram),
            undone: Vec::new(),
            redone: Vec::new(),
            before_gesture: None,
            colouring: None,
        };
        editor.set_transfer(tf);
        editor
    }

    /// Replaces the edited function and forgets the edits before it (another
    /// volume or a session was opened).
    pub fn set_transfer(&mut self, tf: &TransferFunction) {
        self.show(tf);
        self.undone.clear();
        self.redone.clear();
    }

    /// Replaces the edited function as an edit that [`Self::undo`] takes back
    /// (a preset was picked); returns whether the function changed.
    pub fn pick_transfer(&mut self, tf: &TransferFunction) -> bool {
        let before = self.transfer();
        if before == *tf {
            return false;
        }
        self.show(tf);
        self.record(before);
        true
    }

    /// Takes back the last edit; returns whether there was one. Asked for
    /// while a point is held, it ends that drag as an edit of its own first
    /// (and takes it back).
    pub fn undo(&mut self) -> bool {
        self.release();
        let Some(previous) = self.undone.pop() else {
            return false;
        };
        self.redone.push(self.transfer());
        self.show(&previous);
        true
    }

    /// Makes the last edit undone again; returns whether there was one
    /// (none while a point is held: its drag ends as an edit first).
    pub fn redo(&mut self) -> bool {
        self.release();
        let Some(next) = self.redone.pop() else {
            return false;
        };
        self.undone.push(self.transfer());
        self.show(&next);
        true
    }

    /// Shows `tf`, nothing selected.
    fn show(&mut self, tf: &TransferFunction) {
        self.points = tf.points().to_vec();
        self.domain = tf.domain;
        self.gradient_ramp = tf.gradient_ramp;
        self.selected = None;
        self.dragging = false;
        self.before_gesture = None;
        self.colouring = None;
    }

    /// Keeps `before`, the function before an edit, as the step to undo; the
    /// edits undone before it can no longer be made again.
    fn record(&mut self, before: TransferFunction) {
        if self.undone.len() == UNDO_STEPS {
            self.undone.remove(0);
        }
        self.undone.push(before);
        self.redone.clear();
        self.colouring = None;
    }

    /// Replaces the histogram drawn behind the curve.
    pub fn set_histogram(&mut self, histogram: &[u64]) {
        self.histogram = scale_histogram(histogram);
    }

    /// The edited transfer function.
    pub fn transfer(&self) -> TransferFunction {
        let mut tf = TransferFunction::new(self.points.clone())
            .expect("the editor keeps at least two valid points");
        tf.domain = self.domain;
        tf.gradient_ramp = self.gradient_ramp;
        tf
    }

    /// The control points.
    pub fn points(&self) -> &[ControlPoint] {
        &self.points
    }

    /// The selected point, if any.
    pub fn selected(&self) -> Option<usize> {
        self.selected
    }

    /// A button went down at `(x, y)` in a `width × height` editor: picks a point
    /// (right button removes it), or adds one under the pointer. Returns whether
    /// the function changed.
    pub fn press(&mut self, x: f32, y: f32, width: f32, height: f32, remove: bool) -> bool {
        let before = self.transfer();
        let changed = self.press_points(x, y, width, height, remove);
        if remove {
            if changed {
                self.record(before);
            }
        } else if self.dragging {
            // (Recorded on release, if the press and drag changed it.)
            self.before_gesture = Some(before);
        }
        changed
    }

    /// [`Self::press`] on the points alone.
    fn press_points(&mut self, x: f32, y: f32, width: f32, height: f32, remove: bool) -> bool {
        let (width, height) = (width.max(1.0), curve_height(height));
        let hit = self
            .points
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let (px, py) = (p.value * width, alpha_to_y(p.alpha) * height);
                (i, (px - x).hypot(py - y))
            })
            .filter(|&(_, d)| d <= PICK_RADIUS)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i);
        match (hit, remove) {
            (Some(i), true) => {
                if self.points.len() <= 2 {
                    return false;
                }
                self.points.remove(i);
                self.selected = None;
                true
            }
            (None, true) => false,
            (Some(i), false) => {
                self.selected = Some(i);
                self.dragging = true;
                false
            }
            (None, false) => {
                let value = (x / width).clamp(0.0, 1.0);
                let [r, g, b, _] = self.transfer().evaluate(value);
                let point = ControlPoint {
                    value,
                    color: [r, g, b],
                    alpha: y_to_alpha(y / height),
                };
                let at = self.points.partition_point(|p| p.value <= value);
                self.points.insert(at, point);
                self.selected = Some(at);
                self.dragging = true;
                true
            }
        }
    }

    /// The pointer moved while a point is held: moves it (between its
    /// neighbours). Returns whether the function changed.
    pub fn drag_to(&mut self, x: f32, y: f32, width: f32, height: f32) -> bool {
        let (Some(i), true) = (self.selected, self.dragging) else {
            return false;
        };
        let lo = if i == 0 {
            0.0
        } else {
            self.points[i - 1].value
        };
        let hi = self.points.get(i + 1).map_or(1.0, |p| p.value);
        let point = &mut self.points[i];
        let value = (x / width.max(1.0)).clamp(lo, hi);
        let alpha = y_to_alpha(y / curve_height(height));
        let changed = point.value != value || point.alpha != alpha;
        point.value = value;
        point.alpha = alpha;
        changed
    }

    /// The button went up: the press and drag are one edit, if they changed
    /// the function.
    pub fn release(&mut self) {
        self.dragging = false;
        if let Some(before) = self.before_gesture.take()
            && before != self.transfer()
        {
            self.record(before);
        }
    }

    /// Colours the selected point; returns whether the function changed.
    /// Colours given one after another to the same point are one edit.
    pub fn set_color(&mut self, color: [f32; 3]) -> bool {
        match self.selected {
            Some(i) if self.points[i].color != color => {
                let before = self.transfer();
                self.points[i].color = color;
                if self.colouring != Some(i) {
                    self.record(before);
                    self.colouring = Some(i);
                }
                true
            }
            _ => false,
        }
    }

    /// Draws the editor into `width × height` RGBA8 pixels (rows from the top).
    pub fn draw(&self, width: u32, height: u32) -> Vec<[u8; 4]> {
        let (w, h) = (width.max(1), height.max(COLOR_BAR + 2));
        let curve_h = h - COLOR_BAR;
        let mut px = vec![[32, 33, 36, 255]; (w * h) as usize];
        let tf = self.transfer();
        let bins = self.histogram.len().max(1);
        for x in 0..w {
            let v = (x as f32 + 0.5) / w as f32;
            let bar = self
                .histogram
                .get(((v * bins as f32) as usize).min(bins - 1))
                .copied()
                .unwrap_or(0.0);
            let top = ((1.0 - bar) * curve_h as f32) as u32;
            for y in top..curve_h {
                px[(y * w + x) as usize] = [70, 72, 78, 255];
            }
            let [r, g, b, a] = tf.evaluate(v);
            let shade = |c: f32| (c * (0.35 + 0.65 * a.sqrt()) * 255.0) as u8;
            for y in curve_h..h {
                px[(y * w + x) as usize] = [shade(r), shade(g), shade(b), 255];
            }
        }
        // The opacity curve, one segment per pixel column.
        let y_of = |a: f32| alpha_to_y(a) * (curve_h - 1) as f32;
        let mut previous = y_of(tf.evaluate(0.0)[3]);
        for x in 0..w {
            let y = y_of(tf.evaluate((x as f32 + 0.5) / w as f32)[3]);
            let (a, b) = (previous.min(y) as u32, previous.max(y) as u32);
            for yy in a..=b.min(curve_h - 1) {
                px[(yy * w + x) as usize] = [232, 234, 237, 255];
            }
            previous = y;
        }
        for (i, p) in self.points.iter().enumerate() {
            let cx = p.value * (w - 1) as f32;
            let cy = y_of(p.alpha);
            let [r, g, b] = p.color.map(|c| (c * 255.0) as u8);
            let ring = if Some(i) == self.selected {
                [138, 180, 248, 255]
            } else {
                [20, 20, 20, 255]
            };
            for dy in -5i32..=5 {
                for dx in -5i32..=5 {
                    let d = ((dx * dx + dy * dy) as f32).sqrt();
                    let (x, y) = (cx as i32 + dx, cy as i32 + dy);
                    if d > 5.0 || x < 0 || y < 0 || x >= w as i32 || y >= curve_h as i32 {
                        continue;
                    }
                    px[(y as u32 * w + x as u32) as usize] =
                        if d > 3.5 { ring } else { [r, g, b, 255] };
                }
            }
        }
        px
    }
}

fn curve_height(height: f32) -> f32 {
    (height - COLOR_BAR as f32).max(1.0)
}

/// Opacity to the fraction of the curve's height from the top (square-root scale).
fn alpha_to_y(alpha: f32) -> f32 {
    1.0 - alpha.clamp(0.0, 1.0).sqrt()
}

fn y_to_alpha(y: f32) -> f32 {
    let s = (1.0 - y).clamp(0.0, 1.0);
    s * s
}

/// Log-scaled bins in `[0, 1]`.
fn scale_histogram(counts: &[u64]) -> Vec<f32> {
    let max = counts.iter().copied().max().unwrap_or(0);
    if max == 0 {
        return vec![0.0; counts.len()];
    }
    let top = (max as f32).ln_1p();
    counts.iter().map(|&c| (c as f32).ln_1p() / top).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn editor() -> TfEditor {
        TfEditor::new(
            &TransferFunction::preset("grayscale").unwrap(),
            &[1, 10, 100, 0],
        )
    }

    #[test]
    fn edits_are_undone_and_redone_one_gesture_at_a_time() {
        let mut e = editor();
        let (w, h) = (200.0, 110.0);
        let start = e.transfer();
        assert!(!e.undo(), "nothing to undo at first");
        // Add a point and drag it: one edit.
        assert!(e.press(100.0, 50.0, w, h, false));
        assert!(e.drag_to(120.0, 40.0, w, h));
        assert!(e.drag_to(130.0, 30.0, w, h));
        e.release();
        let added = e.transfer();
        assert_eq!(added.points().len(), 3);
        // Colour it in three steps (a picker's drag): one edit.
        for c in [0.2, 0.4, 0.6] {
            assert!(e.set_color([c, 0.1, 0.1]));
        }
        let coloured = e.transfer();
        // Pick it and let go without moving: no edit.
        let at = e.points()[1];
        let (px, py) = (at.value * w, alpha_to_y(at.alpha) * curve_height(h));
        assert!(!e.press(px, py, w, h, false));
        assert_eq!(e.selected(), Some(1));
        e.release();
        assert_eq!(e.transfer(), coloured);
        // Remove it: one edit.
        assert!(e.press(px, py, w, h, true));
        assert_eq!(e.points().len(), 2);
        let removed = e.transfer();
        // A preset picked: one edit.
        let preset = TransferFunction::preset("shapes").unwrap();
        assert!(e.pick_transfer(&preset));
        assert!(!e.pick_transfer(&preset), "the same curve again is no edit");
        for expected in [&removed, &coloured, &added, &start] {
            assert!(e.undo());
            assert_eq!(&e.transfer(), expected);
        }
        assert!(!e.undo());
        for expected in [&added, &coloured, &removed, &preset] {
            assert!(e.redo());
            assert_eq!(&e.transfer(), expected);
        }
        assert!(!e.redo());
        // An edit after an undo drops what was undone.
        assert!(e.undo());
        assert!(e.press(20.0, 90.0, w, h, false));
        e.release();
        assert!(!e.redo());
        // Another volume's function forgets the edits.
        e.set_transfer(&start);
        assert!(!e.undo());
        // Undo while a point is held ends its drag as an edit and takes back
        // that drag alone (it took back the edit before, and the drag came
        // back with it on redo); the point no longer follows the pointer.
        assert!(e.press(100.0, 50.0, w, h, false));
        e.release();
        let added = e.transfer();
        let at = e.points()[1];
        let (px, py) = (at.value * w, alpha_to_y(at.alpha) * curve_height(h));
        assert!(!e.press(px, py, w, h, false));
        assert!(e.drag_to(px + 20.0, py + 10.0, w, h));
        assert!(e.undo());
        assert_eq!(e.transfer(), added, "the drag alone is taken back");
        assert!(!e.drag_to(px + 30.0, py + 10.0, w, h));
        e.release();
        assert!(e.undo());
        assert_eq!(e.transfer(), start, "then the point added");
    }

    #[test]
    fn clicking_empty_space_adds_a_point_that_drags_between_its_neighbours() {
        let mut e = editor();
        let (w, h) = (200.0, 110.0);
        assert!(e.press(100.0, 50.0, w, h, false));
        assert_eq!(e.points().len(), 3);
        let i = e.selected().unwrap();
        assert!((e.points()[i].value - 0.5).abs() < 1e-6);
        assert!((e.points()[i].alpha - 0.25).abs() < 1e-6, "sqrt scale");
        // Dragging far right stops at the last point's value.
        assert!(e.drag_to(500.0, 0.0, w, h));
        assert_eq!(e.points()[i].value, 1.0);
        assert_eq!(e.points()[i].alpha, 1.0);
        e.release();
        assert!(!e.drag_to(10.0, 10.0, w, h));
        let tf = e.transfer();
        assert_eq!(tf.points().len(), 3);
    }

    #[test]
    fn right_click_removes_a_point_but_keeps_two() {
        let mut e = editor();
        let (w, h) = (200.0, 110.0);
        e.press(100.0, 50.0, w, h, false);
        e.release();
        assert!(e.press(100.0, 50.0, w, h, true));
        assert_eq!(e.points().len(), 2);
        // The first point sits at (0, alpha 0 → bottom of the curve).
        assert!(!e.press(0.0, 100.0, w, h, true));
        assert_eq!(e.points().len(), 2);
    }

    #[test]
    fn the_selected_point_takes_a_colour_and_the_drawing_shows_it() {
        let mut e = editor();
        assert!(!e.set_color([1.0, 0.0, 0.0]), "nothing selected");
        e.press(0.0, 100.0, 200.0, 110.0, false);
        assert_eq!(e.selected(), Some(0));
        assert!(e.set_color([1.0, 0.0, 0.0]));
        let px = e.draw(200, 110);
        assert_eq!(px.len(), 200 * 110);
        assert!(px.contains(&[255, 0, 0, 255]), "the red point is drawn");
        assert!(px.contains(&[70, 72, 78, 255]), "the histogram is drawn");
    }
}
