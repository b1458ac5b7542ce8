//! The check of a frame's settings before it renders: every field a program can
//! set in code (they are public), by the rules the session and scene files are
//! read with, so that a value no file could give is an error naming it rather
//! than a blank, white or NaN picture.

use glam::Vec3;

use super::error::RenderError;
use super::sabella::SabellaOutput;
use super::segments::{ImportanceSource, LocalMode, Membership, SegmentScene};
use super::settings::{ModeParameters, RenderSettings};
use super::shading::{Light, Shading};
use super::transfer::{TransferFunction, check_domain, check_gradient_ramp};

/// The largest ambient, diffuse or specular factor: the sample's colour is
/// multiplied by their sum, so beyond it every colour channel above 1/100 is
/// white wherever light falls.
pub const MAX_LIGHT_FACTOR: f32 = 100.0;

/// A setting that is out of its range: the field (as the library names it)
/// and what is wrong.
fn setting(field: impl Into<String>, what: impl Into<String>) -> RenderError {
    RenderError::Setting {
        field: field.into(),
        what: what.into(),
    }
}

/// `v` is a finite number of at least 0.
fn non_negative(field: &str, v: f32) -> Result<(), RenderError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(setting(field, format!("{v} must be a finite number ≥ 0")))
    }
}

/// `v` lies in `[0, 1]`.
fn unit(field: &str, v: f32) -> Result<(), RenderError> {
    if (0.0..=1.0).contains(&v) {
        Ok(())
    } else {
        Err(setting(field, format!("{v} must lie in [0, 1]")))
    }
}

impl RenderSettings {
    /// Checks every setting before a frame (both renderers call it; a program
    /// may call it after editing fields): the step, early termination and
    /// iso-value, the transfer function's domain and gradient ramp, the mode's
    /// parameters, shading, the background, the cut and a two-level scene.
    /// Each rule is the one the session and scene files are read with (a file
    /// that reads renders).
    pub fn check(&self) -> Result<(), RenderError> {
        if !(self.step.is_finite() && self.step > 0.0) {
            return Err(RenderError::Step(self.step));
        }
        if let Some(t) = self.early_termination
            && !(t > 0.0 && t <= 1.0)
        {
            return Err(RenderError::ErtThreshold(t));
        }
        if !(0.0..=1.0).contains(&self.iso_value) {
            return Err(RenderError::IsoValue(self.iso_value));
        }
        check_transfer("transfer", &self.transfer)?;
        check_mode_parameters(&self.mode_parameters)?;
        if let Some(shading) = &self.shading {
            check_shading(shading)?;
        }
        for v in self.background {
            unit("background", v)?;
        }
        self.clip.validate()?;
        if let Some(scene) = &self.segments {
            scene.check()?;
        }
        Ok(())
    }
}

/// A transfer function's domain and gradient ramp (its points are checked
/// when it is made).
fn check_transfer(field: &str, tf: &TransferFunction) -> Result<(), RenderError> {
    if let Some(domain) = tf.domain {
        check_domain(domain).map_err(|e| setting(format!("{field}.domain"), e))?;
    }
    if let Some(ramp) = tf.gradient_ramp {
        check_gradient_ramp(ramp).map_err(|e| setting(format!("{field}.gradient_ramp"), e))?;
    }
    Ok(())
}

/// The plain modes' parameters.
fn check_mode_parameters(p: &ModeParameters) -> Result<(), RenderError> {
    if let Some(gain) = p.xray_gain {
        non_negative("mode_parameters.xray_gain", gain)?;
    }
    for v in p.context {
        non_negative("mode_parameters.context", v)?;
    }
    check_importance("mode_parameters.importance", p.importance)?;
    if let SabellaOutput::Colours(mapping) = p.sabella {
        if let Some(h) = mapping.hue.into_iter().find(|h| !h.is_finite()) {
            return Err(setting(
                "mode_parameters.sabella.hue",
                format!("{h} must be a finite number of degrees"),
            ));
        }
        for s in mapping.saturation {
            unit("mode_parameters.sabella.saturation", s)?;
        }
    }
    Ok(())
}

/// An importance source's weight or exponents: finite, at least 0.
fn check_importance(field: &str, source: ImportanceSource) -> Result<(), RenderError> {
    match source {
        ImportanceSource::Constant(w)
        | ImportanceSource::Intensity(w)
        | ImportanceSource::Gradient(w) => non_negative(field, w),
        ImportanceSource::Silhouette(p) | ImportanceSource::Lighting(p) => {
            p.into_iter().try_for_each(|v| non_negative(field, v))
        }
    }
}

/// Blinn-Phong's factors, exponent, threshold and light.
fn check_shading(s: &Shading) -> Result<(), RenderError> {
    for (field, v) in [
        ("shading.ambient", s.ambient),
        ("shading.diffuse", s.diffuse),
        ("shading.specular", s.specular),
    ] {
        check_light_factor(v).map_err(|what| setting(field, what))?;
    }
    non_negative("shading.shininess", s.shininess)?;
    non_negative("shading.gradient_threshold", s.gradient_threshold)?;
    non_negative("shading.fade_width", s.fade_width)?;
    if let Light::Fixed(d) = s.light
        && let Some(problem) = light_direction_problem(d)
    {
        return Err(setting("shading.light", problem));
    }
    Ok(())
}

/// Why `d` is no light direction, if it is none: not finite, zero, or of a
/// length whose square 32-bit floats do not hold (the renderers normalise
/// it so).
pub fn light_direction_problem(d: Vec3) -> Option<String> {
    if !d.is_finite() {
        return Some(format!("the direction {d} is not finite"));
    }
    if d == Vec3::ZERO {
        return Some("the direction is zero".into());
    }
    if d.try_normalize().is_none() {
        let scale = if d.abs().max_element() < 1.0 {
            "up"
        } else {
            "down"
        };
        return Some(format!(
            "the direction {d} cannot be normalised in 32-bit floats (its squared length over- or underflows); scale it {scale} (only its direction counts)"
        ));
    }
    None
}

/// An ambient, diffuse or specular factor: finite, 0 to [`MAX_LIGHT_FACTOR`];
/// what is wrong otherwise.
pub fn check_light_factor(v: f32) -> Result<(), String> {
    if !(v.is_finite() && v >= 0.0) {
        return Err(format!("{v} must be a finite number ≥ 0"));
    }
    if v > MAX_LIGHT_FACTOR {
        let d = Shading::default();
        return Err(format!(
            "{v} is beyond {MAX_LIGHT_FACTOR}: the factor multiplies the sample's colour, and above it every lit colour is white (the default light is ambient {}, diffuse {}, specular {})",
            d.ambient, d.diffuse, d.specular
        ));
    }
    Ok(())
}

impl LocalMode {
    /// Checks the mode's parameters as a scene file's are checked: gains,
    /// weights and κ finite and at least 0, an iso-value in `[0, 1]`.
    pub fn check(&self) -> Result<(), String> {
        let non_negative = |name: &str, v: f32| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(format!("{name} = {v} must be a non-negative finite number"))
            }
        };
        match *self {
            LocalMode::XRay { gain: Some(g) } => non_negative("gain", g),
            LocalMode::FirstHit { iso } if !(0.0..=1.0).contains(&iso) => {
                Err(format!("iso = {iso} must lie in [0, 1]"))
            }
            LocalMode::ContextPreserving { kt, ks } => {
                non_negative("kt", kt).and_then(|()| non_negative("ks", ks))
            }
            LocalMode::Importance { source } => {
                check_importance("importance", source).map_err(|e| e.to_string())
            }
            _ => Ok(()),
        }
    }
}

impl SegmentScene {
    /// Checks a scene made or edited in code as [`SegmentScene::parse`] checks
    /// a file: its layers, its objects' ids (each once; a layer object's in
    /// `1..=layers`), transfer functions, modes and cuts.
    pub fn check(&self) -> Result<(), RenderError> {
        let scene = |what: String| setting("segments", what);
        if let Membership::Layers(layers) = &self.membership {
            super::segments::check_layers(layers).map_err(scene)?;
        }
        for (i, o) in self.objects.iter().enumerate() {
            let object = |what: String| scene(format!("object {:?}: {what}", o.name));
            if self.objects[..i].iter().any(|p| p.id == o.id) {
                return Err(scene(format!("object id {} is defined twice", o.id)));
            }
            if let Membership::Layers(layers) = &self.membership {
                super::segments::check_layer_id(o.id, layers.len()).map_err(object)?;
            }
            check_transfer("transfer", &o.transfer).map_err(|e| object(e.to_string()))?;
            o.mode.check().map_err(object)?;
            o.clip.validate().map_err(|e| object(e.to_string()))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::segments::{GlobalMode, ObjectStyle};

    /// `change` made to default settings is refused, naming `field`.
    fn refused(change: impl FnOnce(&mut RenderSettings), field: &str) {
        let mut s = RenderSettings::default();
        change(&mut s);
        let e = s.check().expect_err(field).to_string();
        assert!(e.starts_with(field), "{field}: {e}");
    }

    #[test]
    fn every_field_set_out_of_range_in_code_is_refused_by_name() {
        RenderSettings::default().check().unwrap();
        refused(|s| s.transfer.domain = Some([5.0, 5.0]), "transfer.domain");
        refused(
            |s| s.transfer.domain = Some([f32::NAN, 1.0]),
            "transfer.domain",
        );
        refused(
            |s| s.transfer.gradient_ramp = Some([1.0, 0.0]),
            "transfer.gradient_ramp",
        );
        refused(
            |s| s.mode_parameters.xray_gain = Some(f32::NAN),
            "mode_parameters.xray_gain",
        );
        refused(
            |s| s.mode_parameters.context = [-1.0, 0.4],
            "mode_parameters.context",
        );
        refused(
            |s| s.mode_parameters.importance = ImportanceSource::Constant(f32::NAN),
            "mode_parameters.importance",
        );
        refused(
            |s| {
                s.mode_parameters.importance = ImportanceSource::Lighting([1.0, f32::INFINITY, 0.0])
            },
            "mode_parameters.importance",
        );
        let shading = |f: fn(&mut Shading)| {
            move |s: &mut RenderSettings| {
                let mut sh = Shading::default();
                f(&mut sh);
                s.shading = Some(sh);
            }
        };
        refused(shading(|s| s.ambient = f32::NAN), "shading.ambient");
        refused(shading(|s| s.diffuse = -5.0), "shading.diffuse");
        refused(shading(|s| s.specular = 1e30), "shading.specular");
        refused(shading(|s| s.shininess = f32::NAN), "shading.shininess");
        refused(
            shading(|s| s.light = Light::Fixed(Vec3::ZERO)),
            "shading.light",
        );
        refused(
            shading(|s| s.light = Light::Fixed(Vec3::NAN)),
            "shading.light",
        );
        let long = light_direction_problem(Vec3::new(0.0, 1e20, 0.0)).unwrap();
        assert!(long.contains("scale it down"), "{long}");
        let short = light_direction_problem(Vec3::new(0.0, 1e-30, 0.0)).unwrap();
        assert!(short.contains("scale it up"), "{short}");
        refused(|s| s.background = [f32::NAN; 3], "background");
        refused(|s| s.background = [-5.0, 0.0, 0.0], "background");
        // What files accept passes.
        let mut s = RenderSettings::default();
        s.mode_parameters.xray_gain = Some(0.0);
        s.shading = Some(Shading {
            ambient: MAX_LIGHT_FACTOR,
            light: Light::Fixed(Vec3::new(0.0, 1e-3, 0.0)),
            ..Shading::default()
        });
        s.background = [1.0, 0.0, 0.5];
        s.check().unwrap();
    }

    #[test]
    fn a_scene_made_in_code_is_checked_as_a_file_is() {
        let object = |id, mode| ObjectStyle {
            name: format!("o{id}"),
            id,
            visible: true,
            transfer: TransferFunction::preset("shapes").unwrap(),
            mode,
            clip: Default::default(),
        };
        let scene = |layers: Vec<[f32; 2]>, objects| RenderSettings {
            segments: Some(SegmentScene {
                membership: Membership::Layers(layers),
                objects,
                global: GlobalMode::Dvr,
            }),
            ..RenderSettings::default()
        };
        let two = vec![[0.1, 0.4], [0.4, 1.0]];
        let fine = scene(
            two.clone(),
            vec![object(1, LocalMode::Dvr), object(2, LocalMode::Mip)],
        );
        fine.check().unwrap();
        for (settings, said) in [
            (scene(vec![[f32::NAN, 0.5]], vec![]), "layer 0"),
            (scene(vec![[0.8, 0.2]], vec![]), "layer 0"),
            (scene(vec![], vec![]), "`layers` is empty"),
            (
                scene(
                    two.clone(),
                    vec![object(1, LocalMode::Dvr), object(1, LocalMode::Mip)],
                ),
                "object id 1 is defined twice",
            ),
            (
                scene(two.clone(), vec![object(0, LocalMode::Dvr)]),
                "id 0 names no layer",
            ),
            (
                scene(
                    two.clone(),
                    vec![object(
                        1,
                        LocalMode::XRay {
                            gain: Some(f32::NAN),
                        },
                    )],
                ),
                "object \"o1\": gain = NaN",
            ),
            (
                scene(
                    two.clone(),
                    vec![object(1, LocalMode::FirstHit { iso: 5.0 })],
                ),
                "iso = 5 must lie in [0, 1]",
            ),
        ] {
            let e = settings.check().expect_err(said).to_string();
            assert!(
                e.starts_with("segments: ") && e.contains(said),
                "{said}: {e}"
            );
        }
        let mut domain = fine.clone();
        domain.segments.as_mut().unwrap().objects[0].transfer.domain = Some([3.0, 3.0]);
        let e = domain.check().unwrap_err().to_string();
        assert!(e.contains("object \"o1\": transfer.domain"), "{e}");
    }
}
