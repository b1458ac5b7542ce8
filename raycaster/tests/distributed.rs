//! Distributed rendering against the single-process renderers, with the ranks
//! as threads linked by channels (the same protocol the `raycaster` binary
//! runs over MPI): for 1 to 8 ranks, perspective, orthographic and inside
//! cameras, every plain mode and a two-level scene, the image equals the
//! object-parallel renderer's exactly and the sequential oracle's within
//! 1/255, and the ranks together take exactly the samples one process takes.

mod render_support;

use std::time::Duration;

use raycaster::render::{
    Camera, ClipPlane, ClipRegion, Compositing, CropBox, DepthBand, DistributedFrame,
    DistributedOptions, GlobalMode, LevelChoice, LocalMode, Membership, Mode, ObjectStyle,
    ParallelOptions, Partition, Projection, RenderError, RenderSettings, RenderVolume, Renderer,
    SegmentScene, SimdLevel, Vec3, channel_links, render_distributed_levels, render_parallel,
    render_sequential,
};
use raycaster::synth::SceneKind;
use raycaster::volume::Volume;
use render_support::*;

const SIZE: u32 = 36;

fn cameras(volume: &Volume) -> Vec<(&'static str, Camera)> {
    let c = centre(volume);
    vec![
        ("perspective", default_camera(volume, SIZE)),
        (
            "orthographic",
            Camera::look_at(
                c + Vec3::new(-40.0, 45.0, -30.0),
                c,
                Vec3::Z,
                Projection::Orthographic { height: 70.0 },
                SIZE,
                SIZE + 5,
            )
            .unwrap(),
        ),
        (
            "inside",
            Camera::look_at(
                c + Vec3::new(1.5, -2.0, 0.7),
                c + Vec3::new(20.0, 8.0, -5.0),
                Vec3::Z,
                Projection::Perspective { vfov_deg: 100.0 },
                SIZE + 3,
                SIZE,
            )
            .unwrap(),
        ),
    ]
}

/// Renders on `ranks` thread-ranks; rank 0's result.
fn distributed(
    volume: &RenderVolume<'_>,
    camera: &Camera,
    settings: &RenderSettings,
    ranks: usize,
    tile: u32,
    bands: Option<u32>,
) -> DistributedFrame {
    distributed_with(
        volume,
        camera,
        settings,
        ranks,
        tile,
        bands,
        Compositing::Relay,
    )
    .unwrap()
}

/// Renders on `ranks` thread-ranks with `compositing`; rank 0's result or the
/// first rank's error.
fn distributed_with(
    volume: &RenderVolume<'_>,
    camera: &Camera,
    settings: &RenderSettings,
    ranks: usize,
    tile: u32,
    bands: Option<u32>,
    compositing: Compositing,
) -> Result<DistributedFrame, RenderError> {
    distributed_levels(
        &[(volume, None)],
        camera,
        settings,
        ranks,
        tile,
        bands,
        compositing,
    )
}

/// Renders a frame of several levels on `ranks` thread-ranks with
/// `compositing`; rank 0's result or the first rank's error.
fn distributed_levels(
    passes: &[(&RenderVolume<'_>, Option<DepthBand>)],
    camera: &Camera,
    settings: &RenderSettings,
    ranks: usize,
    tile: u32,
    bands: Option<u32>,
    compositing: Compositing,
) -> Result<DistributedFrame, RenderError> {
    let links = channel_links(ranks, Duration::from_secs(120));
    let options = DistributedOptions {
        parallel: ParallelOptions {
            render_threads: 1,
            compositing_threads: 1,
            tile_size: tile,
        },
        bands,
        compositing,
    };
    std::thread::scope(|scope| {
        let handles: Vec<_> = links
            .iter()
            .map(|link| {
                scope.spawn(move || {
                    render_distributed_levels(
                        link,
                        &mut Renderer::new(),
                        passes,
                        camera,
                        settings,
                        &options,
                    )
                })
            })
            .collect();
        let results: Vec<Result<DistributedFrame, RenderError>> =
            handles.into_iter().map(|h| h.join().unwrap()).collect();
        let mut frames = Vec::new();
        for result in results {
            frames.push(result?);
        }
        for other in &frames[1..] {
            assert!(other.frame.is_none(), "only rank 0 assembles the image");
        }
        Ok(frames.swap_remove(0))
    })
}

fn layers_scene() -> SegmentScene {
    let tf = scene_preset(SceneKind::Shapes);
    let modes = [
        LocalMode::Dvr,
        LocalMode::Mip,
        LocalMode::Importance {
            source: raycaster::render::ImportanceSource::Constant(1.0),
        },
    ];
    SegmentScene {
        // (Normalised over the domain: raw 40, 120, 200 of 0..255. Written
        // raw, every value fell below the first layer and the scene showed
        // nothing; the settings check refuses such layers now.)
        membership: Membership::Layers(vec![
            [40.0 / 255.0, 120.0 / 255.0],
            [120.0 / 255.0, 200.0 / 255.0],
            [200.0 / 255.0, 1.0],
        ]),
        objects: modes
            .iter()
            .enumerate()
            .map(|(i, &mode)| ObjectStyle {
                name: format!("layer {i}"),
                id: (i + 1) as u8,
                visible: true,
                transfer: tf.clone(),
                mode,
                // The second layer cut by a plane: per-object clipping crosses parts too.
                clip: if i == 1 {
                    ClipRegion {
                        crop: None,
                        planes: vec![ClipPlane {
                            point: Vec3::splat(18.0),
                            normal: Vec3::new(0.2, 1.0, 0.0),
                        }],
                    }
                } else {
                    ClipRegion::default()
                },
            })
            .collect(),
        global: GlobalMode::Dvr,
    }
}

/// DVR of the `shapes` scene at a step that puts samples off the voxel grid.
fn shapes_settings() -> RenderSettings {
    RenderSettings {
        transfer: scene_preset(SceneKind::Shapes),
        step: 0.6,
        ..RenderSettings::default()
    }
}

#[test]
fn every_rank_count_camera_and_mode_gives_the_single_process_image() {
    let volume = scene_volume(SceneKind::Shapes, 40);
    let prepared = RenderVolume::new(&volume, Some(9)).unwrap();
    let base = shapes_settings();
    let mut cases: Vec<(String, RenderSettings)> = Mode::ALL
        .iter()
        .map(|&mode| {
            (
                mode.name().to_string(),
                RenderSettings {
                    mode,
                    ..base.clone()
                },
            )
        })
        .collect();
    cases.push((
        "two-level".into(),
        RenderSettings {
            segments: Some(layers_scene()),
            ..base.clone()
        },
    ));
    cases.push((
        "dvr-no-ert-no-ess-jitter".into(),
        RenderSettings {
            early_termination: None,
            empty_space_skipping: false,
            jitter: true,
            ..base.clone()
        },
    ));
    cases.push((
        "dvr-crop-and-clip".into(),
        RenderSettings {
            clip: ClipRegion {
                crop: Some(CropBox {
                    lo: Vec3::new(3.0, 5.5, 2.0),
                    hi: Vec3::new(36.0, 30.0, 33.0),
                }),
                planes: vec![ClipPlane {
                    point: Vec3::splat(20.0),
                    normal: Vec3::new(1.0, -0.5, 0.3),
                }],
            },
            ..base.clone()
        },
    ));
    cases.push((
        "dvr-preintegrated".into(),
        RenderSettings {
            preintegrated: true,
            ..base.clone()
        },
    ));
    let mut checked = 0;
    for (view, camera) in cameras(&volume) {
        for (name, settings) in &cases {
            let single = render_parallel(
                &prepared,
                &camera,
                settings,
                &ParallelOptions {
                    render_threads: 2,
                    compositing_threads: 1,
                    tile_size: 8,
                },
            )
            .unwrap();
            let oracle = render_sequential(&prepared, &camera, settings).unwrap();
            let single_image = single.to_image();
            for ranks in [1, 2, 3, 4, 8] {
                let (tile, bands) = match ranks {
                    3 => (5, Some(7)),
                    8 => (8, Some(2)),
                    _ => (8, None),
                };
                let result = distributed(&prepared, &camera, settings, ranks, tile, bands);
                let frame = result.frame.unwrap();
                let label = format!("{view} {name} {ranks} ranks");
                assert_images_match(&label, &frame.to_image(), &single_image, 0);
                assert_images_match(&label, &frame.to_image(), &oracle.to_image(), 1);
                assert_eq!(frame.depth.len(), single.depth.len());
                for (a, b) in frame.depth.iter().zip(&single.depth) {
                    assert!(a == b || (a - b).abs() < 1e-4, "{label}: depth {a} vs {b}");
                }
                assert_eq!(
                    frame.stats.counters.samples, single.stats.counters.samples,
                    "{label}: the ranks together take the samples one process takes"
                );
                assert_eq!(
                    frame.stats.counters.rays_terminated, single.stats.counters.rays_terminated,
                    "{label}"
                );
                assert_eq!(
                    result.ranks.len(),
                    ranks,
                    "{label}: one statistics row per rank"
                );
                let per_rank: u64 = result.ranks.iter().map(|r| r.counters.samples).sum();
                assert_eq!(per_rank, frame.stats.counters.samples, "{label}");
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 3 * (Mode::ALL.len() + 4) * 5);
}

#[test]
fn ranks_share_the_rendered_bricks_and_each_renders_only_its_part() {
    let volume = scene_volume(SceneKind::Shapes, 48);
    let prepared = RenderVolume::new(&volume, Some(9)).unwrap();
    let settings = RenderSettings {
        transfer: scene_preset(SceneKind::Shapes),
        ..RenderSettings::default()
    };
    let camera = default_camera(&volume, 40);
    let partition = Partition::new(&prepared, &settings, 4).unwrap();
    let result = distributed(&prepared, &camera, &settings, 4, 8, None);
    for (r, stats) in result.ranks.iter().enumerate() {
        assert_eq!(stats.rank as usize, r);
        assert_eq!(stats.part_box(), partition.parts()[r]);
        assert_eq!(stats.bricks, partition.weights()[r]);
        assert!(
            stats.counters.samples > 0,
            "rank {r} rendered nothing: {stats:?}"
        );
    }
    let total: u64 = partition.weights().iter().sum();
    for &w in partition.weights() {
        assert!(w * 4 >= total / 2, "unbalanced: {:?}", partition.weights());
    }
}

#[test]
fn direct_send_of_partial_images_matches_for_dvr_and_refuses_other_modes() {
    let volume = scene_volume(SceneKind::Shapes, 40);
    let prepared = RenderVolume::new(&volume, Some(9)).unwrap();
    let base = shapes_settings();
    let options = ParallelOptions {
        render_threads: 2,
        compositing_threads: 1,
        tile_size: 8,
    };
    for (view, camera) in cameras(&volume) {
        // With ERT each part stops only at its own opacity threshold, so the
        // parts behind add what one process skips: at most (1 − 0.99) of
        // full intensity, 2.55/255, which can round to 3.
        for (ert, tolerance) in [(None, 1), (Some(0.99), 3)] {
            let settings = RenderSettings {
                early_termination: ert,
                ..base.clone()
            };
            let single = render_parallel(&prepared, &camera, &settings, &options).unwrap();
            for ranks in [1, 2, 3, 5, 8] {
                let frame = distributed_with(
                    &prepared,
                    &camera,
                    &settings,
                    ranks,
                    8,
                    None,
                    Compositing::DirectSend,
                )
                .unwrap()
                .frame
                .unwrap();
                let label = format!("direct send, {view}, ERT {ert:?}, {ranks} ranks");
                assert_images_match(&label, &frame.to_image(), &single.to_image(), tolerance);
                if ert.is_none() {
                    assert_eq!(
                        frame.stats.counters.samples, single.stats.counters.samples,
                        "{label}: without ERT the parts take exactly one process's samples"
                    );
                } else {
                    assert!(
                        frame.stats.counters.samples >= single.stats.counters.samples,
                        "{label}: ERT per part can only take more samples"
                    );
                }
            }
        }
    }
    let camera = default_camera(&volume, SIZE);
    for settings in [
        RenderSettings {
            mode: Mode::Mip,
            ..base.clone()
        },
        RenderSettings {
            segments: Some(layers_scene()),
            ..base.clone()
        },
        // A pre-integrated sample's segment reaches into the part behind: the
        // seams lost it (8–19/255).
        RenderSettings {
            preintegrated: true,
            ..base.clone()
        },
    ] {
        let error = distributed_with(
            &prepared,
            &camera,
            &settings,
            2,
            8,
            None,
            Compositing::DirectSend,
        )
        .unwrap_err();
        assert!(
            error
                .to_string()
                .contains("DVR without pre-integration only"),
            "{error}"
        );
    }
}

#[test]
fn a_frame_of_several_levels_gives_the_single_process_image() {
    let dir = tempfile::TempDir::new().unwrap();
    let volume = pyramid_shapes(dir.path());
    let views = [
        (150.0, 0.7, 48),
        // The camera inside the volume.
        (40.0, 2.0, 40),
    ];
    for (distance, azimuth, size) in views {
        let camera = wide_view(&volume, distance, azimuth, false, size, size);
        let bands = LevelChoice::default().bands(&volume, &camera);
        assert!(bands.len() > 1, "{distance}: {bands:?}");
        let levels = prepare_levels(&volume, &bands);
        let passes = level_passes(&levels, &bands);
        for (mode, jitter) in [
            (Mode::Dvr, true),
            (Mode::Mip, false),
            (Mode::FirstHit, false),
        ] {
            let settings = RenderSettings {
                mode,
                jitter,
                transfer: scene_preset(SceneKind::Shapes),
                simd: Some(SimdLevel::Scalar),
                ..RenderSettings::default()
            };
            let options = ParallelOptions {
                render_threads: 1,
                compositing_threads: 1,
                tile_size: 8,
            };
            let single = Renderer::new()
                .render_levels(&passes, &camera, &settings, &options)
                .unwrap();
            for ranks in [1, 2, 3, 4] {
                let name = format!("levels-{distance}-{mode:?}-{ranks}");
                let frame = distributed_levels(
                    &passes,
                    &camera,
                    &settings,
                    ranks,
                    8,
                    None,
                    Compositing::Relay,
                )
                .unwrap()
                .frame
                .unwrap();
                assert_images_match(&name, &frame.to_image(), &single.to_image(), 0);
                assert_eq!(
                    frame.stats.counters.samples, single.stats.counters.samples,
                    "{name}"
                );
                assert_eq!(
                    (frame.stats.level, frame.stats.coarsest_level),
                    (single.stats.level, single.stats.coarsest_level)
                );
            }
        }
        // Direct send composites partial images of one level only.
        let dvr = RenderSettings::default();
        let refused =
            distributed_levels(&passes, &camera, &dvr, 2, 8, None, Compositing::DirectSend)
                .unwrap_err();
        assert!(refused.to_string().contains("one level"), "{refused}");
    }
}
