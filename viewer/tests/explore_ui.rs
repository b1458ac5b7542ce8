//! Exploring a volume, driven headless: the Cut panel (crop sliders and the
//! clipping plane) changes the picture and the settings sent to the renderer,
//! a session saved after cutting restores the sliders; keyboard shortcuts reset
//! the view, show axis views and save screenshots; the slice views follow the
//! crosshair; recent files are remembered and reopened.
//!
//! One test function: the platform can be set once per process.

use std::path::PathBuf;
use std::time::{Duration, Instant};

mod support;
use support::{element, generate_file, mode_index, settle};

use i_slint_backend_testing::ElementHandle;
use raycaster::render::{CropBox, Vec3};
use raycaster::session::Session;
use raycaster::slice::{Axis, Slice};
use raycaster::synth::SceneKind;
use raycaster::volume::Volume;
use slint::platform::{Key, PointerEventButton, WindowEvent};
use slint::{ComponentHandle, Model};
use viewer::{Source, Viewer};

/// Pumps until `done` holds, then until the newest frame is on screen.
fn wait_until(v: &Viewer, what: &str, done: impl Fn(&Viewer) -> bool) {
    let start = Instant::now();
    while !done(v) {
        v.pump();
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "{what}: {:?}",
            v.ui().get_message()
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    settle(v);
}

/// The RGBA bytes of an image.
fn pixels(image: &slint::Image) -> (u32, u32, Vec<u8>) {
    let buffer = image.to_rgba8().expect("a pixel image");
    (buffer.width(), buffer.height(), buffer.as_bytes().to_vec())
}

fn frame(v: &Viewer) -> Vec<u8> {
    pixels(&v.ui().get_frame()).2
}

/// The scale bar is a fraction of the frame's width as shown: a frame of
/// another aspect than the canvas (a session's first frame) is fitted into it,
/// narrower, and the bar with it (it measured the canvas: "100 mm" over 200).
fn scale_bar_measures_the_frame_shown(v: &Viewer) {
    let ui = v.ui();
    let canvas = element(v, "App::canvas").size();
    let (frame, fraction) = (ui.get_frame(), ui.get_scale_fraction());
    let bar = || element(v, "App::scale-bar").size().width;
    let shown = frame.size();
    let fitted = canvas
        .width
        .min(canvas.height * shown.width as f32 / shown.height as f32);
    assert!((bar() - fitted * fraction).abs() < 1.0, "{} px", bar());
    // A frame twice as wide as high, in a canvas less wide than that: as wide
    // as the canvas. One as high as wide: as wide as the canvas is high.
    assert!(canvas.width < 2.0 * canvas.height && canvas.width > canvas.height);
    for (w, h, width) in [(200, 100, canvas.width), (100, 100, canvas.height)] {
        let buffer = slint::SharedPixelBuffer::<slint::Rgba8Pixel>::new(w, h);
        ui.set_frame(slint::Image::from_rgba8(buffer));
        ui.set_scale_fraction(0.25);
        assert!((bar() - 0.25 * width).abs() < 1.0, "{w}×{h}: {} px", bar());
    }
    // On a dark plate that holds the bar and its label (they vanished over
    // bright skin).
    let plate = element(v, "App::scale-plate");
    let bar = element(v, "App::scale-bar");
    let (p, b) = (plate.absolute_position(), bar.absolute_position());
    assert!(p.x < b.x && p.y < b.y, "{p:?} {b:?}");
    assert!(
        p.x + plate.size().width > b.x + bar.size().width
            && p.y + plate.size().height > b.y + bar.size().height
    );
    ui.set_frame(frame);
    ui.set_scale_fraction(fraction);
}

/// The centred crosshair's lines run through the slice views' side letters
/// (centred on the edges): each letter sits on a plate that hides the line
/// under it, where the line showed between the glyphs' strokes.
fn edge_letters_stay_readable_over_the_crosshair(v: &Viewer) {
    let shot = v.ui().window().take_snapshot().expect("the window draws");
    let width = shot.width() as usize;
    // The lines' red, green and blue (the slices are grey, the letters
    // yellow: red over green over blue, blended with their dark plate).
    let line = |x: usize, y: usize| {
        let p = &shot.as_bytes()[(y * width + x) * 4..][..3];
        let [r, g, b] = [p[0], p[1], p[2]].map(i32::from);
        g > r + 40 || b > r + 40 || (r > g + 100 && (g - b).abs() < 30)
    };
    let mut crossed = 0;
    for label in ElementHandle::find_by_element_type_name(v.ui(), "EdgeLabel") {
        let (at, size) = (label.absolute_position(), label.size());
        if size.width < 1.0 || at.x < 0.0 {
            continue;
        }
        let (x0, y0) = (at.x.round() as usize, at.y.round() as usize);
        let (x1, y1) = (x0 + size.width as usize, y0 + size.height as usize);
        let rows = y0..y1.min(shot.height() as usize);
        let under: usize = rows
            .clone()
            .map(|y| (x0..x1.min(width)).filter(|&x| line(x, y)).count())
            .sum();
        assert_eq!(
            under, 0,
            "crosshair pixels show through the letter at {at:?}"
        );
        // Beside it, the line the letter sits on.
        let beside = [x0.saturating_sub(3), x1 + 2];
        if rows
            .clone()
            .any(|y| beside.iter().any(|&x| x < width && line(x, y)))
        {
            crossed += 1;
        }
    }
    assert!(
        crossed >= 2,
        "{crossed} letters lie on the crosshair's lines"
    );
}

/// Presses and releases a key with the given text.
fn key(v: &Viewer, text: &str) {
    let window = v.ui().window();
    window.dispatch_event(WindowEvent::KeyPressed { text: text.into() });
    window.dispatch_event(WindowEvent::KeyReleased { text: text.into() });
}

fn crop_of(v: &Viewer) -> Option<CropBox> {
    v.session().unwrap().settings.clip.crop
}

#[test]
fn the_viewer_cuts_slices_and_remembers_files() {
    support::headless_platform();
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("config");
    support::private_config(&config);
    let file_a = dir.path().join("shapes.vol");
    generate_file(&file_a, SceneKind::Shapes, 48);
    let file_b = dir.path().join("shells.vol");
    generate_file(&file_b, SceneKind::Shells, 40);

    let v = support::shown_viewer(Source::File(file_a.clone()), 1000.0, 820.0);
    settle(&v);
    // The laid-out canvas: a full-quality frame of its size.
    v.ui().invoke_reset_view();
    settle(&v);
    let home = v.orbit();
    let whole = frame(&v);
    assert_eq!(crop_of(&v), None, "no cut at first");
    assert_eq!(
        (v.ui().get_dim_x(), v.ui().get_dim_y(), v.ui().get_dim_z()),
        (48, 48, 48)
    );

    // 0. A box's pick hands the keys back to the canvas: the wheel over the
    // box then scrolls the panel instead of changing its value (a mode picked,
    // then the panel scrolled, changed the mode unseen). The preset box (the
    // search finds the panel's later boxes not).
    let preset_box = element(&v, "App::preset-box");
    let preset = v.ui().get_preset_index();
    preset_box.mock_single_click(PointerEventButton::Left);
    let (escape, down): (slint::SharedString, slint::SharedString) =
        (Key::Escape.into(), Key::DownArrow.into());
    key(&v, &escape);
    key(&v, &down);
    assert_eq!(
        v.ui().get_preset_index(),
        preset + 1,
        "the arrow key picked the next preset"
    );
    // (The event loop's next turn: timers due now run.)
    slint::platform::update_timers_and_animations();
    for delta in [-120.0, 120.0, 120.0] {
        preset_box.scroll(0.0, delta);
    }
    assert_eq!(
        v.ui().get_preset_index(),
        preset + 1,
        "the wheel left the preset alone"
    );
    // Picked with the mouse from the open list: closing it gave the box the
    // focus back, and the first wheel step changed the value.
    preset_box.mock_single_click(PointerEventButton::Left);
    let names = v.ui().get_tf_presets();
    let wanted = names.row_data(preset as usize + 2).unwrap();
    let item = ElementHandle::find_by_accessible_label(v.ui(), &wanted)
        .find(|e| e.accessible_label().as_deref() == Some(wanted.as_str()))
        .unwrap_or_else(|| panic!("no list item {wanted}"));
    item.mock_single_click(PointerEventButton::Left);
    slint::platform::update_timers_and_animations();
    assert_eq!(
        v.ui().get_preset_index(),
        preset + 2,
        "picked from the list"
    );
    preset_box.scroll(0.0, -120.0);
    assert_eq!(
        v.ui().get_preset_index(),
        preset + 2,
        "the wheel after a pick from the list left the preset alone"
    );
    v.ui().set_preset_index(preset);
    v.ui().invoke_preset_selected(preset);
    settle(&v);
    // The Threads count: the wheel over it scrolls the panel too (Slint's
    // spin box took it under the pointer and changed the count unseen); its
    // buttons step the count within range.
    // (A tall window: the element search passes over what the panel's
    // scroll area has outside the window.)
    let window = v.ui().window();
    window.set_size(slint::LogicalSize::new(1000.0, 2400.0));
    v.pump();
    let threads = v.ui().get_threads();
    v.ui().set_threads(1);
    let threads_box = element(&v, "App::threads-box");
    for delta in [120.0, 120.0, -120.0, 120.0] {
        threads_box.scroll(0.0, delta);
    }
    assert_eq!(
        v.ui().get_threads(),
        1,
        "the wheel left the thread count alone"
    );
    let button = |label: &str| {
        ElementHandle::find_by_accessible_label(v.ui(), label)
            .next()
            .unwrap_or_else(|| panic!("no button {label}"))
    };
    button("more").mock_single_click(PointerEventButton::Left);
    assert_eq!(v.ui().get_threads(), 2, "+ adds a thread");
    button("fewer").mock_single_click(PointerEventButton::Left);
    button("fewer").mock_single_click(PointerEventButton::Left);
    assert_eq!(v.ui().get_threads(), 1, "− stops at one thread");
    v.ui().set_threads(threads);
    window.set_size(slint::LogicalSize::new(1000.0, 820.0));
    v.pump();
    v.ui().invoke_canvas_resized();
    settle(&v);
    assert_eq!(frame(&v), whole);

    // 1. Crop: the upper x bound at half keeps voxels 0..=24 of 0..=47.
    v.ui().set_crop_x1(0.5);
    v.ui().invoke_cut_changed(false);
    settle(&v);
    assert_eq!(
        crop_of(&v),
        Some(CropBox {
            lo: Vec3::ZERO,
            hi: Vec3::new(24.0, 47.0, 47.0)
        })
    );
    let cropped = frame(&v);
    assert_ne!(cropped, whole, "the crop changes the picture");
    // Each row's label says the voxels kept, as the crop box has them.
    let labels: Vec<String> = ElementHandle::find_by_element_id(v.ui(), "CropRow::label")
        .map(|e| e.accessible_label().unwrap_or_default().to_string())
        .collect();
    assert_eq!(labels[0], "x 0 .. 24 of 0 .. 47 voxels", "{labels:?}");
    // Both z sliders at the top keep the last voxel's slab, 46 .. 47, and
    // say so (the label said 47 .. 47).
    v.ui().set_crop_z0(1.0);
    v.ui().invoke_cut_changed(false);
    settle(&v);
    let z = ElementHandle::find_by_element_id(v.ui(), "CropRow::label")
        .nth(2)
        .and_then(|e| e.accessible_label())
        .unwrap_or_default();
    assert_eq!(z, "z 46 .. 47 of 0 .. 47 voxels");
    assert_eq!(crop_of(&v).map(|c| (c.lo.z, c.hi.z)), Some((46.0, 47.0)));
    v.ui().set_crop_z0(0.0);
    v.ui().invoke_cut_changed(false);
    settle(&v);
    assert_eq!(frame(&v), cropped, "the z sliders back: the same picture");

    // The clipping plane: enabled, moved and turned with its sliders.
    v.ui().set_plane_enabled(true);
    v.ui().set_plane_offset(-0.1);
    v.ui().set_plane_azimuth(90.0);
    v.ui().set_plane_elevation(30.0);
    v.ui().invoke_cut_changed(false);
    settle(&v);
    let clip = v.session().unwrap().settings.clip;
    assert_eq!(clip.planes.len(), 1);
    let n = clip.planes[0].normal;
    let (a, e) = (90f32.to_radians(), 30f32.to_radians());
    let expected = Vec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin());
    assert!((n - expected).length() < 1e-5, "normal {n}");
    let along = (clip.planes[0].point - Vec3::splat(23.5)).dot(n);
    let half = Vec3::splat(47.0).length() / 2.0;
    assert!((along + 0.1 * half).abs() < 1e-3, "offset {along}");
    assert!(v.ui().get_plane_info().contains("normal"));
    assert!(!v.ui().get_plane_info().contains("keeps nothing"));
    // Moved past the volume, the plane keeps nothing, and says so.
    v.ui().set_plane_offset(1.0);
    v.ui().invoke_cut_changed(false);
    settle(&v);
    assert!(
        v.ui()
            .get_plane_info()
            .contains("it keeps nothing of the volume"),
        "{}",
        v.ui().get_plane_info()
    );
    v.ui().set_plane_offset(-0.1);
    v.ui().invoke_cut_changed(false);
    settle(&v);
    assert!(!v.ui().get_plane_info().contains("keeps nothing"));
    let cut = frame(&v);
    assert_ne!(cut, cropped, "the plane cuts more away");

    // A session saved after cutting holds the cut; uncutting restores the
    // whole picture; opening the session brings the sliders and picture back.
    let session_path = dir.path().join("cut.toml");
    v.ui()
        .set_session_path(session_path.display().to_string().into());
    element(&v, "App::session-save").invoke_accessible_default_action();
    let saved = Session::load(&session_path).unwrap();
    assert_eq!(saved.settings.clip, clip);
    element(&v, "App::cut-reset").invoke_accessible_default_action();
    settle(&v);
    assert!(v.session().unwrap().settings.clip.is_empty());
    assert!(!v.ui().get_plane_enabled());
    assert_eq!(v.ui().get_crop_x1(), 1.0);
    assert!(frame(&v) == whole, "uncut: the whole volume again");
    element(&v, "App::session-open").invoke_accessible_default_action();
    wait_until(&v, "session restored", |v| v.ui().get_crop_x1() < 1.0);
    assert!(!v.ui().get_message_is_error(), "{:?}", v.ui().get_message());
    assert!((v.ui().get_crop_x1() - 24.0 / 47.0).abs() < 1e-6);
    assert!(v.ui().get_plane_enabled());
    assert!((v.ui().get_plane_azimuth() - 90.0).abs() < 1e-3);
    assert!((v.ui().get_plane_elevation() - 30.0).abs() < 1e-3);
    assert!((v.ui().get_plane_offset() + 0.1).abs() < 1e-4);
    assert_eq!(v.session().unwrap().settings.clip, clip, "bit for bit");
    assert!(frame(&v) == cut, "the cut picture is back");

    // 2. Keyboard shortcuts on the canvas (a click gives it the keyboard).
    element(&v, "App::canvas").mock_single_click(PointerEventButton::Left);
    settle(&v);
    key(&v, "1");
    settle(&v);
    assert_eq!((v.orbit().azimuth, v.orbit().elevation), (0.0, 0.0), "+x");
    let from_x = frame(&v);
    key(&v, "3");
    settle(&v);
    assert!(v.orbit().elevation > 1.5, "from the top");
    assert_ne!(frame(&v), from_x);
    key(&v, "Y");
    settle(&v);
    assert!((v.orbit().azimuth + std::f32::consts::FRAC_PI_2).abs() < 1e-6);
    assert_eq!(v.orbit().elevation, 0.0, "from −y");
    // The edges name the volume's axes (this file has no orientation) and a
    // scale bar measures the view in voxels (spacing 1).
    let ui = v.ui();
    let edges = [
        ui.get_label_left(),
        ui.get_label_right(),
        ui.get_label_top(),
        ui.get_label_bottom(),
    ];
    assert_eq!(edges.map(|e| e.to_string()), ["−x", "+x", "+z", "−z"]);
    assert!(
        ui.get_scale_label().ends_with(" voxels"),
        "{}",
        ui.get_scale_label()
    );
    assert!(ui.get_scale_fraction() > 0.05 && ui.get_scale_fraction() <= 0.25);
    scale_bar_measures_the_frame_shown(&v);
    // The crosshair's slice planes outlined over the picture, and gone again.
    let plain = frame(&v);
    element(&v, "App::planes-box").invoke_accessible_default_action();
    settle(&v);
    assert!(ui.get_show_planes());
    let outlined = frame(&v);
    assert_ne!(outlined, plain, "the planes are drawn");
    assert!(
        outlined.chunks(4).any(|p| p[..3] == [230, 70, 70]),
        "the x plane is outlined in red"
    );
    element(&v, "App::planes-box").invoke_accessible_default_action();
    settle(&v);
    assert!(frame(&v) == plain, "no outlines once unticked");
    // A folder as the screenshot path: numbered screenshots inside it (before:
    // `FOLDER-1.png` beside it).
    let folder = dir.path().join("shots");
    std::fs::create_dir(&folder).unwrap();
    v.ui()
        .set_screenshot_path(folder.display().to_string().into());
    key(&v, "s");
    assert!(
        folder.join("screenshot-1.png").exists(),
        "{:?}",
        v.ui().get_message()
    );
    key(&v, "r");
    settle(&v);
    assert_eq!(v.orbit(), home, "R resets the view");
    key(&v, "q");
    assert_eq!(v.orbit(), home, "other keys do nothing");
    // S saves a numbered screenshot beside the Save PNG path and says where.
    let shot = dir.path().join("shot.png");
    v.ui()
        .set_screenshot_path(shot.display().to_string().into());
    key(&v, "s");
    let first = dir.path().join("shot-1.png");
    assert!(first.exists(), "{:?}", v.ui().get_message());
    assert!(v.ui().get_message().contains(&*first.display().to_string()));
    let image = raycaster::render::RgbImage::load_png(&first).unwrap();
    assert_eq!(image.width() * image.height() * 4, frame(&v).len() as u32);
    // Ctrl+S too.
    let window = v.ui().window();
    window.dispatch_event(WindowEvent::KeyPressed {
        text: Key::Control.into(),
    });
    key(&v, "s");
    window.dispatch_event(WindowEvent::KeyReleased {
        text: Key::Control.into(),
    });
    assert!(dir.path().join("shot-2.png").exists());
    // Asked for while a new view renders, the screenshot waits for its
    // full-quality frame (before: tiles of two views, or a black tile).
    key(&v, "y");
    key(&v, "s");
    let third = dir.path().join("shot-3.png");
    assert!(!third.exists(), "saved before the frame was complete");
    assert!(
        v.ui().get_message().contains("when the frame is complete"),
        "{:?}",
        v.ui().get_message()
    );
    settle(&v);
    assert!(third.exists(), "{:?}", v.ui().get_message());
    assert!(v.ui().get_message().contains("shot-3.png"));
    let image = raycaster::render::RgbImage::load_png(&third).unwrap();
    let on_screen: Vec<u8> = frame(&v).chunks(4).flat_map(|p| p[..3].to_vec()).collect();
    assert_eq!(image.data(), &on_screen[..], "the view's finished frame");
    key(&v, "r");
    settle(&v);
    assert!(v.ui().get_help().contains("R reset"));
    // Ctrl+Z takes back a transfer-function edit (the picker names the
    // preset again), Ctrl+Y makes it again (custom), Ctrl+Z twice more takes
    // back a preset pick too.
    let control = |pressed: bool| {
        let text = Key::Control.into();
        let event = if pressed {
            WindowEvent::KeyPressed { text }
        } else {
            WindowEvent::KeyReleased { text }
        };
        v.ui().window().dispatch_event(event);
    };
    let with_control = |text: &str| {
        control(true);
        key(&v, text);
        control(false);
        settle(&v);
    };
    let (preset, unedited) = (v.ui().get_preset_index(), frame(&v));
    let other = (preset + 1) % raycaster::render::PRESETS.len() as i32;
    v.ui().set_preset_index(other);
    v.ui().invoke_preset_selected(other);
    settle(&v);
    let picked = frame(&v);
    assert!(picked != unedited, "another preset changes the picture");
    element(&v, "App::tf-area").mock_single_click(PointerEventButton::Left);
    settle(&v);
    let edited = frame(&v);
    assert!(edited != picked, "a new point changes the picture");
    let custom = raycaster::render::PRESETS.len() as i32;
    assert_eq!(v.ui().get_preset_index(), custom);
    element(&v, "App::canvas").mock_single_click(PointerEventButton::Left);
    settle(&v);
    with_control("z");
    assert!(frame(&v) == picked, "undone: the preset's picture");
    assert_eq!(v.ui().get_preset_index(), other);
    with_control("y");
    assert!(frame(&v) == edited, "redone: the edited picture");
    assert_eq!(v.ui().get_preset_index(), custom);
    with_control("z");
    with_control("z");
    assert!(frame(&v) == unedited, "the preset pick undone too");
    assert_eq!(v.ui().get_preset_index(), preset);
    with_control("z");
    assert!(frame(&v) == unedited, "nothing more to undo");
    assert!(v.ui().get_help().contains("Ctrl+Z"));
    // A click in the curve editor hands the keys to the canvas: Ctrl+Z after
    // typing a path undoes the new point (it went to the path field, and
    // emptied it).
    let field = element(&v, "App::session-field");
    field.mock_single_click(PointerEventButton::Left);
    let typed = v.ui().get_session_path();
    element(&v, "App::tf-area").mock_single_click(PointerEventButton::Left);
    settle(&v);
    assert!(frame(&v) != unedited, "a new point");
    with_control("z");
    assert!(frame(&v) == unedited, "the point undone, not the path");
    assert_eq!(v.ui().get_session_path(), typed);
    // Ctrl+Z while a point is held ends its drag as an edit and undoes it
    // alone (it undid the edit before and dropped the drag).
    let tf = element(&v, "App::tf-area");
    let (pos, size) = (tf.absolute_position(), tf.size());
    let at = slint::LogicalPosition::new(pos.x + size.width * 0.5, pos.y + size.height * 0.5);
    let window = v.ui().window();
    let mouse = |event: WindowEvent| {
        window.dispatch_event(event);
        settle(&v);
    };
    mouse(WindowEvent::PointerPressed {
        position: at,
        button: PointerEventButton::Left,
    });
    mouse(WindowEvent::PointerReleased {
        position: at,
        button: PointerEventButton::Left,
    });
    let added = frame(&v);
    assert!(added != unedited, "a point added");
    mouse(WindowEvent::PointerPressed {
        position: at,
        button: PointerEventButton::Left,
    });
    mouse(WindowEvent::PointerMoved {
        position: slint::LogicalPosition::new(at.x + 10.0, at.y + size.height * 0.3),
    });
    assert!(frame(&v) != added, "the point dragged");
    with_control("z");
    assert!(frame(&v) == added, "the drag alone undone");
    mouse(WindowEvent::PointerReleased {
        position: at,
        button: PointerEventButton::Left,
    });
    with_control("z");
    assert!(frame(&v) == unedited, "then the point");

    // 3. Slice views through the crosshair (the volume's centre at first).
    assert_eq!(v.crosshair(), [23, 23, 23]);
    assert_eq!(
        (
            v.ui().get_cross_x(),
            v.ui().get_cross_y(),
            v.ui().get_cross_z()
        ),
        (23, 23, 23)
    );
    let before = [v.ui().get_slice_x(), v.ui().get_slice_y()].map(|i| pixels(&i));
    let axial = pixels(&v.ui().get_slice_z());
    assert_eq!((axial.0, axial.1), (48, 48));
    edge_letters_stay_readable_over_the_crosshair(&v);
    // A click on the axial (z) slice, fitted into a 100×100 area: x 12, y 47 − 36.
    v.ui().invoke_slice_clicked(2, 26.0, 76.0, 100.0, 100.0);
    assert_eq!(v.crosshair(), [12, 11, 23], "x and y move, z stays");
    assert_eq!(
        (
            v.ui().get_cross_x(),
            v.ui().get_cross_y(),
            v.ui().get_cross_z()
        ),
        (12, 11, 23)
    );
    let after = [v.ui().get_slice_x(), v.ui().get_slice_y()].map(|i| pixels(&i));
    assert_ne!(after[0], before[0], "the sagittal slice moved");
    assert_ne!(after[1], before[1], "the coronal slice moved");
    // The sagittal view is slice x = 12 of the file (but for the crosshair lines).
    let volume = Volume::open(&file_a).unwrap();
    let expected = Slice::extract(&volume, Axis::X, 12)
        .unwrap()
        .to_image(Some([0.0, 255.0]))
        .unwrap();
    let shown = &after[0].2;
    let differing = expected
        .data()
        .chunks(3)
        .zip(shown.chunks(4))
        .filter(|(e, s)| e[..] != s[..3])
        .count();
    assert!(differing <= 48 + 48, "{differing} pixels differ");
    // Free window/level: a right-drag down a fifth of the axial view lowers the
    // window's centre by a fifth of the data's span; the picker says "custom".
    let info = v.ui().get_slice_window_info();
    let axial = pixels(&v.ui().get_slice_z());
    v.ui().invoke_slice_window_dragged(2, 0.0, 0.0, true);
    v.ui().invoke_slice_window_dragged(2, 0.0, 0.2, false);
    let names = v.ui().get_slice_windows();
    assert_eq!(
        v.ui().get_slice_window_index() as usize,
        names.row_count() - 1
    );
    assert!(
        names
            .row_data(names.row_count() - 1)
            .unwrap()
            .starts_with("custom")
    );
    assert_ne!(v.ui().get_slice_window_info(), info);
    assert_ne!(
        pixels(&v.ui().get_slice_z()),
        axial,
        "a brighter axial slice"
    );
    let old = Slice::extract(&volume, Axis::X, 23).unwrap();
    assert_ne!(
        old.values,
        Slice::extract(&volume, Axis::X, 12).unwrap().values
    );
    // Clicks outside the fitted image do nothing; the wheel steps a slice,
    // turned away from the user into the screen: down z in the axial view (x
    // right, y up: +z comes out), so the touchpad's steps below go up it.
    v.ui().invoke_slice_clicked(0, 1.0, 50.0, 300.0, 100.0);
    assert_eq!(v.crosshair(), [12, 11, 23]);
    v.ui().invoke_slice_scrolled(2, 60.0);
    assert_eq!(v.crosshair(), [12, 11, 22]);
    // A touchpad's small deltas add up to a step.
    v.ui().invoke_slice_scrolled(2, -20.0);
    v.ui().invoke_slice_scrolled(2, -20.0);
    assert_eq!(v.crosshair(), [12, 11, 22]);
    v.ui().invoke_slice_scrolled(2, -20.0);
    assert_eq!(v.crosshair(), [12, 11, 23]);
    // Into the screen in every view: down x in the sagittal view (y right, z
    // up), up y in the coronal one (x right, z up: +y goes in). The wheel went
    // up every index before, out of the screen in two views of three.
    v.ui().invoke_slice_scrolled(0, 60.0);
    assert_eq!(v.crosshair(), [11, 11, 23]);
    v.ui().invoke_slice_scrolled(1, 60.0);
    assert_eq!(v.crosshair(), [11, 12, 23]);
    v.ui().invoke_slice_scrolled(0, -60.0);
    v.ui().invoke_slice_scrolled(1, -60.0);
    v.ui().invoke_slice_scrolled(2, -60.0);
    assert_eq!(v.crosshair(), [12, 11, 24]);
    // A named window (lung, in the file's units) changes the grey levels.
    let lung = v
        .ui()
        .get_slice_windows()
        .iter()
        .position(|w| w == "lung")
        .unwrap() as i32;
    let z_before = pixels(&v.ui().get_slice_z());
    v.ui().set_slice_window_index(lung);
    v.ui().invoke_slice_window_selected(lung);
    assert!(
        v.ui().get_slice_window_info().contains("-1350"),
        "{}",
        v.ui().get_slice_window_info()
    );
    assert_ne!(pixels(&v.ui().get_slice_z()), z_before);
    // Zoomed 2× about the crosshair (12, 11): the axial view shows 25 × 25
    // voxels (odd, so a crosshair away from the edges sits in the middle),
    // x 0..=24 and y 0..=24 (rows 23..48); a click maps through the zoom.
    v.ui().set_slice_zoom(2.0);
    v.ui().invoke_slice_zoom_changed();
    let zoomed = pixels(&v.ui().get_slice_z());
    assert_eq!((zoomed.0, zoomed.1), (25, 25));
    v.ui().invoke_slice_clicked(2, 10.0, 90.0, 100.0, 100.0);
    assert_eq!(v.crosshair(), [2, 2, 24]);
    v.ui().set_slice_zoom(1.0);
    v.ui().invoke_slice_zoom_changed();
    assert_eq!(pixels(&v.ui().get_slice_z()).0, 48);
    // A pointer drag across the axial view moves the crosshair all the way.
    // (Under X11 the drag stopped after its first step while the views were
    // repeated over a model of their images, rebuilt as the slices changed;
    // the testing backend keeps the grab, so this checks the drag itself;
    // the rebuild was checked under Xvfb with xdotool.)
    let axial =
        i_slint_backend_testing::ElementHandle::find_by_element_id(v.ui(), "App::slice-view")
            .nth(2)
            .expect("the axial view");
    let (at, size) = (axial.absolute_position(), axial.size());
    let before = v.crosshair();
    // Step by step, the window drawn between steps as on screen (the slice
    // images change under the pointer).
    let window = v.ui().window();
    let point =
        |f: f32| slint::LogicalPosition::new(at.x + size.width * f, at.y + size.height / 2.0);
    window.dispatch_event(WindowEvent::PointerMoved {
        position: point(0.5),
    });
    window.dispatch_event(WindowEvent::PointerPressed {
        position: point(0.5),
        button: PointerEventButton::Left,
    });
    for step in 1..=9 {
        window.dispatch_event(WindowEvent::PointerMoved {
            position: point(0.5 + 0.05 * step as f32),
        });
        v.pump();
        window.take_snapshot().expect("the window draws");
    }
    window.dispatch_event(WindowEvent::PointerReleased {
        position: point(0.95),
        button: PointerEventButton::Left,
    });
    let after = v.crosshair();
    assert!(
        after[0] >= before[0] + 8 && after[2] == before[2],
        "{before:?} → {after:?}"
    );

    // An average frame of this mostly empty volume is dark: the message line
    // says where the rays' means lie (it showed a dark picture without a word,
    // where `raycaster render` warned), once, and not in other modes.
    v.ui()
        .set_mode_index(mode_index(raycaster::render::Mode::Average));
    v.ui().invoke_settings_changed();
    settle(&v);
    let said = v.ui().get_message().to_string();
    assert!(
        said.starts_with("average: the picture is dark — the rays' means lie in 0 .. ")
            && said.contains("of the transfer function's range 0 .. 255"),
        "{said}"
    );
    v.ui().set_mode_index(0);
    v.ui().invoke_settings_changed();
    settle(&v);
    // (It stayed through every later mode.)
    let said = v.ui().get_message().to_string();
    assert!(!said.contains("picture is dark"), "{said}");

    // 4. Recent files: the file and the session opened so far, newest first.
    let recent_file = config.join("raycaster/recent");
    let listed = std::fs::read_to_string(&recent_file).unwrap();
    assert_eq!(
        listed.lines().collect::<Vec<_>>(),
        [
            session_path.display().to_string(),
            file_a.display().to_string()
        ]
    );
    // A dragged window belongs to its volume: another volume opens fitted.
    v.ui().invoke_slice_window_dragged(2, 0.0, 0.0, true);
    v.ui().invoke_slice_window_dragged(2, 0.0, 0.2, false);
    let custom = v.ui().get_slice_windows().row_count() as i32 - 1;
    assert_eq!(v.ui().get_slice_window_index(), custom);
    // Typed with quotes and spaces around it, as pasted from a file manager,
    // on zoomed slice views.
    v.ui().set_slice_zoom(3.0);
    let repaints = v.ui().get_repaints();
    v.ui()
        .invoke_open_file(format!(" '{}' ", file_b.display()).into());
    wait_until(&v, "file b", |v| {
        v.volume_name() == file_b.display().to_string()
    });
    // The whole window is made dirty for the new volume (the software
    // renderer's partial repaint left text of the volume before on screen).
    wait_until(&v, "whole-window repaints", |v| {
        v.ui().get_repaints() >= repaints + 2
    });
    assert_eq!(v.ui().get_slice_window_index(), 0, "fitted");
    // The new volume's slices start whole, and the path field names it as
    // opened (it kept the text typed).
    assert_eq!(v.ui().get_slice_zoom(), 1.0);
    assert_eq!(v.ui().get_file_path(), file_b.display().to_string());
    assert_eq!(
        v.recent_files(),
        [file_b.clone(), session_path.clone(), file_a.clone()]
    );
    let menu: Vec<String> = v
        .ui()
        .get_recent_files()
        .iter()
        .map(|s| s.to_string())
        .collect();
    assert_eq!(menu[0], "recent files (3)");
    assert_eq!(menu[3], file_a.display().to_string());
    // A new volume comes uncut, its crosshair at its centre.
    assert_eq!(crop_of(&v), None);
    assert_eq!(v.crosshair(), [19, 19, 19]);
    // A named CT window goes too where the next volume's values are no
    // Hounsfield units (it carried over unsaid, washing slices out).
    v.ui().set_slice_window_index(lung);
    v.ui().invoke_slice_window_selected(lung);
    // Picking the oldest entry reopens it; a file gone since is skipped.
    std::fs::remove_file(&file_b).unwrap();
    v.ui().invoke_recent_selected(3);
    wait_until(&v, "file a again", |v| {
        v.volume_name() == file_a.display().to_string()
    });
    assert_eq!(v.ui().get_slice_window_index(), 0, "fitted, not lung");
    assert_eq!(v.ui().get_recent_index(), 0);
    assert_eq!(v.recent_files(), [file_a.clone(), session_path.clone()]);
    let listed: Vec<PathBuf> = std::fs::read_to_string(&recent_file)
        .unwrap()
        .lines()
        .map(PathBuf::from)
        .collect();
    assert_eq!(listed, [file_a.clone(), session_path]);

    // Another program truncates the open file: frames and slices refuse to
    // read it (a read of a missing byte would end the viewer), saying why,
    // and the viewer goes on.
    let whole = std::fs::metadata(&file_a).unwrap().len();
    let cut = std::fs::OpenOptions::new()
        .write(true)
        .open(&file_a)
        .unwrap();
    cut.set_len(whole / 2).unwrap();
    let said = format!(
        "{}: shrank to {} bytes while open (it held {whole})",
        file_a.display(),
        whole / 2
    );
    v.ui().invoke_settings_changed();
    let start = Instant::now();
    while !v
        .ui()
        .get_message()
        .starts_with(&format!("cannot render: {said}"))
    {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "{}",
            v.ui().get_message()
        );
        v.pump();
        std::thread::sleep(Duration::from_millis(5));
    }
    v.ui().invoke_slice_zoom_changed();
    v.pump();
    assert!(
        v.ui().get_message().contains(&format!("slices: {said}")),
        "{}",
        v.ui().get_message()
    );
}
