//! `raycaster compare`: how far one image is from another (quality
//! measurements against a reference rendering).

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use raycaster::render::RgbImage;

/// Compare two PNG images of the same size: the largest per-channel difference
/// and the PSNR (dB over all RGB channels, 8 bits; `inf` when identical).
#[derive(Args, Debug)]
pub struct CompareArgs {
    /// The image to judge.
    image: PathBuf,
    /// The reference.
    reference: PathBuf,
    /// Print one JSON object instead of text: max_difference, psnr_db (null for
    /// identical images, whose PSNR is infinite) and pixels.
    #[arg(long)]
    json: bool,
    /// Write the difference image (×8) here.
    #[arg(long, value_name = "PNG")]
    diff: Option<PathBuf>,
    /// Replace an existing difference image.
    #[arg(long, requires = "diff")]
    force: bool,
}

/// Runs `raycaster compare`.
pub fn run(args: CompareArgs) -> Result<()> {
    if let Some(path) = &args.diff {
        // Never one of the images compared (`--force` would replace it).
        let same = |p: &PathBuf| raycaster::files::same_file(p, path);
        if same(&args.image) || same(&args.reference) {
            bail!(
                "{}: is one of the images compared; name another file for --diff",
                path.display()
            );
        }
        crate::output::check_output(path, args.force)?;
    }
    // (The image errors name the file.)
    let load = |p: &PathBuf, what: &str| {
        RgbImage::load_png(p).with_context(|| format!("cannot read the {what}"))
    };
    let (a, b) = (
        load(&args.image, "image")?,
        load(&args.reference, "reference")?,
    );
    let (Some(max), Some(psnr)) = (a.max_difference(&b), a.psnr(&b)) else {
        bail!(
            "the images differ in size: {}×{} and {}×{}",
            a.width(),
            a.height(),
            b.width(),
            b.height()
        );
    };
    if let Some(path) = &args.diff {
        // The difference image and its encoding.
        let pixels = u64::from(a.width()) * u64::from(a.height());
        crate::memory::check_memory(format_args!("--diff {}", path.display()), pixels * 7)?;
        a.diff(&b).save_png(path)?;
    }
    if args.json {
        // (JSON has no infinity: identical images give null, not a string.)
        let psnr = if psnr.is_finite() {
            serde_json::json!(psnr)
        } else {
            serde_json::Value::Null
        };
        println!(
            "{}",
            serde_json::json!({ "max_difference": max, "psnr_db": psnr, "pixels": u64::from(a.width()) * u64::from(a.height()) })
        );
    } else {
        println!("max difference {max}/255");
        println!("PSNR           {psnr:.2} dB");
    }
    if let Some(path) = args.diff.as_ref().filter(|_| !args.json) {
        eprintln!(
            "wrote {} (the differences ×8, {}×{})",
            path.display(),
            a.width(),
            a.height()
        );
    }
    Ok(())
}
