//! Sessions driven headless: the viewer's camera, transfer function, mode and
//! scene are changed through the UI, saved with "Save session", rendered by the
//! library as `raycaster render --session` does, and restored into a fresh
//! viewer — each time pixel for pixel.
//!
//! One test function: the platform can be set once per process.

use std::path::Path;
use std::time::{Duration, Instant};

mod support;
use support::{element, mode_index, settle};

use raycaster::render::{Mode, PRESETS, RenderVolume, RgbImage, render_sequential_levels};
use raycaster::session::Session;
use raycaster::synth::SceneKind;
use slint::platform::PointerEventButton;
use slint::{LogicalPosition, Model};
use viewer::{Source, Viewer};

/// The canvas image as RGB bytes, with its size.
fn frame(v: &Viewer) -> (u32, u32, Vec<u8>) {
    let image = v.ui().get_frame();
    let buffer = image.to_rgba8().expect("the canvas holds a pixel image");
    let pixels = buffer
        .as_bytes()
        .chunks(4)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect();
    (buffer.width(), buffer.height(), pixels)
}

/// A viewer on `source` in a window of the test's size, its first frame settled.
fn viewer(source: Source) -> Viewer {
    // The laid-out canvas: a frame of its size.
    let v = support::shown_viewer(source, 900.0, 640.0);
    settle(&v);
    v
}

/// Renders a session as `raycaster render --session` does: its volume opened
/// through the library's façade, its levels chosen for its camera (one per band
/// of depths), labels of the same level attached.
fn render_like_the_cli(session: &Session) -> RgbImage {
    let opened = raycaster::source::open(&session.source).unwrap();
    let camera = session.camera().unwrap();
    let labels = opened
        .labels
        .as_ref()
        .filter(|_| session.settings.segments.is_some());
    let levels = labels.map_or(opened.volume.level_count(), |l| {
        l.level_count().min(opened.volume.level_count())
    });
    let bands = session
        .level
        .frame_bands(&opened.volume, &camera, &session.settings, levels);
    let prepared: Vec<RenderVolume<'_>> = bands
        .iter()
        .map(|band| {
            let level = RenderVolume::new(opened.volume.level(band.level), None).unwrap();
            match labels {
                Some(labels) => level.with_labels(labels.level(band.level)).unwrap(),
                None => level,
            }
        })
        .collect();
    let passes: Vec<_> = prepared
        .iter()
        .zip(&bands)
        .map(|(v, b)| (v, b.depth))
        .collect();
    render_sequential_levels(&passes, &camera, &session.settings)
        .unwrap()
        .to_image()
}

fn save_session(v: &Viewer, path: &Path) {
    v.ui().set_session_path(path.display().to_string().into());
    element(v, "App::session-save").invoke_accessible_default_action();
    let message = v.ui().get_message().to_string();
    assert!(
        !v.ui().get_message_is_error() && message.contains("saved session"),
        "{message}"
    );
}

fn lit(pixels: &[u8]) -> usize {
    pixels
        .chunks(3)
        .filter(|p| p.iter().any(|&c| c > 8))
        .count()
}

#[test]
fn sessions_save_render_and_restore_the_picture() {
    support::headless_platform();
    let dir = tempfile::tempdir().unwrap();
    support::private_config(dir.path());

    // 1. Change the camera, transfer function, mode and settings through the UI.
    let v = viewer(Source::BuiltIn(SceneKind::Shapes, 48));
    let (_, _, start) = frame(&v);
    let canvas = element(&v, "App::canvas");
    let c = canvas.absolute_position();
    let size = canvas.size();
    let centre = LogicalPosition::new(c.x + size.width / 2.0, c.y + size.height / 2.0);
    canvas.mock_drag(
        LogicalPosition::new(centre.x + 90.0, centre.y - 40.0),
        PointerEventButton::Left,
    );
    canvas.scroll(0.0, 120.0);
    settle(&v);
    let rainbow = PRESETS.iter().position(|(n, _)| *n == "rainbow").unwrap() as i32;
    v.ui().set_preset_index(rainbow);
    v.ui().invoke_preset_selected(rainbow);
    // A click adds a control point: a transfer function no preset has.
    element(&v, "App::tf-area").mock_single_click(PointerEventButton::Left);
    settle(&v);
    let sabella = mode_index(Mode::Sabella);
    v.ui().set_mode_index(sabella);
    v.ui().set_step_index(1);
    v.ui().set_ert(false);
    v.ui().invoke_settings_changed();
    // The slice views: the crosshair moved by a click on the axial slice, a
    // window set by a right-drag, a zoom.
    let centre_voxel = v.crosshair();
    v.ui().invoke_slice_clicked(2, 20.0, 30.0, 100.0, 100.0);
    assert_ne!(v.crosshair(), centre_voxel, "the click moved the crosshair");
    v.ui().invoke_slice_window_dragged(2, 0.0, 0.0, true);
    v.ui().invoke_slice_window_dragged(2, 0.3, 0.1, false);
    v.ui().set_slice_zoom(2.5);
    v.ui().invoke_slice_zoom_changed();
    let crosshair = v.crosshair();
    let slice_info = v.ui().get_slice_window_info();
    let axial = v.ui().get_slice_z().to_rgba8().unwrap().as_bytes().to_vec();
    settle(&v);
    let (w, h, shown) = frame(&v);
    assert_ne!(shown, start, "the view changed");
    assert!(lit(&shown) > 500, "the scene shows");

    // 2. Save it; the session renders the viewer's frame pixel for pixel.
    let path = dir.path().join("view.toml");
    // An existing file is replaced on a second press only (Save session
    // replaced it without a word, where Save PNG asked).
    std::fs::write(&path, "# hand-edited\n").unwrap();
    v.ui().set_session_path(path.display().to_string().into());
    element(&v, "App::session-save").invoke_accessible_default_action();
    assert!(v.ui().get_message_is_error());
    assert!(
        v.ui()
            .get_message()
            .contains("exists: press Save session again to replace it"),
        "{}",
        v.ui().get_message()
    );
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "# hand-edited\n");
    save_session(&v, &path);
    let session = Session::load(&path).unwrap();
    assert_eq!(session.size, [w, h]);
    assert_eq!(session.settings.mode, Mode::Sabella);
    assert_eq!(session.settings.step, 1.5, "the coarse preset");
    assert_eq!(session.settings.early_termination, None);
    let slices = session.slices.clone().expect("the slice views are saved");
    assert_eq!(slices.crosshair, crosshair);
    assert_eq!(slices.zoom, 2.5);
    assert!(
        matches!(slices.window, raycaster::session::SliceWindow::Values(_)),
        "{:?}",
        slices.window
    );
    assert_eq!(Some(&session), v.session().as_ref());
    assert!(
        PRESETS.iter().all(|(name, _)| {
            raycaster::render::TransferFunction::preset(name)
                .unwrap()
                .points()
                != session.settings.transfer.points()
        }),
        "the edited transfer function is saved, not a preset"
    );
    let rendered = render_like_the_cli(&session);
    assert_eq!((rendered.width(), rendered.height()), (w, h));
    assert!(
        rendered.data() == shown.as_slice(),
        "the session renders the viewer's frame"
    );
    let orbit = v.orbit();
    drop(v);

    // 3. A fresh viewer restores the same state and picture.
    let v = viewer(Source::Session(path.clone()));
    assert!(!v.ui().get_message_is_error(), "{:?}", v.ui().get_message());
    assert!(
        v.ui()
            .get_message()
            .starts_with(&format!("opened session {}", path.display())),
        "said as Open session says it: {:?}",
        v.ui().get_message()
    );
    assert_eq!(v.orbit(), orbit);
    assert_eq!(v.ui().get_mode_index(), sabella);
    assert_eq!(v.ui().get_step_index(), 1);
    assert!(!v.ui().get_ert());
    assert_eq!(v.crosshair(), crosshair, "the crosshair is restored");
    assert_eq!(v.ui().get_slice_zoom(), 2.5);
    assert_eq!(v.ui().get_slice_window_info(), slice_info);
    assert!(
        v.ui().get_slice_z().to_rgba8().unwrap().as_bytes() == axial.as_slice(),
        "the restored axial slice is the saved one"
    );
    assert_eq!(v.session().as_ref(), Some(&session));
    assert!(
        frame(&v).2 == shown,
        "the restored picture is the saved one"
    );

    // 4. "Open session" in a viewer showing something else restores it too; a
    // bad session is refused with its field and the view stays.
    v.ui().invoke_reset_view();
    v.ui().set_mode_index(0);
    v.ui().invoke_settings_changed();
    settle(&v);
    assert!(frame(&v).2 != shown);
    let bad = dir.path().join("bad.toml");
    std::fs::write(
        &bad,
        std::fs::read_to_string(&path)
            .unwrap()
            .replace("mode = \"sabella\"", "mode = \"glow\""),
    )
    .unwrap();
    // Opens session `p`, which must be refused: the error shown.
    let open_refused = |p: &Path| {
        v.ui().set_message("".into());
        v.ui().set_message_is_error(false);
        v.ui().set_session_path(p.display().to_string().into());
        element(&v, "App::session-open").invoke_accessible_default_action();
        let start = Instant::now();
        while !v.ui().get_message_is_error() {
            v.pump();
            assert!(start.elapsed() < Duration::from_secs(30), "no error shown");
            std::thread::sleep(Duration::from_millis(5));
        }
        v.ui().get_message().to_string()
    };
    let message = open_refused(&bad);
    assert!(message.contains("render.mode"), "{message}");
    assert_eq!(v.ui().get_mode_index(), 0, "the view stays");
    // A scene object cropped beside the volume: refused at open, the view
    // kept (it replaced the view with a black canvas and "cannot render").
    let beside = dir.path().join("beside.toml");
    std::fs::write(
        &beside,
        std::fs::read_to_string(&path).unwrap()
            + "\n[scene]\nlayers = [[0.0, 1.0]]\n[[scene.object]]\nname = \"away\"\n\
               crop = [500.0, 0.0, 0.0, 600.0, 10.0, 10.0]\n",
    )
    .unwrap();
    let message = open_refused(&beside);
    assert!(message.contains("scene object \"away\""), "{message}");
    assert_eq!(v.ui().get_mode_index(), 0, "the view stays");
    v.ui().set_session_path(path.display().to_string().into());
    element(&v, "App::session-open").invoke_accessible_default_action();
    let start = Instant::now();
    while v.orbit() != orbit {
        v.pump();
        assert!(start.elapsed() < Duration::from_secs(60), "not restored");
        std::thread::sleep(Duration::from_millis(5));
    }
    settle(&v);
    assert!(frame(&v).2 == shown, "Open session restores the picture");

    // 5. A two-level scene with an edited object round-trips as well.
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../volumes/scenes");
    v.ui()
        .invoke_load_scene(scenes.join("shapes-npr.toml").display().to_string().into());
    settle(&v);
    let mut row = v.ui().get_objects().row_data(0).unwrap();
    row.visible = false;
    v.ui().invoke_object_changed(0, row);
    settle(&v);
    let (_, _, edited) = frame(&v);
    assert!(edited != shown, "the scene renders differently");
    // With pre-integration and ray-start jitter from the settings panel.
    v.ui().set_preintegrate(true);
    v.ui().set_jitter(true);
    v.ui().invoke_settings_changed();
    settle(&v);
    assert!(
        v.ui().get_status().contains("pre-integrated"),
        "{}",
        v.ui().get_status()
    );
    let (_, _, with_scene) = frame(&v);
    assert!(with_scene != edited, "jitter and pre-integration show");
    let scene_path = dir.path().join("scene-view.toml");
    save_session(&v, &scene_path);
    let session = Session::load(&scene_path).unwrap();
    assert!(session.settings.preintegrated && session.settings.jitter);
    let scene = session
        .settings
        .segments
        .as_ref()
        .expect("the scene is saved");
    assert!(!scene.objects[0].visible, "with its edit");
    assert!(render_like_the_cli(&session).data() == with_scene.as_slice());
    drop(v);
    let v = viewer(Source::Session(scene_path));
    assert_eq!(v.ui().get_objects().row_count(), 2);
    assert!(!v.ui().get_objects().row_data(0).unwrap().visible);
    assert!(v.ui().get_preintegrate() && v.ui().get_jitter());
    assert!(frame(&v).2 == with_scene, "the scene's picture is restored");
    drop(v);

    // 6. A session's label volume stays with a label scene: with the scene
    // cleared, Save session writes no `labels =` (which reading refuses
    // without a label scene), and the saved session opens.
    let data = dir.path().join("shells.vol");
    support::generate_file(&data, SceneKind::Shells, 24);
    let labels = dir.path().join("shells.labels.vol");
    support::generate_labels(&labels, SceneKind::Shells, 24);
    let mut labelled = session.clone();
    labelled.source = raycaster::source::VolumeSource::File {
        path: data,
        access: raycaster::volume::Access::Mapped,
    };
    labelled.labels = Some(labels);
    labelled.settings.segments = Some(
        raycaster::render::SegmentScene::parse(
            "labels = \"shells.labels.vol\"\n[[object]]\nid = 1\ntf = \"shells\"\nmode = \"dvr\"\n",
            dir.path(),
        )
        .unwrap(),
    );
    let labelled_path = dir.path().join("labelled.toml");
    std::fs::write(&labelled_path, labelled.to_toml().unwrap()).unwrap();
    let v = viewer(Source::Session(labelled_path.clone()));
    assert_eq!(v.ui().get_objects().row_count(), 1, "the label scene");
    // A session's scene has no file of its own: the Segments path field no
    // longer names another scene's file (its Save offered to replace it), and
    // Save (scene) without a name says so.
    let elsewhere = dir.path().join("elsewhere.toml");
    std::fs::write(&elsewhere, "keep me").unwrap();
    v.ui()
        .set_scene_path(elsewhere.display().to_string().into());
    v.ui()
        .invoke_open_session(labelled_path.display().to_string().into());
    settle(&v);
    assert_eq!(v.ui().get_scene_path(), "");
    v.ui().invoke_save_scene("".into());
    assert_eq!(
        v.ui().get_message(),
        "type a file name for the scene next to Save (scene)"
    );
    assert_eq!(std::fs::read_to_string(&elsewhere).unwrap(), "keep me");
    v.ui().invoke_clear_scene();
    settle(&v);
    let cleared = dir.path().join("cleared.toml");
    save_session(&v, &cleared);
    let reread = Session::load(&cleared).unwrap();
    assert_eq!((reread.labels, reread.settings.segments), (None, None));
}
