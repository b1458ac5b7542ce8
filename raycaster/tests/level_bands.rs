//! Frames of several pyramid levels: a deep perspective view samples each band
//! of depths at its own level. The sequential and parallel renderers agree on
//! them, levels meet without cracks, and far levels spare the full-resolution
//! bricks.

mod render_support;

use raycaster::render::{
    Camera, LevelBand, LevelChoice, Mode, ParallelOptions, PixelProgress, PixelRect,
    RenderSettings, RenderVolume, Renderer, SimdLevel, TileSink, render_sequential_levels,
    render_sequential_noting,
};
use raycaster::synth::SceneKind;
use raycaster::volume::{Access, Layout, SampleType, Volume};
use render_support::{
    assert_images_match, level_passes, prepare_levels, pyramid_shapes, scene_file, scene_preset,
    white_tf, wide_view,
};
use tempfile::TempDir;

/// A close perspective view of `volume` (256³ with levels 0–2), 64 pixels wide
/// with a 90° field: level 1 begins 64 voxels deep, level 2 at 128.
fn close_view(volume: &Volume, orthographic: bool) -> Camera {
    wide_view(volume, 150.0, 0.7, orthographic, 64, 64)
}

fn level_numbers(bands: &[LevelBand]) -> Vec<usize> {
    bands.iter().map(|b| b.level).collect()
}

#[test]
fn a_deep_perspective_view_gets_a_band_per_level_and_other_views_one() {
    let dir = TempDir::new().unwrap();
    let volume = pyramid_shapes(dir.path());
    assert_eq!(volume.level_count(), 3);
    let camera = close_view(&volume, false);
    let auto = LevelChoice::default();
    let bands = auto.bands(&volume, &camera);
    assert_eq!(level_numbers(&bands), [0, 1, 2]);
    assert!(bands.iter().all(|b| b.depth.is_some()));
    // The nearest band is the level a frame of one level would take.
    assert_eq!(bands[0].level, auto.resolve(&volume, &camera));
    // One level coarser everywhere; the coarsest cannot split further.
    let coarser = LevelChoice::Auto { bias: 1.0 }.bands(&volume, &camera);
    assert_eq!(level_numbers(&coarser), [1, 2]);
    let coarsest = LevelChoice::Auto { bias: 2.0 }.bands(&volume, &camera);
    assert_eq!(
        coarsest,
        [LevelBand {
            level: 2,
            depth: None
        }]
    );
    // A fixed level and an orthographic view sample one level everywhere.
    assert_eq!(
        LevelChoice::Fixed(1).bands(&volume, &camera),
        [LevelBand {
            level: 1,
            depth: None
        }]
    );
    let flat = close_view(&volume, true);
    assert_eq!(
        auto.bands(&volume, &flat),
        [LevelBand {
            level: auto.resolve(&volume, &flat),
            depth: None
        }]
    );
    // A volume without a pyramid has one level.
    let linear = render_support::scene_volume(SceneKind::Shapes, 64);
    assert_eq!(
        auto.bands(&linear, &close_view(&linear, false)),
        [LevelBand {
            level: 0,
            depth: None
        }]
    );
}

#[test]
fn frames_of_several_levels_are_the_same_in_parallel_and_sequentially() {
    let dir = TempDir::new().unwrap();
    for (layout, sample_type) in [
        (Layout::Bricked { side: 16 }, SampleType::U8),
        (Layout::Linear, SampleType::U16),
    ] {
        let volume = scene_file(
            dir.path(),
            SceneKind::Shapes,
            256,
            layout,
            sample_type,
            Access::Mapped,
        );
        let camera = close_view(&volume, false);
        let bands = LevelChoice::default().bands(&volume, &camera);
        assert_eq!(bands.len(), 3, "{layout:?}");
        let levels = prepare_levels(&volume, &bands);
        let passes = level_passes(&levels, &bands);
        let mut renderer = Renderer::new();
        let modes = [Mode::Dvr, Mode::Mip, Mode::FirstHit, Mode::Average];
        for (i, mode) in modes.into_iter().enumerate() {
            for variant in 0..4 {
                let mut transfer = scene_preset(SceneKind::Shapes);
                transfer.domain = (sample_type == SampleType::U16).then_some([0.0, 255.0 * 257.0]);
                let settings = RenderSettings {
                    mode,
                    transfer,
                    jitter: variant & 1 == 1,
                    early_termination: (variant & 2 == 0).then_some(0.95),
                    empty_space_skipping: variant != 3,
                    simd: Some(if variant == 1 && mode == Mode::Dvr {
                        SimdLevel::widest()
                    } else {
                        SimdLevel::Scalar
                    }),
                    ..RenderSettings::default()
                };
                let options = ParallelOptions {
                    render_threads: 1 + (i + variant) % 2,
                    compositing_threads: 1,
                    tile_size: [8, 16][variant % 2],
                };
                let sequential = render_sequential_levels(&passes, &camera, &settings).unwrap();
                let parallel = renderer
                    .render_levels(&passes, &camera, &settings, &options)
                    .unwrap();
                let name = format!("levels-{layout:?}-{mode:?}-{variant}");
                assert_images_match(&name, &parallel.to_image(), &sequential.to_image(), 1);
                let (s, p) = (&sequential.stats, &parallel.stats);
                assert_eq!(s.counters.samples, p.counters.samples, "{name}");
                assert_eq!(
                    (s.level, s.coarsest_level, p.level, p.coarsest_level),
                    (0, 2, 0, 2),
                    "{name}"
                );
            }
        }
    }
}

#[test]
fn levels_meet_without_cracks_and_far_levels_spare_full_resolution() {
    let dir = TempDir::new().unwrap();
    let volume = pyramid_shapes(dir.path());
    let camera = close_view(&volume, false);
    let bands = LevelChoice::default().bands(&volume, &camera);
    let levels = prepare_levels(&volume, &bands);
    let banded = level_passes(&levels, &bands);
    // Every value equally translucent: a uniform medium whatever the data, so
    // every level shows the same haze, each level's opacity corrected for its
    // step. (That levels meet exactly, sample for sample, is
    // `render::level::tests::levels_meet_without_a_gap_or_an_overlap`.)
    let settings = RenderSettings {
        transfer: white_tf(&[(0.0, 0.02), (1.0, 0.02)]),
        shading: None,
        early_termination: None,
        ..RenderSettings::default()
    };
    // The progress a command shows: every pixel of every level's pass (a frame
    // of several levels carries every pixel on), all done at the end.
    let progress = PixelProgress::new();
    let mixed = render_sequential_noting(&banded, &camera, &settings, &progress).unwrap();
    let pixels = u64::from(camera.width()) * u64::from(camera.height());
    assert_eq!(progress.total(), 3 * pixels);
    assert_eq!((progress.done(), progress.fraction()), (3 * pixels, 1.0));
    let full = RenderVolume::new(volume.level(0), None).unwrap();
    let progress = PixelProgress::new();
    let fine = render_sequential_noting(&[(&full, None)], &camera, &settings, &progress).unwrap();
    // One level: the pixels its box projects onto, each ray's pixel among them.
    let (lo, hi) = full.geometry().world_bounds();
    let projected = camera.project_box(lo, hi).unwrap().area();
    assert_eq!((progress.total(), progress.done()), (projected, projected));
    assert!(fine.stats.counters.rays <= projected && fine.stats.counters.rays > projected / 4);
    // The parallel renderer's progress: level by level (each a third of the
    // frame), reaching the whole frame at the end.
    struct Shares(std::sync::Mutex<Vec<f64>>);
    impl TileSink for Shares {
        fn tile_finished(&self, _: PixelRect, _: &[[f32; 4]], _: &[f32]) {}
        fn progress(&self, share: f64) {
            self.0.lock().unwrap().push(share);
        }
    }
    let shares = Shares(std::sync::Mutex::new(Vec::new()));
    let options = ParallelOptions {
        render_threads: 2,
        compositing_threads: 1,
        tile_size: 16,
    };
    Renderer::new()
        .render_levels_into(&banded, &camera, &settings, &options, &shares, &|| false)
        .unwrap()
        .unwrap();
    let shares = shares.0.into_inner().unwrap();
    let in_third = |k: f64| {
        shares
            .iter()
            .any(|&s| s > k / 3.0 + 1e-9 && s < (k + 1.0) / 3.0 - 1e-9)
    };
    assert!(
        in_third(0.0) && in_third(1.0) && in_third(2.0),
        "{shares:?}"
    );
    assert!(
        shares.windows(2).all(|w| w[0] <= w[1]),
        "one compositor: in order"
    );
    assert_eq!(shares.last(), Some(&1.0));
    assert_images_match("levels-haze", &mixed.to_image(), &fine.to_image(), 2);
    // Samples of level k stand for 2^k times the distance: far fewer of them,
    // and the far levels never visit level 0's far bricks.
    let (m, f) = (&mixed.stats.counters, &fine.stats.counters);
    assert!(
        m.samples * 10 < f.samples * 7,
        "{} vs {}",
        m.samples,
        f.samples
    );
    let near_only = render_sequential_levels(&banded[..1], &camera, &settings).unwrap();
    assert!(
        near_only.stats.counters.brick_visits * 2 < fine.stats.counters.brick_visits,
        "{} of {} brick visits",
        near_only.stats.counters.brick_visits,
        fine.stats.counters.brick_visits
    );
    // Two-level scenes sample one level per frame.
    let scene = raycaster::render::SegmentScene::parse(
        "layers = [[0.0, 1.0]]\n[[object]]\ntf = \"shapes\"\n",
        dir.path(),
    )
    .unwrap();
    let two_level = RenderSettings {
        segments: Some(scene),
        ..RenderSettings::default()
    };
    let refused = render_sequential_levels(&banded, &camera, &two_level).unwrap_err();
    assert!(refused.to_string().contains("one level"), "{refused}");
    assert!(render_sequential_levels(&banded[..1], &camera, &two_level).is_ok());
}

/// The passes of a frame of several levels are distinct levels of one volume,
/// finest first, each with its band: a program that passes other volumes, a
/// level twice or a level without its band gets an error from both renderers
/// (they were composited as if they were one volume's levels).
#[test]
fn passes_that_are_not_one_volume_s_levels_are_refused_by_both_renderers() {
    let dir = TempDir::new().unwrap();
    let volume = pyramid_shapes(dir.path());
    let camera = close_view(&volume, false);
    let bands = LevelChoice::default().bands(&volume, &camera);
    let levels = prepare_levels(&volume, &bands);
    let passes = level_passes(&levels, &bands);
    let other = render_support::scene_volume(SceneKind::Shells, 128);
    let other = RenderVolume::new(&other, None).unwrap();
    let settings = RenderSettings::default();
    let bad = [
        vec![passes[0], (&other, passes[1].1)],
        vec![passes[0], passes[0]],
        vec![passes[1], passes[0]],
        vec![passes[0], (passes[1].0, None)],
    ];
    for (i, bad) in bad.iter().enumerate() {
        let said = [
            render_sequential_levels(bad, &camera, &settings)
                .map(|_| ())
                .unwrap_err()
                .to_string(),
            Renderer::new()
                .render_levels(bad, &camera, &settings, &ParallelOptions::default())
                .map(|_| ())
                .unwrap_err()
                .to_string(),
        ];
        assert!(said[0].starts_with("levels: "), "case {i}: {}", said[0]);
        assert_eq!(said[0], said[1], "case {i}");
    }
    render_sequential_levels(&passes, &camera, &settings).unwrap();
}
