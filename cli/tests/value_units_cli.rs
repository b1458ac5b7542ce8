//! Values in the file's units: a CT scan's `--domain`, `--iso` and `--window` in
//! Hounsfield units (or named windows) give the same pictures as the stored values
//! of a file without units, and a first render without flags fits the data.

mod support;

use support::{raycaster, stderr};

use std::path::Path;

use raycaster::render::RgbImage;
use raycaster::volume::{Content, Format, Header, Layout, SampleType, ValueUnits, Volume};

const N: u32 = 40;

/// A CT phantom: a bone ball (1000 HU) in soft tissue (40 HU) in air (−1000 HU),
/// stored as HU + 32768.
struct Phantom;

impl raycaster::synth::Scene for Phantom {
    fn fill_row(&self, x: u32, y: u32, out: &mut [f32]) {
        let c = (N - 1) as f32 / 2.0;
        for (z, o) in out.iter_mut().enumerate() {
            let r =
                ((x as f32 - c).powi(2) + (y as f32 - c).powi(2) + (z as f32 - c).powi(2)).sqrt();
            let hu = if r < 8.0 {
                1000.0
            } else if r < 16.0 {
                40.0
            } else {
                -1000.0
            };
            *o = (hu + 32768.0) / 65535.0;
        }
    }
}

/// Writes the phantom to `name`, with `units` in its header or none (a file of
/// an older volgen: values are the stored samples).
fn write_phantom(dir: &Path, name: &str, units: Option<ValueUnits>) {
    let header = Header::new(
        [N; 3],
        [1.0; 3],
        Layout::Bricked { side: 16 },
        SampleType::U16,
        Content::Scalar,
        Format::Extended,
    )
    .with_units(units);
    raycaster::generate::generate(
        &Phantom,
        &header,
        &dir.join(name),
        &Default::default(),
        &raycaster::job::Job::silent(),
    )
    .unwrap();
    let v = Volume::open(dir.join(name)).unwrap();
    assert_eq!(v.voxel([20, 20, 20]), 33768, "bone stored as HU + 32768");
}

fn setup() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let hu = ValueUnits::new(1.0, -32768.0, "HU").unwrap();
    write_phantom(dir.path(), "ct.vol", Some(hu));
    write_phantom(dir.path(), "old.vol", None);
    dir
}

/// Runs `raycaster` with `args` and `-o NAME`, and loads the picture.
fn picture(dir: &Path, name: &str, args: &[&str]) -> RgbImage {
    let mut all = args.to_vec();
    all.extend(["-o", name, "--force"]);
    let out = raycaster(&all, dir);
    assert!(out.status.success(), "{args:?}: {}", stderr(&out));
    RgbImage::load_png(&dir.join(name)).unwrap()
}

fn render(dir: &Path, file: &str, extra: &[&str]) -> RgbImage {
    let mut args = vec!["render", file, "--size", "64", "--azimuth", "30"];
    args.extend(extra);
    picture(dir, "r.png", &args)
}

#[test]
fn domain_and_iso_in_hounsfield_units_equal_stored_values_and_ct_fits_by_default() {
    let dir = setup();
    let d = dir.path();
    let stored = render(
        d,
        "old.vol",
        &["--tf", "ct-bone", "--domain", "31768,34768"],
    );
    assert!(stored.data().iter().any(|&p| p > 40), "the bone ball shows");
    for extra in [
        &["--tf", "ct-bone", "--domain", "-1000,2000"][..],
        &["--tf", "ct-bone", "--domain", "ct"],
        // No flags: a CT scan opens with ct-bone over −1000..2000 HU.
        &[],
    ] {
        assert!(render(d, "ct.vol", extra) == stored, "{extra:?}");
    }
    // A named window is its HU range.
    let lung = render(d, "ct.vol", &["--tf", "grayscale", "--domain", "lung"]);
    assert!(lung == render(d, "ct.vol", &["--tf", "grayscale", "--domain", "-1350,150"]));
    assert!(lung != stored);
    // First hit at 500 HU is the middle of −1000..2000 HU.
    let iso_stored = render(
        d,
        "old.vol",
        &[
            "--mode",
            "first-hit",
            "--tf",
            "ct-bone",
            "--domain",
            "31768,34768",
        ],
    );
    for iso in ["500", "50%"] {
        let got = render(
            d,
            "ct.vol",
            &["--mode", "first-hit", "--tf", "ct-bone", "--iso", iso],
        );
        assert!(got == iso_stored, "--iso {iso}");
    }
    assert!(
        render(
            d,
            "ct.vol",
            &["--mode", "first-hit", "--tf", "ct-bone", "--iso", "-200"]
        ) != iso_stored
    );
}

#[test]
fn values_outside_the_data_or_the_domain_are_said_in_hounsfield_units() {
    let dir = setup();
    let d = dir.path();
    let out = raycaster(
        &["render", "ct.vol", "--domain", "5000,6000", "-o", "w.png"],
        d,
    );
    assert!(out.status.success());
    let text = stderr(&out);
    assert!(
        text.contains(
            "--domain 5000 HU to 6000 HU lies outside the data's values -1000 HU to 1000 HU"
        ),
        "{text}"
    );
    let out = raycaster(
        &[
            "render",
            "ct.vol",
            "--mode",
            "first-hit",
            "--iso",
            "2500",
            "-o",
            "i.png",
        ],
        d,
    );
    assert!(!out.status.success());
    let text = stderr(&out);
    assert!(
        text.contains("--iso 2500 lies outside the transfer function's domain -1000 HU to 2000 HU"),
        "{text}"
    );
    assert!(!d.join("i.png").exists());
    // A file without units gets the hint to convert it again.
    let out = raycaster(
        &["render", "old.vol", "--domain", "-1000,2000", "-o", "o.png"],
        d,
    );
    assert!(
        stderr(&out).contains("convert it again to give HU"),
        "{}",
        stderr(&out)
    );
    let out = raycaster(&["render", "ct.vol", "--domain", "lungs", "-o", "x.png"], d);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("soft-tissue"), "{}", stderr(&out));
    // A transfer-function file's `domain` is in stored values: HU written
    // there miss the data, said with the data's span in HU and the flag that
    // takes HU.
    let tf = |name: &str, domain: &str| {
        std::fs::write(
            d.join(name),
            format!("domain {domain}\npoint 0 0 0 0 0\npoint 1 1 1 1 1\n"),
        )
        .unwrap();
        let out = raycaster(
            &["render", "ct.vol", "--tf", name, "-o", "t.png", "--force"],
            d,
        );
        assert!(out.status.success(), "{}", stderr(&out));
        stderr(&out)
    };
    let text = tf("hu.tf", "-1000 2000");
    assert!(
        text.contains("hu.tf: `domain -1000 2000` is in stored sample values and lies outside the data's, 31768 to 33768")
            && text.contains("in the file's units the data span -1000 HU to 1000 HU: --domain LO,HI takes those"),
        "{text}"
    );
    assert!(!tf("stored.tf", "31768 33768").contains("warning"));
    // A named (HU) window on stored samples without units is warned of, as
    // `slice --window` does; on the CT file it is not.
    let named = |file: Option<&str>, name: &str| {
        let mut args = vec!["render", "--domain", name, "-o", "n.png", "--force"];
        args.extend(file);
        let out = raycaster(&args, d);
        assert!(out.status.success(), "{}", stderr(&out));
        stderr(&out)
    };
    assert!(
        named(None, "bone").contains(
            "warning: --domain bone: a CT window in Hounsfield units, and built-in shapes scene 128³ holds stored samples without value units"
        )
    );
    assert!(!named(Some("ct.vol"), "lung").contains("warning"));
}

#[test]
fn slice_windows_are_in_hounsfield_units_or_named() {
    let dir = setup();
    let d = dir.path();
    let slice = |file: &str, window: &str| {
        picture(
            d,
            "s.png",
            &[
                "slice", file, "--axis", "z", "--index", "20", "--window", window,
            ],
        )
    };
    let stored = slice("old.vol", "31418,32918");
    assert!(slice("ct.vol", "lung") == stored);
    assert!(slice("ct.vol", "-1350,150") == stored);
    assert!(slice("ct.vol", "bone") != stored);
    // A window narrower than f32 holds at the stored values (0 to 0.001 HU
    // both store as 32768): a threshold at 0 HU, as that of stored values
    // (it was refused as "window 32768,32768").
    let threshold = slice("ct.vol", "0,0.001");
    assert!(threshold == slice("old.vol", "32768,32768.01"));
    assert!(threshold.data().iter().all(|&v| v == 0 || v == 255));
    let out = raycaster(
        &[
            "slice", "ct.vol", "--axis", "z", "--index", "20", "-o", "t.png",
        ],
        d,
    );
    assert!(
        stderr(&out).contains("values -1000 HU (black) to 1000 HU (white)"),
        "{}",
        stderr(&out)
    );
    // With a window, the message names the window it used (it gave the slice's
    // range alone), and still the slice's values.
    let out = raycaster(
        &[
            "slice", "ct.vol", "--axis", "z", "--index", "20", "--window", "lung", "-o", "t.png",
            "--force",
        ],
        d,
    );
    assert!(
        stderr(&out)
            .contains("black at -1350 HU, white at 150 HU; the slice's values -1000 HU to 1000 HU"),
        "{}",
        stderr(&out)
    );
    assert!(!stderr(&out).contains("warning"), "{}", stderr(&out));
    // A window beside every value of the slice is said (the picture was one
    // grey without a word).
    for (window, shade) in [("5000,6000", "black"), ("-3000,-2000", "white")] {
        let out = raycaster(
            &[
                "slice", "ct.vol", "--axis", "z", "--index", "20", "--window", window, "-o",
                "t.png", "--force",
            ],
            d,
        );
        assert!(out.status.success());
        let said = stderr(&out);
        assert!(
            said.contains("lies outside this slice's values, -1000 HU to 1000 HU")
                && said.contains(&format!("the slice is all {shade}")),
            "{said}"
        );
    }
}
