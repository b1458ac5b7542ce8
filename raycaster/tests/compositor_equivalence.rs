//! One compositing interface: for every mode (Sabella too), a two-level scene of ONE object
//! covering every value (`layers = [[0.0, 1.0]]`) in that mode's local form renders
//! the plain mode's image — ≤ 1/255 with early ray termination off, ≤ 3/255 with
//! it on — on two generated scenes, both sample types, sequential and parallel.

mod render_support;

use raycaster::render::{
    Frame, GlobalMode, ImportanceSource, LocalMode, Membership, Mode, ModeParameters, ObjectStyle,
    ParallelOptions, RenderSettings, RenderVolume, RgbImage, SabellaDepth, SabellaMapping,
    SabellaOutput, SegmentScene, TransferFunction, render_parallel, render_sequential,
};
use raycaster::synth::SceneKind;
use raycaster::volume::{SampleType, Volume};
use render_support::*;

const N: u32 = 32;
const SIZE: u32 = 40;

/// Parameters away from the defaults, so that a mode ignoring them would show.
fn parameters() -> ModeParameters {
    ModeParameters {
        xray_gain: Some(2.5),
        context: [2.0, 0.5],
        importance: ImportanceSource::Gradient(2.0),
        sabella: SabellaOutput::Colours(SabellaMapping {
            depth: SabellaDepth::Centroid,
            hue: [200.0, 20.0],
            saturation: [0.9, 0.3],
        }),
    }
}

const ISO: f32 = 0.4;

/// Every plain mode with the local mode written out by hand.
fn modes() -> Vec<(Mode, LocalMode)> {
    let p = parameters();
    vec![
        (Mode::Dvr, LocalMode::Dvr),
        (Mode::Mip, LocalMode::Mip),
        (Mode::Average, LocalMode::Average),
        (Mode::XRay, LocalMode::XRay { gain: p.xray_gain }),
        (Mode::FirstHit, LocalMode::FirstHit { iso: ISO }),
        (
            Mode::Importance,
            LocalMode::Importance {
                source: p.importance,
            },
        ),
        (
            Mode::ContextPreserving,
            LocalMode::ContextPreserving {
                kt: p.context[0],
                ks: p.context[1],
            },
        ),
        (Mode::Silhouette, LocalMode::Silhouette),
        (Mode::Sabella, LocalMode::Sabella { output: p.sabella }),
    ]
}

fn volume(kind: SceneKind, sample_type: SampleType) -> Volume {
    let scene = kind.build([N; 3], 7);
    raycaster::synth::synthesize(scene.as_ref(), kind.name(), [N; 3], [1.0; 3], sample_type)
        .unwrap()
}

/// The scene's preset over the volume's data range (u16 volumes use a part of
/// their type's range); a grey ramp for noise, whose mean values `cloud` hides.
fn transfer(kind: SceneKind, volume: &Volume) -> TransferFunction {
    let mut tf = match kind {
        SceneKind::Noise => TransferFunction::preset("grayscale").unwrap(),
        _ => scene_preset(kind),
    };
    let ranges = volume.ranges().as_slice();
    let lo = ranges.iter().map(|r| r[0]).min().unwrap();
    let hi = ranges.iter().map(|r| r[1]).max().unwrap();
    tf.domain = Some([f32::from(lo), f32::from(hi)]);
    tf
}

fn one_object(tf: &TransferFunction, mode: LocalMode) -> SegmentScene {
    SegmentScene {
        membership: Membership::Layers(vec![[0.0, 1.0]]),
        objects: vec![ObjectStyle {
            name: "everything".into(),
            id: 1,
            visible: true,
            transfer: tf.clone(),
            mode,
            clip: Default::default(),
        }],
        global: GlobalMode::Dvr,
    }
}

fn draw(volume: &Volume, settings: &RenderSettings, parallel: bool) -> Frame {
    let prepared = RenderVolume::new(volume, Some(12)).unwrap();
    let camera = default_camera(volume, SIZE);
    if parallel {
        let options = ParallelOptions {
            render_threads: 3,
            compositing_threads: 2,
            tile_size: 8,
        };
        render_parallel(&prepared, &camera, settings, &options).unwrap()
    } else {
        render_sequential(&prepared, &camera, settings).unwrap()
    }
}

#[test]
fn one_object_covering_every_value_renders_the_plain_mode() {
    let mut checked = 0;
    for kind in [SceneKind::Shapes, SceneKind::Noise] {
        for sample_type in [SampleType::U8, SampleType::U16] {
            let volume = volume(kind, sample_type);
            let tf = transfer(kind, &volume);
            for (mode, local) in modes() {
                for ert in [None, Some(0.99)] {
                    let plain = RenderSettings {
                        mode,
                        mode_parameters: parameters(),
                        iso_value: ISO,
                        early_termination: ert,
                        transfer: tf.clone(),
                        ..RenderSettings::default()
                    };
                    let two_level = RenderSettings {
                        segments: Some(one_object(&tf, local)),
                        ..plain.clone()
                    };
                    let tolerance = if ert.is_some() { 3 } else { 1 };
                    for parallel in [false, true] {
                        let expected = draw(&volume, &plain, parallel).to_image();
                        let actual = draw(&volume, &two_level, parallel).to_image();
                        let name = format!(
                            "one-object-{}-{}-{sample_type:?}-ert{}-{}",
                            kind.name(),
                            mode.name(),
                            ert.is_some(),
                            if parallel { "parallel" } else { "sequential" }
                        );
                        // The picture is not empty: a mode that drew nothing in both
                        // renderings would pass trivially.
                        let black = RgbImage::new(SIZE, SIZE, vec![0; expected.data().len()]);
                        assert!(
                            expected.max_difference(&black).unwrap() > 8,
                            "{name}: the plain image is (nearly) empty: {:?}",
                            expected.max_difference(&black)
                        );
                        assert_images_match(&name, &actual, &expected, tolerance);
                        checked += 1;
                    }
                }
            }
        }
    }
    assert_eq!(checked, 2 * 2 * 9 * 2 * 2);
}

#[test]
fn preintegrated_two_level_dvr_segments_render_the_plain_preintegrated_mode() {
    for kind in [SceneKind::Shapes, SceneKind::Noise] {
        for sample_type in [SampleType::U8, SampleType::U16] {
            let volume = volume(kind, sample_type);
            let tf = transfer(kind, &volume);
            let plain = RenderSettings {
                transfer: tf.clone(),
                step: 1.0,
                preintegrated: true,
                ..RenderSettings::default()
            };
            let two_level = RenderSettings {
                segments: Some(one_object(&tf, LocalMode::Dvr)),
                ..plain.clone()
            };
            let without = RenderSettings {
                preintegrated: false,
                ..two_level.clone()
            };
            for parallel in [false, true] {
                let name = format!(
                    "pre-one-object-{}-{sample_type:?}-{}",
                    kind.name(),
                    if parallel { "parallel" } else { "sequential" }
                );
                let expected = draw(&volume, &plain, parallel).to_image();
                let actual = draw(&volume, &two_level, parallel).to_image();
                assert_images_match(&name, &actual, &expected, 3);
                // The segments do use the pre-integrated table.
                let ordinary = draw(&volume, &without, parallel).to_image();
                assert_ne!(ordinary, actual, "{name}");
            }
        }
    }
}

#[test]
fn every_mode_draws_its_own_picture() {
    // The modes are distinct compositors, not aliases of one another.
    let volume = volume(SceneKind::Shapes, SampleType::U8);
    let tf = transfer(SceneKind::Shapes, &volume);
    let images: Vec<_> = modes()
        .into_iter()
        .map(|(mode, _)| {
            let settings = RenderSettings {
                mode,
                mode_parameters: parameters(),
                iso_value: ISO,
                transfer: tf.clone(),
                ..RenderSettings::default()
            };
            (mode, draw(&volume, &settings, false).to_image())
        })
        .collect();
    for (i, (a, image_a)) in images.iter().enumerate() {
        for (b, image_b) in &images[i + 1..] {
            assert!(
                image_a.max_difference(image_b).unwrap() > 10,
                "{} and {} render alike",
                a.name(),
                b.name()
            );
        }
    }
}

#[test]
fn an_object_without_a_domain_spans_the_frames_domain_values_beyond_it_included() {
    // A scene's preset (no domain of its own) over a domain narrower than the
    // data (a CT window, `--domain`): the object's function spans that domain,
    // and the layer [0, 1] holds the values beyond it, which the function
    // classifies as its ends — the plain mode's picture. (The object's function
    // spanned the type's whole range once: CT rendered as an opaque box.)
    for sample_type in [SampleType::U8, SampleType::U16] {
        let volume = volume(SceneKind::Shapes, sample_type);
        let data = transfer(SceneKind::Shapes, &volume);
        let [lo, hi] = data.domain.unwrap();
        let mut narrow = data.clone();
        narrow.domain = Some([lo + 0.1 * (hi - lo), lo + 0.8 * (hi - lo)]);
        let mut preset = narrow.clone();
        preset.domain = None;
        for (mode, local) in modes()
            .into_iter()
            .filter(|(m, _)| matches!(m, Mode::Dvr | Mode::Mip | Mode::FirstHit))
        {
            let plain = RenderSettings {
                mode,
                iso_value: ISO,
                early_termination: None,
                transfer: narrow.clone(),
                ..RenderSettings::default()
            };
            let two_level = RenderSettings {
                segments: Some(one_object(&preset, local)),
                ..plain.clone()
            };
            for parallel in [false, true] {
                let name = format!("narrow-domain-{}-{sample_type:?}-{parallel}", mode.name());
                let expected = draw(&volume, &plain, parallel).to_image();
                let actual = draw(&volume, &two_level, parallel).to_image();
                assert_images_match(&name, &actual, &expected, 1);
            }
        }
    }
}

#[test]
fn an_object_whose_function_has_a_domain_of_its_own_renders_as_that_function_plain() {
    // The frame spans the data; the object's function a narrower domain of its
    // own, as `--tf FILE` of that function alone does. Gradients (shading, the
    // gradient modes, a 2D function's ramp) are read in the units of the
    // object's function, as the plain mode reads them (they were the frame's:
    // 26/255 apart in DVR on a CT scan).
    let mut checked = 0;
    for sample_type in [SampleType::U8, SampleType::U16] {
        let volume = volume(SceneKind::Shapes, sample_type);
        let data = transfer(SceneKind::Shapes, &volume);
        let [lo, hi] = data.domain.unwrap();
        let mut own = data.clone();
        own.domain = Some([lo + 0.05 * (hi - lo), lo + 0.6 * (hi - lo)]);
        let mut ramp = own.clone();
        ramp.gradient_ramp = Some([0.02, 0.3]);
        for (mode, local) in modes() {
            for tf in [&own, &ramp] {
                if tf.gradient_ramp.is_some() && mode != Mode::Dvr {
                    continue;
                }
                let plain = RenderSettings {
                    mode,
                    iso_value: ISO,
                    mode_parameters: parameters(),
                    early_termination: None,
                    transfer: tf.clone(),
                    ..RenderSettings::default()
                };
                let two_level = RenderSettings {
                    segments: Some(one_object(tf, local)),
                    transfer: data.clone(),
                    ..plain.clone()
                };
                for parallel in [false, true] {
                    let name = format!(
                        "own-domain-{}-{sample_type:?}-{}-{parallel}",
                        mode.name(),
                        tf.gradient_ramp.is_some()
                    );
                    let expected = draw(&volume, &plain, parallel).to_image();
                    let actual = draw(&volume, &two_level, parallel).to_image();
                    assert_images_match(&name, &actual, &expected, 1);
                    checked += 1;
                }
            }
        }
    }
    assert_eq!(checked, 2 * 2 * (modes().len() + 1));
}
