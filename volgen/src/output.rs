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
