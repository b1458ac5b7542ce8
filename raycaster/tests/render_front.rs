//! The asynchronous front end: frames complete into the shared buffer, newer
//! requests supersede older ones, shutdown joins, and storms of random requests
//! neither deadlock nor lose a frame's ending.

mod render_support;

use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use raycaster::render::{
    Camera, FrameEvent, FrameRequest, FrameStats, LevelChoice, Mode, ParallelOptions, RenderFront,
    RenderSettings, RenderVolume, render_parallel,
};
use raycaster::synth::SceneKind;
use render_support::*;

/// Runs `f` on a thread and fails the test if it takes longer than `limit`.
fn with_timeout(limit: Duration, f: impl FnOnce() + Send + 'static) {
    let (tx, rx) = std::sync::mpsc::channel();
    let handle = std::thread::spawn(move || {
        f();
        let _ = tx.send(());
    });
    match rx.recv_timeout(limit) {
        Ok(()) => handle.join().unwrap(),
        Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
            // The closure panicked: surface its message.
            handle.join().unwrap();
        }
        Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
            panic!("deadlock: no progress within {limit:?}")
        }
    }
}

fn settings() -> RenderSettings {
    RenderSettings {
        transfer: scene_preset(SceneKind::Shapes),
        ..RenderSettings::default()
    }
}

/// Requests a frame of `camera` at the automatic level and waits (up to 30 s)
/// for it to finish: its id and statistics.
fn finished_frame(
    front: &RenderFront,
    camera: Camera,
    options: ParallelOptions,
) -> (u64, FrameStats) {
    let id = front.request(FrameRequest {
        camera,
        settings: settings(),
        options,
        level: LevelChoice::default(),
    });
    let event = front
        .events()
        .recv_timeout(Duration::from_secs(30))
        .unwrap();
    let FrameEvent::Done { id: done, stats } = event else {
        panic!("expected a finished frame, got {event:?}");
    };
    assert_eq!(done, id);
    (id, stats)
}

#[test]
fn a_frame_completes_into_the_buffer_as_the_parallel_renderer_draws_it() {
    let volume = Arc::new(scene_volume(SceneKind::Shapes, 32));
    let notices = Arc::new(AtomicU64::new(0));
    let counter = notices.clone();
    let front = RenderFront::new(
        volume.clone(),
        None,
        Some(Arc::new(move || {
            counter.fetch_add(1, Ordering::Relaxed);
        })),
    )
    .unwrap();
    let camera = default_camera(&volume, 48);
    let options = ParallelOptions {
        render_threads: 2,
        compositing_threads: 1,
        tile_size: 8,
    };
    let (id, stats) = finished_frame(&front, camera, options);
    assert!(stats.counters.samples > 0);
    let prepared = RenderVolume::new(&volume, None).unwrap();
    let expected = render_parallel(&prepared, &camera, &settings(), &options)
        .unwrap()
        .to_image();
    let fb = front.framebuffer().lock().clone();
    assert_eq!((fb.width, fb.height, fb.frame_id), (48, 48, id));
    assert_eq!(fb.tiles_written, 36, "6×6 tiles of 8 pixels");
    let rgb: Vec<u8> = fb.pixels.iter().flat_map(|p| [p[0], p[1], p[2]]).collect();
    assert_eq!(rgb, expected.data());
    // One notice per tile plus one for the frame's end.
    assert_eq!(notices.load(Ordering::Relaxed), 37);
    front.shutdown();
}

#[test]
fn a_newer_request_supersedes_the_one_in_progress() {
    with_timeout(Duration::from_secs(60), || {
        let volume = Arc::new(scene_volume(SceneKind::Noise, 96));
        let front = RenderFront::new(volume.clone(), None, None).unwrap();
        let slow = FrameRequest {
            camera: default_camera(&volume, 256),
            settings: RenderSettings {
                step: 0.05,
                early_termination: None,
                empty_space_skipping: false,
                transfer: scene_preset(SceneKind::Noise),
                ..RenderSettings::default()
            },
            options: ParallelOptions {
                render_threads: 1,
                compositing_threads: 1,
                tile_size: 16,
            },
            level: LevelChoice::default(),
        };
        let first = front.request(slow.clone());
        std::thread::sleep(Duration::from_millis(20));
        let quick = FrameRequest {
            camera: default_camera(&volume, 16),
            ..slow
        };
        let second = front.request(quick);
        let a = front.events().recv().unwrap();
        let b = front.events().recv().unwrap();
        assert!(
            matches!(a, FrameEvent::Superseded { id } if id == first),
            "{a:?}"
        );
        assert!(
            matches!(b, FrameEvent::Done { id, .. } if id == second),
            "{b:?}"
        );
        front.shutdown();
    });
}

#[test]
fn invalid_settings_fail_the_frame_not_the_front() {
    let volume = Arc::new(scene_volume(SceneKind::Shapes, 16));
    let front = RenderFront::new(volume.clone(), None, None).unwrap();
    let bad = FrameRequest {
        camera: default_camera(&volume, 8),
        settings: RenderSettings {
            step: -1.0,
            ..settings()
        },
        options: ParallelOptions::default(),
        level: LevelChoice::default(),
    };
    let id = front.request(bad.clone());
    let event = front.events().recv().unwrap();
    assert!(
        matches!(event, FrameEvent::Failed { id: i, .. } if i == id),
        "{event:?}"
    );
    let good = FrameRequest {
        settings: settings(),
        ..bad
    };
    let id = front.request(good);
    assert!(matches!(front.events().recv().unwrap(), FrameEvent::Done { id: i, .. } if i == id));
    assert!(
        RenderFront::new(volume, Some(1), None).is_err(),
        "brick side 1 is refused"
    );
}

#[test]
fn a_frame_of_another_size_starts_from_the_last_picture_not_black() {
    let volume = Arc::new(scene_volume(SceneKind::Shapes, 32));
    let front = RenderFront::new(volume.clone(), None, None).unwrap();
    let full = FrameRequest {
        camera: default_camera(&volume, 64),
        settings: settings(),
        options: ParallelOptions::default(),
        level: LevelChoice::default(),
    };
    let id = front.request(full.clone());
    assert!(matches!(front.events().recv().unwrap(), FrameEvent::Done { id: i, .. } if i == id));
    let lit = |pixels: &[[u8; 4]]| {
        pixels
            .iter()
            .filter(|p| p[..3].iter().any(|&c| c > 8))
            .count()
    };
    let shown = lit(&front.framebuffer().lock().pixels);
    assert!(shown > 64 * 64 / 20, "the scene is visible: {shown} pixels");
    // A half-size frame that fails before any tile lands: the buffer holds the
    // last picture scaled to the new size.
    let bad = FrameRequest {
        camera: default_camera(&volume, 32),
        settings: RenderSettings {
            step: -1.0,
            ..settings()
        },
        ..full
    };
    let id = front.request(bad);
    assert!(matches!(front.events().recv().unwrap(), FrameEvent::Failed { id: i, .. } if i == id));
    let fb = front.framebuffer().lock();
    assert_eq!((fb.width, fb.height), (32, 32));
    let scaled = lit(&fb.pixels);
    assert!(
        scaled * 4 > shown / 2 && scaled * 4 < shown * 2,
        "{scaled} lit of 32² after {shown} of 64²"
    );
}

#[test]
fn request_storms_end_every_frame_exactly_once_and_shut_down() {
    with_timeout(Duration::from_secs(240), || {
        let volume = Arc::new(scene_volume(SceneKind::Shapes, 24));
        let mut rng = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move |n: u64| {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            rng % n
        };
        let mut requests = 0;
        let mut done = 0;
        for cycle in 0..400 {
            let front = RenderFront::new(volume.clone(), Some(4 + next(12) as u32), None).unwrap();
            let mut ids = Vec::new();
            for _ in 0..(1 + next(60)) {
                let size = 4 + next(40) as u32;
                let settings = RenderSettings {
                    mode: Mode::ALL[next(4) as usize],
                    step: 0.3 + next(10) as f32 * 0.1,
                    early_termination: (next(2) == 0).then_some(0.99),
                    empty_space_skipping: next(2) == 0,
                    ..settings()
                };
                let options = ParallelOptions {
                    render_threads: 1 + next(4) as usize,
                    compositing_threads: 1 + next(2) as usize,
                    tile_size: 1 + next(20) as u32,
                };
                ids.push(front.request(FrameRequest {
                    camera: default_camera(&volume, size),
                    settings,
                    options,
                    level: LevelChoice::default(),
                }));
                if next(4) == 0 {
                    std::thread::sleep(Duration::from_micros(next(2000)));
                }
            }
            requests += ids.len();
            // Half the cycles wait for the last frame, half shut down at once.
            let wait_for_last = cycle % 2 == 0;
            let mut endings: HashMap<u64, FrameEvent> = HashMap::new();
            if wait_for_last {
                let last = *ids.last().unwrap();
                while !endings.contains_key(&last) {
                    let e = front.events().recv().unwrap();
                    assert!(endings.insert(e.id(), e).is_none(), "a frame ended twice");
                }
                assert!(
                    matches!(endings[&last], FrameEvent::Done { .. }),
                    "the last request completes"
                );
            }
            let events = front.events().clone();
            front.shutdown();
            for e in events.try_iter() {
                assert!(endings.insert(e.id(), e).is_none(), "a frame ended twice");
            }
            assert_eq!(
                endings.len(),
                ids.len(),
                "cycle {cycle}: every request ends exactly once"
            );
            for id in &ids {
                assert!(
                    endings.contains_key(id),
                    "cycle {cycle}: request {id} never ended"
                );
            }
            done += endings
                .values()
                .filter(|e| matches!(e, FrameEvent::Done { .. }))
                .count();
        }
        assert!(requests > 10_000, "{requests} requests");
        assert!(done >= 200, "{done} frames completed");
    });
}

#[test]
fn a_deep_view_renders_its_levels_by_depth_into_the_buffer_like_the_cli() {
    let dir = tempfile::TempDir::new().unwrap();
    let volume = Arc::new(pyramid_shapes(dir.path()));
    let front = RenderFront::new(volume.clone(), None, None).unwrap();
    // Outside and close, and inside the volume.
    for distance in [150.0, 90.0] {
        let camera = wide_view(&volume, distance, 0.7, false, 80, 64);
        let options = ParallelOptions {
            render_threads: 2,
            compositing_threads: 1,
            tile_size: 16,
        };
        let (_, stats) = finished_frame(&front, camera, options);
        let bands = LevelChoice::default().frame_bands(&volume, &camera, &settings(), 3);
        assert!(bands.len() > 1, "{distance}: {bands:?}");
        assert_eq!(
            (stats.level, stats.coarsest_level),
            (bands[0].level as u32, bands[bands.len() - 1].level as u32)
        );
        let levels = prepare_levels(&volume, &bands);
        let passes = level_passes(&levels, &bands);
        let expected = raycaster::render::render_sequential_levels(&passes, &camera, &settings())
            .unwrap()
            .to_image();
        let fb = front.framebuffer().lock().clone();
        assert_eq!(fb.tiles_written, 5 * 4, "every tile, once");
        let rgb: Vec<u8> = fb.pixels.iter().flat_map(|p| [p[0], p[1], p[2]]).collect();
        let got = raycaster::render::RgbImage::new(80, 64, rgb);
        assert_images_match(&format!("front-levels-{distance}"), &got, &expected, 1);
    }
    front.shutdown();
}

#[test]
fn a_file_truncated_under_its_mapping_fails_frames_instead_of_faulting() {
    use raycaster::volume::{Access, Layout, SampleType};
    let dir = tempfile::tempdir().unwrap();
    for access in [Access::Mapped, Access::Ram] {
        let volume = Arc::new(scene_file(
            dir.path(),
            SceneKind::Shapes,
            96,
            Layout::Bricked { side: 16 },
            SampleType::U8,
            access,
        ));
        let path = volume.path().to_path_buf();
        let whole = std::fs::metadata(&path).unwrap().len();
        volume.check_whole().unwrap();
        let front = RenderFront::new(volume.clone(), None, None).unwrap();
        let camera = default_camera(&volume, 48);
        let request = || FrameRequest {
            camera,
            settings: settings(),
            options: ParallelOptions::default(),
            level: LevelChoice::Fixed(0),
        };
        front.request(request());
        let event = front
            .events()
            .recv_timeout(Duration::from_secs(30))
            .unwrap();
        assert!(matches!(event, FrameEvent::Done { .. }), "{event:?}");
        // Another program cuts the file in half (its pyramid and the second
        // half of its samples): a mapped volume's frames fail, naming the file
        // and its sizes; one read into RAM renders on.
        let file = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
        file.set_len(whole / 2).unwrap();
        let id = front.request(request());
        let event = front
            .events()
            .recv_timeout(Duration::from_secs(30))
            .unwrap();
        match (access, event) {
            (Access::Mapped, FrameEvent::Failed { id: failed, error }) => {
                assert_eq!(failed, id);
                let expected = format!(
                    "{}: shrank to {} bytes while open (it held {whole})",
                    path.display(),
                    whole / 2
                );
                assert!(error.starts_with(&expected), "{error}");
                assert!(volume.check_whole().is_err());
            }
            (Access::Ram, FrameEvent::Done { id: done, .. }) => {
                assert_eq!(done, id);
                volume.check_whole().unwrap();
            }
            (access, event) => panic!("{access:?}: {event:?}"),
        }
        front.shutdown();
        drop(volume);
        std::fs::remove_file(&path).unwrap();
    }
}
