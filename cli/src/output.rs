//! Output files of the commands: checked before any work is done.

use std::path::Path;

use anyhow::{Result, bail};

/// Refuses, before any rendering, an image output that could not be written:
/// not a `.png` name, or [`check_file`]'s reasons.
pub fn check_output(output: &Path, force: bool) -> Result<()> {
    // (A folder first: its name is rarely the problem.)
    if output.is_dir() {
        bail!("{}: is a directory; name a file", output.display());
    }
    if output.as_os_str() == "-" {
        bail!("-: images are written to files, not to standard output; name a .png file");
    }
    if let Some(problem) = raycaster::files::png_name_problem(output) {
        bail!("{}: {problem}", output.display());
    }
    check_file(output, force)
}

/// [`check_output`] for a command that reads `inputs`: an output that is one
/// of them is refused too (`--force` would replace the input with the image).
pub fn check_output_of<I: AsRef<Path>>(
    output: &Path,
    force: bool,
    inputs: impl IntoIterator<Item = I>,
) -> Result<()> {
    check_not_an_input(output, inputs, "the image")?;
    check_output(output, force)
}

/// Refuses an output that is one of `inputs` (`--force` would replace the
/// input with `what`, "the image" or "the CSV").
pub fn check_not_an_input<I: AsRef<Path>>(
    output: &Path,
    inputs: impl IntoIterator<Item = I>,
    what: &str,
) -> Result<()> {
    if let Some(input) = inputs
        .into_iter()
        .find(|i| raycaster::files::same_file(i.as_ref(), output))
    {
        let input = input.as_ref();
        // (The input's own name where the output's is another way to write it,
        // a data file a header names.)
        let which = if input == output {
            String::new()
        } else {
            format!(" ({})", input.display())
        };
        bail!(
            "{}: is an input of this command{which}; name another file for {what}",
            output.display()
        );
    }
    Ok(())
}

/// Refuses, before any work, an output file that could not be written
/// ([`raycaster::files::output_problem`]: a directory, a missing or unwritable
/// folder, a device or named pipe, or an existing file without `--force`).
pub fn check_file(output: &Path, force: bool) -> Result<()> {
    if let Some(problem) = raycaster::files::output_problem(output, force) {
        bail!("{}: {problem}", output.display());
    }
    Ok(())
}
