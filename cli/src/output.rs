//! Output files of the commands: checked before any work is done.

use std::path::Path;

use anyhow::{Result, bail};

/// Refuses, before any rendering, an output that could not be written: not a
/// `.png` name, a missing or unwritable folder, or an existing file without
/// `--force`.
pub fn check_output(output: &Path, force: bool) -> Result<()> {
    let is_png = output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if !is_png {
        bail!(
            "{}: only PNG images are written; name the output with .png",
            output.display()
        );
    }
    if output.is_dir() {
        bail!("{}: is a directory; name an image file", output.display());
    }
    if output.exists() && !force {
        bail!(
            "{}: already exists (pass --force to replace it)",
            output.display()
        );
    }
    // Creating (and dropping) the temporary file the image will be written to
    // checks that the folder exists and is writable, before a long render.
    raycaster::files::temp_file_beside(output)
        .map_err(|e| anyhow::anyhow!("{}: cannot write there: {e}", output.display()))?;
    Ok(())
}
