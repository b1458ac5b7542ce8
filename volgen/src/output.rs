//! The checks of an output file before any work, and its naming warning.

use std::path::Path;

use anyhow::{Context, bail};

/// Refuses, before any work, an output that cannot be written: a folder, a
/// device or an unwritable folder (said first, and never "already exists" for
/// a folder --force cannot replace), or an existing file without `force`.
pub fn check_output(path: &Path, force: bool) -> anyhow::Result<()> {
    // (`-` is no file name here: a volume is mapped and written in place.)
    if path.as_os_str() == "-" {
        bail!("-: volumes are written to files, not to standard output; name a .vol file");
    }
    raycaster::files::temp_file_beside(path)
        .with_context(|| format!("{}: cannot write there", path.display()))?;
    if !force && let Some(problem) = raycaster::files::existing_output(path) {
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
