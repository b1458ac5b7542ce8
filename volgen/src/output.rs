//! The checks of an output file before any work, and its naming warning.

use std::path::Path;

use anyhow::bail;

/// Refuses, before any work, an output that cannot be written
/// ([`raycaster::files::output_problem`]: a folder, a device or an unwritable
/// folder, an existing file without `force`), and `-`.
pub fn check_output(path: &Path, force: bool) -> anyhow::Result<()> {
    // (`-` is no file name here: a volume is mapped and written in place.)
    if path.as_os_str() == "-" {
        bail!("-: volumes are written to files, not to standard output; name a .vol file");
    }
    if let Some(problem) = raycaster::files::output_problem(path, force) {
        bail!("{}: {problem}", path.display());
    }
    Ok(())
}

/// A warning for an output not named `.vol` (`volgen generate -o x.raw`
/// writes a `.vol` file all the same), or `None`.
pub fn output_name_warning(output: &Path) -> Option<String> {
    (!raycaster::volume::has_vol_extension(output)).then(|| {
        format!(
            "warning: {} will be a .vol file whatever its name says (name it NAME.vol)",
            output.display()
        )
    })
}

/// A warning for a volume of `dims` voxels at `spacing` whose rays, at the
/// renderer's default step, would take more samples than it allows
/// ([`raycaster::render::MAX_SAMPLES_PER_RAY`]): a spacing ratio within the
/// 1e4 read can still make a long axis too long (512 voxels at 1e4). Names the
/// finest step that renders it; `None` when the default step does.
pub fn ray_length_warning(dims: [u32; 3], spacing: [f32; 3]) -> Option<String> {
    use raycaster::render::{MAX_SAMPLES_PER_RAY, RenderSettings, samples_over, world_diagonal};
    let step = RenderSettings::default().step;
    let min_spacing = spacing.into_iter().fold(f32::INFINITY, f32::min);
    let diagonal = world_diagonal(dims, spacing);
    let per_ray = samples_over(diagonal, min_spacing, step);
    if per_ray <= MAX_SAMPLES_PER_RAY {
        return None;
    }
    // The finest step whose rays fit, rounded up to two significant digits.
    let finest = diagonal / f64::from(min_spacing) / (MAX_SAMPLES_PER_RAY - 2.0);
    let scale = 10f64.powf(finest.log10().floor() - 1.0);
    let finest = (finest / scale).ceil() * scale;
    Some(format!(
        "warning: rays through this volume take up to {per_ray:.0} samples at the default step {step}, \
         more than the {MAX_SAMPLES_PER_RAY:.0} the renderer allows (its diagonal is {:.0} times the \
         smallest spacing): render it with --step {finest} or more, or with spacings closer together",
        diagonal / f64::from(min_spacing)
    ))
}

/// A warning for a bricked layout whose padding makes the file several times
/// its voxels (an axis thinner than a brick: 20000×20000×1 in bricks of 16
/// stores 16 planes, a 10 GB file for 0.4 GB of voxels), naming the linear
/// layout; `None` for small files and ordinary paddings.
pub fn padding_warning(dims: [u32; 3], layout: raycaster::volume::Layout) -> Option<String> {
    let raycaster::volume::Layout::Bricked { side } = layout else {
        return None;
    };
    let side = u32::from(side);
    let stored =
        raycaster::volume::BlockGrid::new(dims, side).block_count() * u64::from(side).pow(3);
    let voxels: u64 = dims.iter().map(|&d| u64::from(d)).product();
    (stored > 4 * voxels && stored > 64 << 20).then(|| {
        let [x, y, z] = dims;
        format!(
            "warning: bricks of {side} voxels a side store {:.1} times the volume's {x}x{y}x{z} voxels (an axis thinner than a brick is padded to its side); --layout linear stores them as they are",
            stored as f64 / voxels as f64
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bricks_that_pad_a_thin_volume_many_times_over_are_warned_of() {
        use raycaster::volume::Layout;
        let bricked = Layout::Bricked { side: 16 };
        let warning = padding_warning([20000, 20000, 1], bricked).unwrap();
        assert!(
            warning.contains("store 18.2 times the volume's 20000x20000x1 voxels"),
            "{warning}"
        );
        assert_eq!(padding_warning([20000, 20000, 1], Layout::Linear), None);
        assert_eq!(padding_warning([1024, 1024, 1024], bricked), None);
        // Small files are not worth a word.
        assert_eq!(padding_warning([100, 100, 1], bricked), None);
    }

    #[test]
    fn a_long_axis_at_a_lopsided_spacing_is_warned_of_with_a_step_that_renders() {
        assert_eq!(ray_length_warning([512, 512, 512], [1.0, 1.0, 1.0]), None);
        // Within the 1e4 ratio, but 511 · 1e4 long in units of the smallest.
        let warning = ray_length_warning([512, 4, 4], [1e4, 1.0, 1.0]).unwrap();
        assert!(warning.contains("--step 1.3 or more"), "{warning}");
        assert!(warning.contains("10220002 samples"), "{warning}");
        // The step it names renders: within the renderer's budget.
        let diagonal = raycaster::render::world_diagonal([512, 4, 4], [1e4, 1.0, 1.0]);
        let per_ray = raycaster::render::samples_over(diagonal, 1.0, 1.3);
        assert!(
            per_ray <= raycaster::render::MAX_SAMPLES_PER_RAY,
            "{per_ray}"
        );
    }
}
