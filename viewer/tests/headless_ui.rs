//! The viewer driven headless: Slint's testing backend with the software
//! renderer, mock time and no event loop (the test pumps the controller).
//!
//! One test function: the platform can be set once per process.

use std::path::Path;
use std::time::{Duration, Instant};

mod support;
use support::{element, generate_file, mode_index, settle, wait_for_frame};

use i_slint_backend_testing::ElementHandle;
use raycaster::render::SegmentScene;
use raycaster::synth::SceneKind;
use slint::platform::PointerEventButton;
use slint::{ComponentHandle, LogicalPosition};
use viewer::{Source, Viewer};

/// Pumps until `done` holds (a background open has landed), then until its frame
/// is on screen.
fn wait_until(v: &Viewer, done: impl Fn(&Viewer) -> bool) {
    let start = Instant::now();
    while !done(v) {
        v.pump();
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "{:?}",
            v.ui().get_message()
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    wait_for_frame(v);
}

/// The canvas image as RGB triples, with its size.
fn frame(v: &Viewer) -> (u32, u32, Vec<[u8; 3]>) {
    let image = v.ui().get_frame();
    let buffer = image.to_rgba8().expect("the canvas holds a pixel image");
    let pixels = buffer
        .as_bytes()
        .chunks(4)
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    (buffer.width(), buffer.height(), pixels)
}

fn lit(pixels: &[[u8; 3]]) -> usize {
    pixels.iter().filter(|p| p.iter().any(|&c| c > 8)).count()
}

#[test]
fn the_viewer_runs_headless() {
    support::headless_platform();
    let config = tempfile::tempdir().unwrap();
    support::private_config(config.path());

    let v = Viewer::new(Source::BuiltIn(SceneKind::Shapes, 64), None).unwrap();
    v.ui()
        .window()
        .set_size(slint::LogicalSize::new(1000.0, 700.0));
    v.ui().show().unwrap();

    // 1. It starts on the built-in scene and shows a non-empty image (a
    // full-quality frame of the laid-out canvas).
    v.pump();
    v.ui().invoke_reset_view();
    wait_for_frame(&v);
    assert_eq!(v.last_stats().map(|(_, moving)| moving), Some(false));
    let (w, h, first) = frame(&v);
    assert!(w > 200 && h > 200, "canvas frame {w}×{h}");
    assert!(lit(&first) > first.len() / 50, "the scene is visible");
    assert!(
        v.ui().get_status().contains("samples/s"),
        "{}",
        v.ui().get_status()
    );
    let shot = v.ui().window().take_snapshot().unwrap();
    let canvas_lit = shot
        .as_bytes()
        .chunks(4)
        .filter(|p| p[0] > 100 && p[1] > 40 && p[2] < 120)
        .count();
    assert!(
        canvas_lit > 500,
        "orange solids on screen: {canvas_lit} pixels"
    );

    // 2. A drag orbits the camera; an interactive frame, then full quality.
    // The release asks for full quality while the drag's frame renders: that
    // frame finishes first (the full-quality tiles fill in over a picture of
    // their own view; over the drag's unfinished older view they showed torn
    // edges), so none is superseded.
    let before = v.orbit();
    let superseded = v.frames_superseded();
    let canvas = element(&v, "App::canvas");
    let c = canvas.absolute_position();
    let size = canvas.size();
    let centre = LogicalPosition::new(c.x + size.width / 2.0, c.y + size.height / 2.0);
    canvas.mock_drag(
        LogicalPosition::new(centre.x + 120.0, centre.y + 30.0),
        PointerEventButton::Left,
    );
    let after = v.orbit();
    assert!(
        (after.azimuth - before.azimuth).abs() > 0.5,
        "azimuth {} → {}",
        before.azimuth,
        after.azimuth
    );
    assert!(after.elevation != before.elevation);
    wait_for_frame(&v);
    let (_, _, dragged) = frame(&v);
    assert_eq!(v.last_stats().map(|(_, moving)| moving), Some(false));
    assert_eq!(
        v.frames_superseded(),
        superseded,
        "the release superseded the drag's frame"
    );
    assert_ne!(dragged, first, "the rotated view differs");

    // The wheel zooms: a coarser interactive frame first, full quality once the
    // view rests.
    canvas.scroll(0.0, 240.0);
    wait_for_frame(&v);
    let (iw, ih, _) = frame(&v);
    let (stats, moving) = v.last_stats().unwrap();
    assert!(moving, "the wheel frame is interactive");
    // With AVX2 its step is the still frames' half voxel; without, it is
    // coarser (unless this machine is fast enough for still quality),
    // pre-integrated from 1 voxel (below the brick step, 15 voxels here, where
    // skipping would stop).
    let status = v.ui().get_status().to_string();
    let step: f32 = status
        .split(" · step ")
        .nth(1)
        .and_then(|rest| rest.split([' ', '·']).next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no step in {status:?}"));
    assert!((0.5..=4.0).contains(&step), "{status}");
    if raycaster::render::SimdLevel::automatic().has_gathers() {
        assert_eq!(step, 0.5, "{status}");
    }
    assert_eq!(
        status.contains("pre-integrated"),
        (1.0..15.0).contains(&step),
        "{status}"
    );
    // (At most the canvas: the pacing learnt from the drag's frame brings
    // them up to full resolution where frames are fast.)
    assert!(iw <= w && ih <= h, "interactive frame {iw}×{ih} vs {w}×{h}");
    assert_eq!((stats.width, stats.height), (iw, ih));
    i_slint_backend_testing::mock_elapsed_time(Duration::from_millis(300));
    slint::platform::update_timers_and_animations();
    wait_for_frame(&v);
    let (fw, fh, zoomed) = frame(&v);
    assert_eq!((fw, fh), (w, h), "full quality after the motion stops");
    assert_eq!(v.last_stats().map(|(_, m)| m), Some(false));
    assert!(
        lit(&zoomed) > lit(&dragged),
        "zoomed in, the scene fills more"
    );

    // Pacing: a burst of wheel steps while a moving frame renders. No moving
    // frame is dropped unfinished (each shows whole); the newest view follows
    // the one in flight, and full quality once the view rests.
    let superseded = v.frames_superseded();
    for _ in 0..10 {
        canvas.scroll(0.0, 24.0);
    }
    wait_for_frame(&v);
    assert_eq!(
        v.frames_superseded(),
        superseded,
        "moving frames were dropped before they finished"
    );
    let (_, moving) = v.last_stats().unwrap();
    assert!(moving);
    i_slint_backend_testing::mock_elapsed_time(Duration::from_millis(300));
    slint::platform::update_timers_and_animations();
    wait_for_frame(&v);
    assert_eq!(v.last_stats().map(|(_, m)| m), Some(false));
    assert_eq!(frame(&v).0, w);

    // "Pre-integration" in the panel: still frames too.
    assert!(!v.ui().get_status().contains("pre-integrated"));
    let before_preintegration = frame(&v).2;
    v.ui().set_preintegrate(true);
    v.ui().invoke_settings_changed();
    settle(&v);
    let status = v.ui().get_status().to_string();
    assert!(
        !status.starts_with("interactive") && status.contains("step 0.5 pre-integrated"),
        "{status}"
    );
    assert_ne!(frame(&v).2, before_preintegration, "pre-integration shows");
    // MIP ignores it: the status does not claim it.
    v.ui()
        .set_mode_index(mode_index(raycaster::render::Mode::Mip));
    v.ui().invoke_settings_changed();
    settle(&v);
    let status = v.ui().get_status().to_string();
    assert!(!status.contains("pre-integrated"), "{status}");
    v.ui().set_mode_index(0);
    v.ui().set_preintegrate(false);
    v.ui().invoke_settings_changed();

    // "Full quality only": moving frames are full size too.
    v.ui().set_full_quality_only(true);
    canvas.scroll(0.0, -120.0);
    wait_for_frame(&v);
    assert_eq!(frame(&v).0, w);
    v.ui().set_full_quality_only(false);

    // Moving frames show whole: while one renders, the canvas keeps the last
    // picture and then shows the new one, never its tiles over the old view
    // (they tore the picture while dragging). Pumped as fast as the test can,
    // one render thread (slower frames), over several wheel steps.
    settle(&v);
    let threads = v.ui().get_threads();
    v.ui().set_threads(1);
    for notch in 0..6 {
        let mut seen = vec![frame(&v).2];
        canvas.scroll(0.0, if notch % 2 == 0 { 24.0 } else { -24.0 });
        let start = Instant::now();
        while !v.idle() {
            v.pump();
            let shown = frame(&v).2;
            if seen.last() != Some(&shown) {
                seen.push(shown);
            }
            assert!(start.elapsed() < Duration::from_secs(60), "no frame");
        }
        assert!(v.last_stats().unwrap().1, "a moving frame");
        assert_eq!(
            seen.len(),
            2,
            "wheel step {notch}: the canvas showed {} pictures for one moving frame",
            seen.len()
        );
    }
    v.ui().set_threads(threads);

    // 3. Another preset changes the image.
    let (_, _, before_preset) = frame(&v);
    let grayscale = raycaster::render::PRESETS
        .iter()
        .position(|(n, _)| *n == "grayscale")
        .unwrap() as i32;
    v.ui().set_preset_index(grayscale);
    v.ui().invoke_preset_selected(grayscale);
    wait_for_frame(&v);
    let (_, _, gray) = frame(&v);
    assert_ne!(gray, before_preset);
    assert!(
        gray.iter()
            .filter(|p| p[0] > 20)
            .all(|p| p[0].abs_diff(p[2]) <= 2),
        "the grayscale preset renders grey"
    );

    // Editing the transfer function: a click adds a point and re-renders.
    let tf = element(&v, "App::tf-area");
    tf.mock_single_click(PointerEventButton::Left);
    wait_for_frame(&v);
    assert_ne!(frame(&v).2, gray, "the new control point changes the image");
    // The picker no longer names the preset: the curve is custom.
    {
        use slint::Model;
        let index = v.ui().get_preset_index();
        let entries = v.ui().get_tf_presets();
        assert_eq!(index as usize, raycaster::render::PRESETS.len());
        assert_eq!(entries.row_data(index as usize).unwrap(), "custom");
        // Picking `custom` keeps the curve.
        let edited = frame(&v).2;
        v.ui().invoke_preset_selected(index);
        wait_for_frame(&v);
        assert_eq!(frame(&v).2, edited);
    }

    // 4. A bad file shows an error and keeps the old volume.
    let dir = tempfile::tempdir().unwrap();
    let name = v.volume_name();
    let session = dir.path().join("view.toml");
    std::fs::write(&session, "version = 1\n").unwrap();
    for bad in [
        dir.path().join("missing.vol"),
        {
            let junk = dir.path().join("junk.vol");
            std::fs::write(&junk, b"this is not a volume").unwrap();
            junk
        },
        session.clone(),
    ] {
        v.ui().set_file_path(bad.display().to_string().into());
        element(&v, "App::open-button").invoke_accessible_default_action();
        let start = Instant::now();
        while !v.ui().get_message_is_error() {
            v.pump();
            assert!(start.elapsed() < Duration::from_secs(30), "no error shown");
            std::thread::sleep(Duration::from_millis(5));
        }
        let message = v.ui().get_message().to_string();
        let file = bad.file_name().unwrap().to_string_lossy().into_owned();
        assert!(message.contains(&file), "{message}");
        assert!(message.contains("previous volume stays"), "{message}");
        // A session typed where a volume belongs: what opens it is named.
        assert_eq!(
            bad == session,
            message.contains("is a TOML file, not a volume: Open session opens a saved session"),
            "{message}"
        );
        assert_eq!(v.volume_name(), name, "the old volume stays");
        v.ui().invoke_reset_view();
        wait_for_frame(&v);
        assert!(lit(&frame(&v).2) > 0, "and still renders");
        v.ui().set_message_is_error(false);
    }

    // A good file opens (in the background) and replaces the volume. A
    // screenshot asked for while the old view rendered is dropped, and said so:
    // it would have shown the new volume.
    let good = dir.path().join("shells.vol");
    generate_file(&good, SceneKind::Shells, 48);
    // (A moving frame: it settles only when the mocked clock moves, so the
    // volume is installed before the old view is complete.)
    v.ui().invoke_cut_changed(true);
    let early = dir.path().join("early.png");
    v.ui()
        .invoke_save_screenshot(early.display().to_string().into());
    v.ui().invoke_open_file(good.display().to_string().into());
    wait_until(&v, |v| v.volume_name() == good.display().to_string());
    let message = v.ui().get_message().to_string();
    assert!(
        message
            .contains("early.png was not saved: the volume changed before its frame was complete"),
        "{message}"
    );
    wait_for_frame(&v);
    assert!(!early.exists());
    assert!(v.ui().get_volume_info().contains("48×48×48"));

    // Segments: a layer scene loads into the panel, renders, edits and saves.
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../volumes/scenes");
    let plain = frame(&v).2;
    v.ui()
        .invoke_load_scene(scenes.join("shapes-npr.toml").display().to_string().into());
    wait_for_frame(&v);
    use slint::Model;
    let rows = v.ui().get_objects();
    assert_eq!(rows.row_count(), 2);
    assert_ne!(frame(&v).2, plain, "two-level rendering differs");
    // The objects' functions are their own: the global one's picker and
    // editor do nothing then, and say so (edits marked it "custom", unused).
    let preset_box = element(&v, "App::preset-box");
    assert_eq!(preset_box.accessible_enabled(), Some(false));
    // So do the objects' modes: the Mode picker is off (it changed nothing).
    // (A tall window: the element search passes over what the panel's
    // scroll area has outside the window.)
    let size = v.ui().window().size();
    v.ui()
        .window()
        .set_size(slint::LogicalSize::new(1000.0, 2400.0));
    v.pump();
    let mode_box = element(&v, "App::mode-box");
    assert_eq!(mode_box.accessible_enabled(), Some(false));
    v.ui().window().set_size(size);
    v.pump();
    v.ui().invoke_canvas_resized();
    wait_for_frame(&v);
    let (preset, curve) = (
        v.ui().get_preset_index(),
        v.session().unwrap().settings.transfer,
    );
    element(&v, "App::tf-area").mock_single_click(PointerEventButton::Left);
    v.pump();
    assert_eq!(v.ui().get_preset_index(), preset, "not marked custom");
    assert_eq!(
        v.session().unwrap().settings.transfer,
        curve,
        "a click on the editor adds no point"
    );
    // Objects whose functions come from files (no preset) show "custom" in
    // their picker (it was empty).
    v.ui().invoke_load_scene(
        scenes
            .join("shapes-windows.toml")
            .display()
            .to_string()
            .into(),
    );
    wait_for_frame(&v);
    let custom = v.ui().get_tf_presets().row_count() as i32 - 1;
    let windows = v.ui().get_objects();
    assert_eq!(windows.row_count(), 3);
    assert!((0..3).all(|i| windows.row_data(i).unwrap().preset_index == custom));
    v.ui()
        .invoke_load_scene(scenes.join("shapes-npr.toml").display().to_string().into());
    wait_for_frame(&v);
    let rows = v.ui().get_objects();
    // Every object hidden is said (the canvas went black unsaid), and the
    // note goes once one shows again.
    let mut first = rows.row_data(0).unwrap();
    first.visible = false;
    v.ui().invoke_object_changed(0, first.clone());
    let mut row = rows.row_data(1).unwrap();
    row.visible = false;
    v.ui().invoke_object_changed(1, row);
    wait_for_frame(&v);
    assert!(
        v.ui()
            .get_message()
            .contains("every object of the scene is hidden"),
        "{}",
        v.ui().get_message()
    );
    first.visible = true;
    v.ui().invoke_object_changed(0, first.clone());
    wait_for_frame(&v);
    assert_eq!(v.ui().get_message(), "");
    // Nor does it outlive the scene.
    first.visible = false;
    v.ui().invoke_object_changed(0, first.clone());
    assert!(
        v.ui()
            .get_message()
            .contains("every object of the scene is hidden")
    );
    v.ui().invoke_clear_scene();
    wait_for_frame(&v);
    // (The hidden-objects note goes with the scene, and so does "loaded
    // scene …", which stayed under the plain picture.)
    assert_eq!(
        v.ui().get_message(),
        "plain rendering: the scene was dropped"
    );
    v.ui()
        .invoke_load_scene(scenes.join("shapes-npr.toml").display().to_string().into());
    wait_for_frame(&v);
    let rows = v.ui().get_objects();
    let mut row = rows.row_data(1).unwrap();
    row.visible = false;
    v.ui().invoke_object_changed(1, row);
    wait_for_frame(&v);
    assert!(!v.ui().get_objects().row_data(1).unwrap().visible);
    let saved = dir.path().join("saved.toml");
    v.ui().invoke_save_scene(saved.display().to_string().into());
    let back = SegmentScene::load(&saved).unwrap();
    assert!(!back.objects[1].visible, "the edit is saved");
    // A gain set by the scene file goes back to the automatic one with its
    // row's *auto* button; rows without a set gain have none.
    let label = |i| v.ui().get_objects().row_data(i).unwrap().param_label;
    assert_eq!(label(0), "gain");
    // (A tall window: the search passes over the panel's rows outside it.)
    let size = v.ui().window().size();
    v.ui()
        .window()
        .set_size(slint::LogicalSize::new(1000.0, 2400.0));
    v.pump();
    let buttons: Vec<_> = ElementHandle::find_by_element_id(v.ui(), "App::gain-auto").collect();
    assert_eq!(buttons.len(), 1, "one row has a set gain");
    buttons[0].invoke_accessible_default_action();
    wait_for_frame(&v);
    assert_eq!(label(0), "gain (auto)");
    assert_eq!(
        ElementHandle::find_by_element_id(v.ui(), "App::gain-auto").count(),
        0
    );
    v.ui().window().set_size(size);
    v.pump();
    v.ui().invoke_canvas_resized();
    wait_for_frame(&v);
    v.ui().invoke_save_scene(saved.display().to_string().into());
    v.ui().invoke_save_scene(saved.display().to_string().into());
    let back = SegmentScene::load(&saved).unwrap();
    assert_eq!(
        back.objects[0].mode,
        raycaster::render::LocalMode::XRay { gain: None },
        "saved without a gain"
    );
    settle(&v);

    // Screenshot.
    let png = dir.path().join("shot.png");
    v.ui()
        .invoke_save_screenshot(png.display().to_string().into());
    let image = raycaster::render::RgbImage::load_png(&png).unwrap();
    let (sw, sh, shown) = frame(&v);
    assert_eq!((image.width(), image.height()), (sw, sh));
    assert_eq!(
        image.data(),
        shown.as_flattened(),
        "the screenshot is the frame on screen"
    );
    assert_eq!((sw, sh), (w, h), "long paths do not resize the canvas");
    // Save PNG on an existing file: replaced only when pressed again.
    std::fs::write(&png, b"keep me").unwrap();
    v.ui()
        .invoke_save_screenshot(png.display().to_string().into());
    let message = v.ui().get_message().to_string();
    assert!(
        message.contains("shot.png exists: press Save PNG again to replace it"),
        "{message}"
    );
    assert_eq!(std::fs::read(&png).unwrap(), b"keep me");
    v.ui()
        .invoke_save_screenshot(png.display().to_string().into());
    assert!(raycaster::render::RgbImage::load_png(&png).is_ok());
    // No name: said, not an empty OS error.
    v.ui().invoke_save_screenshot("".into());
    assert_eq!(
        v.ui().get_message(),
        "type a file name for the PNG next to Save PNG"
    );
    // Another extension: refused as the CLI's -o refuses it, nothing written.
    let jpg = png.with_extension("jpg");
    v.ui()
        .invoke_save_screenshot(jpg.display().to_string().into());
    let message = v.ui().get_message().to_string();
    assert!(
        message.ends_with("shot.jpg: only PNG images are written; name the file with .png"),
        "{message}"
    );
    assert!(!jpg.exists());
    // A folder takes numbered screenshots, as the S key saves them (it was
    // refused as a name without .png).
    let shots = dir.path().join("shots");
    std::fs::create_dir(&shots).unwrap();
    v.ui()
        .invoke_save_screenshot(shots.display().to_string().into());
    settle(&v);
    assert!(
        shots.join("screenshot-1.png").exists(),
        "{}",
        v.ui().get_message()
    );
    // Save session: no name, or a folder, is said (it said "cannot write
    // session : No such file or directory").
    for blank in ["", "   "] {
        v.ui().invoke_save_session(blank.into());
        assert_eq!(
            v.ui().get_message(),
            "type a file name for the session next to Save session"
        );
    }
    v.ui()
        .invoke_save_session(shots.display().to_string().into());
    assert!(
        v.ui()
            .get_message()
            .ends_with("shots: is a folder; name a .toml file in it"),
        "{}",
        v.ui().get_message()
    );

    // A scan in a foreign format (a NIfTI-1 fixture written by nibabel) opens directly.
    let nifti = Path::new(env!("CARGO_MANIFEST_DIR")).join("../volumes/fixtures/u8.nii");
    v.ui().invoke_open_file(nifti.display().to_string().into());
    wait_until(&v, |v| v.ui().get_volume_info().contains("6×5×4"));
    assert!(!v.ui().get_message_is_error(), "{:?}", v.ui().get_message());
    // The segment scene loaded above described the old volume: cleared, and said.
    assert_eq!(v.ui().get_objects().row_count(), 0);
    assert_eq!(preset_box.accessible_enabled(), Some(true));
    let message = v.ui().get_message().to_string();
    assert!(
        message.contains("the two-level scene was cleared: it described the previous volume"),
        "{message}"
    );

    // Bytes after a file's last block: it opens, and the message says so as
    // `raycaster render` does.
    let joined = dir.path().join("joined.vol");
    generate_file(&joined, SceneKind::Shapes, 24);
    let len = std::fs::metadata(&joined).unwrap().len();
    let mut f = std::fs::OpenOptions::new()
        .append(true)
        .open(&joined)
        .unwrap();
    std::io::Write::write_all(&mut f, &[1; 10]).unwrap();
    drop(f);
    v.ui().invoke_open_file(joined.display().to_string().into());
    wait_until(&v, |v| v.volume_name() == joined.display().to_string());
    let message = v.ui().get_message().to_string();
    assert!(
        message.contains(&format!(
            "the file has 10 bytes after its last block (from byte {len})"
        )) && !v.ui().get_message_is_error(),
        "{message}"
    );

    // A session a parser refuses: the message is one line that keeps the
    // reason (before: its snippet lines pushed it out of sight).
    let bad = dir.path().join("bad-session.toml");
    std::fs::write(&bad, "version = 1\n[volume]\nfile = 5\n").unwrap();
    v.ui().invoke_open_session(bad.display().to_string().into());
    wait_until(&v, |v| v.ui().get_message_is_error());
    let message = v.ui().get_message().to_string();
    assert!(
        !message.contains('\n')
            && message
                .contains("session: line 3, column 8 (`file = 5`): invalid type: integer `5`")
            && message.contains("invalid type: integer `5`"),
        "{message}"
    );

    // A label scene whose label file is missing (the volume is a file: no
    // built-in labels): said once, as the scene's `labels =`.
    let scene = dir.path().join("missing-labels.toml");
    std::fs::write(
        &scene,
        "labels = \"nowhere.labels.vol\"\n[[object]]\nid = 1\ntf = \"shapes\"\nmode = \"dvr\"\n",
    )
    .unwrap();
    v.ui().invoke_load_scene(scene.display().to_string().into());
    wait_until(&v, |v| v.ui().get_message_is_error());
    let message = v.ui().get_message().to_string();
    assert!(
        message
            .starts_with("the scene's label volume (its `labels =`, read beside the scene file): ")
            && message.matches("nowhere.labels.vol").count() == 1,
        "{message}"
    );
    // What stays is the view: the volume was not what failed.
    assert!(
        message.ends_with("(the scene was not loaded; the view stays)"),
        "{message}"
    );

    // A session whose fixed level is past the volume's coarsest opens, and
    // the message says which level shows (as `raycaster render` warns).
    let deep = dir.path().join("deep.toml");
    v.ui()
        .invoke_save_session(deep.display().to_string().into());
    let text = std::fs::read_to_string(&deep).unwrap();
    assert!(text.contains("level = \"auto\""), "{text}");
    // (A fixed level takes no automatic level's bias.)
    let fixed: Vec<&str> = text
        .lines()
        .filter(|l| !l.starts_with("lod_bias"))
        .collect();
    let fixed = fixed.join("\n").replace("level = \"auto\"", "level = 99");
    std::fs::write(&deep, fixed).unwrap();
    v.ui()
        .invoke_open_session(deep.display().to_string().into());
    wait_until(&v, |v| v.ui().get_message().contains("deep.toml"));
    let message = v.ui().get_message().to_string();
    assert!(
        message.contains("its level 99 is past the volume's coarsest, 0: showing level 0")
            && !v.ui().get_message_is_error(),
        "{message}"
    );

    // A session whose step no frame can take: the viewer says so when the
    // full-quality frame fails, and refuses a screenshot of the coarse
    // preview still on screen (before: "saved", over the error).
    let tiny = dir.path().join("tiny.toml");
    let text = std::fs::read_to_string(&deep).unwrap();
    let text: Vec<String> = text
        .lines()
        .map(|l| {
            if l.starts_with("step = ") {
                "step = 1e-30".to_string()
            } else {
                l.replace("level = 99", "level = \"auto\"")
            }
        })
        .collect();
    std::fs::write(&tiny, text.join("\n")).unwrap();
    // Opened, its full-quality frame fails.
    let open_tiny = || {
        v.ui()
            .invoke_open_session(tiny.display().to_string().into());
        wait_until(&v, |v| v.ui().get_message().contains("tiny.toml"));
        i_slint_backend_testing::mock_elapsed_time(Duration::from_millis(300));
        slint::platform::update_timers_and_animations();
        wait_until(&v, |v| v.ui().get_message().contains("cannot render"));
    };
    open_tiny();
    let refused = dir.path().join("refused.png");
    v.ui()
        .invoke_save_screenshot(refused.display().to_string().into());
    let message = v.ui().get_message().to_string();
    assert!(
        message.contains("refused.png: the view's frame did not render")
            && v.ui().get_message_is_error(),
        "{message}"
    );
    assert!(!refused.exists());
    // Another step preset: the frame renders, and the message that said it
    // could not goes with it (before: it stayed, red, over a good picture).
    open_tiny();
    let other = if v.ui().get_step_index() == 0 { 1 } else { 0 };
    v.ui().set_step_index(other);
    v.ui().invoke_settings_changed();
    wait_until(&v, |v| v.ui().get_message().is_empty());
    assert!(!v.ui().get_message_is_error());
    // A step longer than the volume: warned of, as `raycaster render` does.
    let huge = dir.path().join("huge.toml");
    let text = std::fs::read_to_string(&tiny).unwrap();
    std::fs::write(&huge, text.replace("step = 1e-30", "step = 1e30")).unwrap();
    v.ui()
        .invoke_open_session(huge.display().to_string().into());
    wait_until(&v, |v| v.ui().get_message().contains("huge.toml"));
    let message = v.ui().get_message().to_string();
    assert!(
        message.contains("(a step of 1e30 is longer than the volume's diagonal"),
        "{message}"
    );

    // A file with a resolution pyramid: the first picture samples the coarsest
    // level at once, the resting view refines to full resolution (close enough
    // that a voxel covers a pixel), and the status line names the level.
    let big = dir.path().join("pyramid.vol");
    generate_file(&big, SceneKind::Shapes, 160);
    v.ui().invoke_open_file(big.display().to_string().into());
    wait_until(&v, |v| v.volume_name() == big.display().to_string());
    let (first, moving) = v.last_stats().unwrap_or_else(|| {
        panic!(
            "no stats: {:?} {:?}",
            v.ui().get_message(),
            v.ui().get_status()
        )
    });
    assert_eq!(first.level, 2, "the coarsest of levels 0..=2 first");
    assert!(moving, "the first picture refines when the view rests");
    assert!(
        v.ui().get_status().contains("level 2"),
        "{}",
        v.ui().get_status()
    );
    // The interactive frame's size follows the machine's load: a share of it.
    let shown = frame(&v);
    assert!(
        lit(&shown.2) * 20 > shown.2.len(),
        "the coarse picture shows the scene: {} lit of {}x{}, {first:?}",
        lit(&shown.2),
        shown.0,
        shown.1
    );
    i_slint_backend_testing::mock_elapsed_time(Duration::from_millis(300));
    slint::platform::update_timers_and_animations();
    wait_for_frame(&v);
    let (refined, moving) = v.last_stats().unwrap();
    assert!(!moving);
    assert_eq!(refined.level, 0, "{}", v.ui().get_status());
    // Level 0 near the camera; a deep view samples the far depths coarser.
    let status = v.ui().get_status().to_string();
    let named = match refined.coarsest_level {
        0 => "level 0".to_string(),
        k => format!("levels 0–{k} by depth"),
    };
    assert!(status.contains(&named), "{status}");
    // No save writes over the volume on screen, pressed twice or not (as
    // `raycaster render` refuses an image onto its inputs; before, a second
    // press of Save PNG replaced the volume).
    let volume_bytes = std::fs::read(&big).unwrap();
    let as_png = dir.path().join("pyramid.png");
    std::fs::rename(&big, &as_png).unwrap();
    v.ui().invoke_open_file(as_png.display().to_string().into());
    wait_until(&v, |v| v.volume_name() == as_png.display().to_string());
    let target: slint::SharedString = as_png.display().to_string().into();
    for _ in 0..2 {
        v.ui().invoke_save_screenshot(target.clone());
    }
    v.ui().invoke_save_session(target.clone());
    v.ui().invoke_save_scene(target);
    let message = v.ui().get_message().to_string();
    assert!(
        message.contains("pyramid.png: the view is read from it; name another file")
            && v.ui().get_message_is_error(),
        "{message}"
    );
    // The path once: the typed name is the volume's own.
    assert_eq!(message.matches("pyramid.png").count(), 1, "{message}");
    assert!(std::fs::read(&as_png).unwrap() == volume_bytes);

    // Started on a file that does not open, with a scene: the file's error is
    // said once, and stays in sight after the scene's message.
    let scene =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../volumes/scenes/shapes-layers10.toml");
    let missing = dir.path().join("missing.vol");
    let w = Viewer::new(Source::File(missing.clone()), Some(scene)).unwrap();
    let message = w.ui().get_message().to_string();
    assert!(w.ui().get_message_is_error(), "{message}");
    assert_eq!(message.matches("missing.vol").count(), 1, "{message}");
    assert!(
        message.contains("(showing the built-in scene) — loaded scene"),
        "{message}"
    );

    // A scene whose object's id the labels never hold: said with the scene,
    // as the CLI warns (the picture was empty without a word).
    let ghost = dir.path().join("ghost.toml");
    std::fs::write(
        &ghost,
        "labels = \"unused.labels.vol\"\n[[object]]\nid = 9\nname = \"ghost\"\n",
    )
    .unwrap();
    let g = Viewer::new(Source::BuiltIn(SceneKind::Shells, 32), Some(ghost)).unwrap();
    let message = g.ui().get_message().to_string();
    assert!(
        message.contains("loaded scene")
            && message.contains("warning: object \"ghost\" (id 9) shows nothing"),
        "{message}"
    );

    // Started on a session whose label volume has another size: the window
    // opens with the error over the built-in scene, as for a session that does
    // not read (before: the viewer exited at start).
    let labels = dir.path().join("small.labels.vol");
    let header = raycaster::volume::Header::new(
        [8; 3],
        [1.0; 3],
        raycaster::volume::Layout::Linear,
        raycaster::volume::SampleType::U8,
        raycaster::volume::Content::Labels,
        raycaster::volume::Format::Extended,
    );
    let mut bytes = header.encode().unwrap();
    bytes.extend([1u8; 512]);
    std::fs::write(&labels, bytes).unwrap();
    let text = std::fs::read_to_string(&deep).unwrap();
    let text = text.replacen(
        "[volume]\n",
        &format!("[volume]\nlabels = {:?}\n", labels.display().to_string()),
        1,
    );
    assert!(text.contains("small.labels.vol"), "{text}");
    // Without a label scene the label volume has no use: said.
    assert!(!text.contains("[scene]"), "{text}");
    let sceneless = dir.path().join("sceneless.toml");
    std::fs::write(&sceneless, &text).unwrap();
    let w = Viewer::new(Source::Session(sceneless), None).unwrap();
    let message = w.ui().get_message().to_string();
    assert!(w.ui().get_message_is_error(), "{message}");
    assert!(
        message.contains("`volume.labels`: a label volume gives a two-level label scene its objects, and there is no scene (showing the built-in scene)"),
        "{message}"
    );
    drop(w);
    let text = text
        + "\n[scene]\nlabels = \"small.labels.vol\"\n[[scene.object]]\nid = 1\ntf = \"shapes\"\nmode = \"dvr\"\n";
    let mislabelled = dir.path().join("mislabelled.toml");
    std::fs::write(&mislabelled, text).unwrap();
    let w = Viewer::new(Source::Session(mislabelled), None).unwrap();
    let message = w.ui().get_message().to_string();
    assert!(w.ui().get_message_is_error(), "{message}");
    assert!(
        message.contains("small.labels.vol: dimensions [8, 8, 8] differ from the data's")
            && message.contains("(showing the built-in scene)"),
        "{message}"
    );
}
