//! The library in a few lines: build (or open) a volume, frame it with a camera and
//! render it to a PNG.
//!
//! ```sh
//! cargo run --release -p raycaster --example render_scene               # built-in scene
//! cargo run --release -p raycaster --example render_scene -- shapes.vol out.png
//! ```
//!
//! `cargo test` compiles this example, so it keeps up with the API.

use std::path::Path;

use raycaster::render::{
    Orbit, ParallelOptions, RenderSettings, RenderVolume, TransferFunction, render_parallel,
};
use raycaster::synth::{SceneKind, synthesize};
use raycaster::volume::{SampleType, Volume};

fn main() {
    // Errors as people read them (`main` returning an error would print Debug text).
    if let Err(e) = run() {
        eprintln!("error: {}", raycaster::errors::error_text(e.as_ref()));
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let input = args.next();
    let output = args.next().unwrap_or_else(|| "example.png".to_string());

    // 1. A volume: a `.vol` file (mapped, not read) or a generated scene in RAM.
    //    `raycaster::import::open_volume_any` also opens NRRD, NIfTI, MetaImage, DICOM.
    let volume = match &input {
        Some(path) => Volume::open(path)?,
        None => {
            let n = 96;
            let scene = SceneKind::Shapes.build([n; 3], 1);
            synthesize(scene.as_ref(), "shapes", [n; 3], [1.0; 3], SampleType::U8)?
        }
    };

    // 2. Prepared for rendering: bricks and their value ranges (empty-space skipping).
    let prepared = RenderVolume::new(&volume, None)?;

    // 3. A camera that frames the whole volume from 60° azimuth, 25° elevation.
    let (lo, hi) = prepared.geometry().world_bounds();
    let orbit = Orbit::framing(
        lo,
        hi,
        (-60f32).to_radians(),
        25f32.to_radians(),
        Some(40.0),
    );
    let camera = orbit.camera(400, 400)?;

    // 4. What to render: direct volume rendering with a preset transfer function.
    let settings = RenderSettings {
        transfer: TransferFunction::preset("shapes")?,
        ..RenderSettings::default()
    };

    // 5. Render on every core and save.
    let frame = render_parallel(&prepared, &camera, &settings, &ParallelOptions::default())?;
    frame.to_image().save_png(Path::new(&output))?;
    println!(
        "wrote {output}: {}x{} in {:.3} s, {} samples",
        frame.width,
        frame.height,
        frame.stats.time.as_secs_f64(),
        frame.stats.counters.samples
    );
    Ok(())
}
