//! The segments panel: one row per object of a two-level scene (visible, local
//! mode, transfer-function preset, the mode's main parameter).

use raycaster::render::{ImportanceSource, LocalMode, ObjectStyle, PRESETS, TransferFunction};

/// Local modes in the order the panel lists them: the Rendering panel's
/// order (`Mode::ALL`), without Sabella's, which has no local mode.
pub const LOCAL_MODES: [&str; 8] = [
    "dvr",
    "mip",
    "average",
    "first-hit",
    "xray",
    "importance",
    "context",
    "silhouette",
];

/// What the panel shows of one object.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectRowData {
    /// Object id.
    pub id: u8,
    /// Name.
    pub name: String,
    /// Shown or clipped.
    pub visible: bool,
    /// Index into [`LOCAL_MODES`].
    pub mode_index: usize,
    /// Index into [`PRESETS`], or `None` for an edited/loaded function.
    pub preset_index: Option<usize>,
    /// The mode's main parameter.
    pub param: f32,
    /// Its label (empty: the mode has none).
    pub param_label: String,
    /// The slider's lower end.
    pub param_min: f32,
    /// The slider's upper end.
    pub param_max: f32,
    /// The slider moves on a log scale of the parameter.
    pub param_log: bool,
}

/// The row of `object`; an X-ray object without a gain of its own shows
/// `auto_gain`, the volume's automatic one it renders with.
pub fn row_of(object: &ObjectStyle, auto_gain: f32) -> ObjectRowData {
    let mode_index = LOCAL_MODES
        .iter()
        .position(|&m| m == object.mode.name())
        .unwrap_or(0);
    let Parameter {
        value: param,
        label: param_label,
        min: param_min,
        max: param_max,
        log: param_log,
    } = parameter(object.mode, auto_gain);
    let preset_index = crate::tf_editor::preset_of(&object.transfer);
    ObjectRowData {
        id: object.id,
        name: object.name.clone(),
        visible: object.visible,
        mode_index,
        preset_index,
        param,
        param_label: param_label.to_owned(),
        param_min,
        param_max,
        param_log,
    }
}

/// The main parameter of a mode and its slider.
struct Parameter {
    value: f32,
    /// Empty: the mode has none.
    label: &'static str,
    min: f32,
    max: f32,
    /// The slider moves on a log scale (a gain whose useful values span
    /// orders of magnitude: 0.06 by default, up to a few).
    log: bool,
}

/// The main parameter of `mode` (`auto_gain`: an X-ray gain not given).
fn parameter(mode: LocalMode, auto_gain: f32) -> Parameter {
    let linear = |value, label, max| Parameter {
        value,
        label,
        min: 0.0,
        max,
        log: false,
    };
    match mode {
        LocalMode::XRay { gain } => Parameter {
            value: gain.unwrap_or(auto_gain),
            // (An automatic gain reads as one: said, as it follows the volume.)
            label: if gain.is_some() {
                "gain"
            } else {
                "gain (auto)"
            },
            min: 0.002,
            max: 5.0,
            log: true,
        },
        LocalMode::FirstHit { iso } => linear(iso, "iso", 1.0),
        LocalMode::ContextPreserving { kt, .. } => linear(kt, "κt", 6.0),
        LocalMode::Importance {
            source:
                ImportanceSource::Constant(w)
                | ImportanceSource::Intensity(w)
                | ImportanceSource::Gradient(w),
        } => linear(w, "weight", 5.0),
        _ => linear(0.0, "", 1.0),
    }
}

/// Applies an edited row to `object`: a new mode starts from its defaults, the
/// same mode takes the row's parameter (an X-ray gain left at `auto_gain`, the
/// automatic one shown, stays automatic); a picked preset keeps the value
/// domain.
pub fn apply(object: &mut ObjectStyle, row: &ObjectRowData, auto_gain: f32) {
    object.visible = row.visible;
    let name = LOCAL_MODES.get(row.mode_index).copied().unwrap_or("dvr");
    if name != object.mode.name() {
        object.mode = default_mode(name);
    } else {
        let p = row.param.max(0.0);
        object.mode = match object.mode {
            LocalMode::XRay { gain } => LocalMode::XRay {
                gain: (gain.is_some() || p != auto_gain).then_some(p),
            },
            LocalMode::FirstHit { .. } => LocalMode::FirstHit { iso: p.min(1.0) },
            LocalMode::ContextPreserving { ks, .. } => LocalMode::ContextPreserving { kt: p, ks },
            LocalMode::Importance { source } => LocalMode::Importance {
                source: match source {
                    ImportanceSource::Constant(_) => ImportanceSource::Constant(p),
                    ImportanceSource::Intensity(_) => ImportanceSource::Intensity(p),
                    ImportanceSource::Gradient(_) => ImportanceSource::Gradient(p),
                    other => other,
                },
            },
            other => other,
        };
    }
    if let Some(i) = row.preset_index
        && Some(i) != row_of(object, auto_gain).preset_index
        && let Some(Ok(mut tf)) = PRESETS.get(i).map(|(n, _)| TransferFunction::preset(n))
    {
        tf.domain = object.transfer.domain;
        object.transfer = tf;
    }
}

/// An X-ray object's gain back to the automatic one (other modes unchanged).
pub fn automatic_gain(object: &mut ObjectStyle) {
    if let LocalMode::XRay { gain } = &mut object.mode {
        *gain = None;
    }
}

/// A mode with the scene format's default parameters.
fn default_mode(name: &str) -> LocalMode {
    match name {
        "mip" => LocalMode::Mip,
        "average" => LocalMode::Average,
        "xray" => LocalMode::XRay { gain: None },
        "first-hit" => LocalMode::FirstHit { iso: 0.5 },
        "importance" => LocalMode::Importance {
            source: ImportanceSource::Intensity(1.0),
        },
        "context" => LocalMode::ContextPreserving { kt: 1.5, ks: 0.4 },
        "silhouette" => LocalMode::Silhouette,
        _ => LocalMode::Dvr,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn object() -> ObjectStyle {
        let mut transfer = TransferFunction::preset("cloud").unwrap();
        transfer.domain = Some([10.0, 900.0]);
        ObjectStyle {
            name: "haze".into(),
            id: 3,
            visible: true,
            transfer,
            mode: LocalMode::ContextPreserving { kt: 2.0, ks: 0.3 },
            clip: Default::default(),
        }
    }

    #[test]
    fn the_local_modes_are_listed_as_the_rendering_panel_lists_the_modes() {
        let plain: Vec<&str> = raycaster::render::Mode::ALL
            .iter()
            .map(|m| m.name())
            .filter(|&m| m != "sabella")
            .collect();
        assert_eq!(LOCAL_MODES.to_vec(), plain);
    }

    #[test]
    fn a_row_shows_the_object_and_edits_come_back() {
        let mut o = object();
        let row = row_of(&o, 0.05);
        assert_eq!(LOCAL_MODES[row.mode_index], "context");
        assert_eq!((row.param, row.param_label.as_str()), (2.0, "κt"));
        assert_eq!(PRESETS[row.preset_index.unwrap()].0, "cloud");
        let edited = ObjectRowData {
            param: 0.0,
            visible: false,
            ..row.clone()
        };
        apply(&mut o, &edited, 0.05);
        assert_eq!(o.mode, LocalMode::ContextPreserving { kt: 0.0, ks: 0.3 });
        assert!(!o.visible);
    }

    #[test]
    fn a_new_mode_or_preset_replaces_the_old_keeping_the_domain() {
        let mut o = object();
        let xray = LOCAL_MODES.iter().position(|&m| m == "xray").unwrap();
        let shells = PRESETS.iter().position(|(n, _)| *n == "shells").unwrap();
        let row = ObjectRowData {
            mode_index: xray,
            preset_index: Some(shells),
            ..row_of(&o, 0.05)
        };
        apply(&mut o, &row, 0.05);
        // The automatic gain, as the plain X-ray mode's, shown on the slider;
        // another edit of the row keeps it automatic, a moved slider sets it.
        assert_eq!(o.mode, LocalMode::XRay { gain: None });
        let row = row_of(&o, 0.05);
        assert_eq!((row.param, row.param_label.as_str()), (0.05, "gain (auto)"));
        apply(
            &mut o,
            &ObjectRowData {
                visible: false,
                ..row.clone()
            },
            0.05,
        );
        assert_eq!(o.mode, LocalMode::XRay { gain: None });
        apply(
            &mut o,
            &ObjectRowData {
                param: 0.2,
                ..row.clone()
            },
            0.05,
        );
        assert_eq!(o.mode, LocalMode::XRay { gain: Some(0.2) });
        assert_eq!(row_of(&o, 0.05).param_label, "gain");
        // The row's *auto* button: the automatic gain again.
        automatic_gain(&mut o);
        assert_eq!(o.mode, LocalMode::XRay { gain: None });
        assert_eq!(row_of(&o, 0.05).param_label, "gain (auto)");
        apply(&mut o, &ObjectRowData { param: 0.2, ..row }, 0.05);
        assert_eq!(
            o.transfer.points(),
            TransferFunction::preset("shells").unwrap().points()
        );
        assert_eq!(o.transfer.domain, Some([10.0, 900.0]));
        // The gain's slider is logarithmic over the gains scenes use (0.06 to
        // a few); the other parameters' sliders are linear from 0.
        let gain = row_of(&o, 0.05);
        assert!(gain.param_log && gain.param_min <= 0.06 && gain.param_max >= 2.0);
        let context = row_of(&object(), 0.05);
        assert!(!context.param_log && context.param_min == 0.0);
    }
}
