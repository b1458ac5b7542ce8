//! The file browser driven headless: "Browse…" lists the typed path's folder,
//! a folder entry shows its contents, a volume entry opens it, a session entry
//! restores it, "Up" goes back, and a folder that is no DICOM series is refused
//! with the view kept.
//!
//! One test function: the platform can be set once per process.

use std::time::{Duration, Instant};

mod support;
use support::{element, generate_file, wait_for_frame};

use raycaster::synth::SceneKind;
use slint::Model;
use viewer::{Source, Viewer};

/// The browser's entries as shown.
fn entries(v: &Viewer) -> Vec<String> {
    v.ui()
        .get_browser_entries()
        .iter()
        .map(|s| s.to_string())
        .collect()
}

/// Pumps events until `done`, at most 30 s.
fn wait_until(v: &Viewer, what: &str, done: impl Fn(&Viewer) -> bool) {
    let start = Instant::now();
    while !done(v) {
        v.pump();
        assert!(start.elapsed() < Duration::from_secs(30), "{what}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

#[test]
fn the_browser_opens_volumes_and_sessions_from_folders() {
    support::headless_platform();
    let dir = tempfile::tempdir().unwrap();
    support::private_config(&dir.path().join("config"));
    let root = dir.path().join("data");
    let scans = root.join("scans");
    std::fs::create_dir_all(&scans).unwrap();
    std::fs::create_dir(root.join("empty")).unwrap();
    generate_file(&scans.join("shells.vol"), SceneKind::Shells, 40);
    std::fs::write(scans.join("readme.txt"), "not a volume").unwrap();
    std::fs::write(root.join("other.nrrd"), "NRRD0004\n").unwrap();

    let v = support::shown_viewer(Source::BuiltIn(SceneKind::Shapes, 32), 1000.0, 820.0);
    wait_for_frame(&v);
    assert_eq!(v.ui().get_dim_x(), 32);

    // "Browse…" starts at the typed path's folder: folders first, then the
    // files the viewer opens.
    v.ui()
        .set_file_path(root.join("missing.vol").display().to_string().into());
    element(&v, "App::browse-button").invoke_accessible_default_action();
    assert!(v.ui().get_browser_shown());
    let canonical_root = std::fs::canonicalize(&root).unwrap();
    assert_eq!(
        v.ui().get_browser_folder().to_string(),
        canonical_root.display().to_string()
    );
    assert_eq!(entries(&v), ["empty/", "scans/", "other.nrrd   9 bytes"]);

    // A folder entry shows its contents (the text file is not offered).
    v.ui().invoke_browser_picked(1);
    let listed = entries(&v);
    assert_eq!(listed.len(), 1, "{listed:?}");
    assert!(listed[0].starts_with("shells.vol   "), "{listed:?}");

    // "Up" goes back; an entry picked again opens the volume.
    element(&v, "App::browser-up").invoke_accessible_default_action();
    assert_eq!(entries(&v)[1], "scans/");
    v.ui().invoke_browser_picked(1);
    v.ui().invoke_browser_picked(0);
    assert!(
        !v.ui().get_browser_shown(),
        "picking a file closes the browser"
    );
    let opened = std::fs::canonicalize(&scans)
        .unwrap()
        .join("shells.vol")
        .display()
        .to_string();
    assert_eq!(v.ui().get_file_path().to_string(), opened);
    wait_until(&v, "the picked volume opens", |v| v.ui().get_dim_x() == 40);
    wait_for_frame(&v);
    assert!(!v.ui().get_message_is_error(), "{}", v.ui().get_message());

    // A session saved beside it is offered and restores.
    let session = scans.join("view.toml");
    v.ui()
        .set_session_path(session.display().to_string().into());
    element(&v, "App::session-save").invoke_accessible_default_action();
    assert!(session.exists(), "{}", v.ui().get_message());
    v.ui().invoke_browse();
    assert_eq!(
        entries(&v).last().map(String::as_str),
        Some("view.toml   (session)")
    );
    // A scene beside it is offered as one and loads over the volume (it was
    // listed as a session, failed to restore, and the session field named it).
    let scene = scans.join("layers.toml");
    std::fs::write(
        &scene,
        "layers = [[0.1, 0.5], [0.5, 1.0]]\n[[object]]\ntf = \"shells\"\n[[object]]\ntf = \"shells\"\n",
    )
    .unwrap();
    v.ui().invoke_browse();
    v.ui().invoke_browse();
    let listed = entries(&v);
    let at = listed
        .iter()
        .position(|e| e == "layers.toml   (scene)")
        .unwrap_or_else(|| panic!("{listed:?}"));
    v.ui().invoke_browser_picked(at as i32);
    assert!(!v.ui().get_browser_shown());
    assert!(!v.ui().get_message_is_error(), "{}", v.ui().get_message());
    assert_eq!(v.ui().get_objects().row_count(), 2);
    assert!(
        v.ui().get_scene_path().ends_with("layers.toml"),
        "{}",
        v.ui().get_scene_path()
    );
    assert_eq!(
        v.ui().get_session_path().to_string(),
        session.display().to_string(),
        "the session field keeps its file"
    );
    v.ui().invoke_browse();
    v.ui().invoke_browse();
    assert!(!v.ui().get_browser_shown(), "Close hides it");

    // A folder that is no DICOM series is refused; the volume stays.
    v.ui().set_file_path(root.display().to_string().into());
    v.ui().invoke_browse();
    v.ui().invoke_browser_picked(0);
    assert!(entries(&v).is_empty(), "the empty folder");
    element(&v, "App::browser-open-folder").invoke_accessible_default_action();
    wait_until(&v, "an error for a folder without DICOM files", |v| {
        v.ui().get_message_is_error()
    });
    let message = v.ui().get_message().to_string();
    assert!(message.contains("empty"), "{message}");
    assert_eq!(v.ui().get_dim_x(), 40, "the previous volume stays");
}
