//! Recently opened files: at most [`MAX_RECENT`] paths, newest first, one a line
//! in `$XDG_CONFIG_HOME/raycaster/recent` (or `~/.config/raycaster/recent`),
//! written atomically. Entries whose file is gone are skipped when read.

use std::path::{Path, PathBuf};

use raycaster::volume::write_file_atomically;

/// The most entries the list keeps.
pub(crate) const MAX_RECENT: usize = 10;

/// Where the list lives: `$XDG_CONFIG_HOME/raycaster/recent`, else
/// `$HOME/.config/raycaster/recent`; `None` without either.
pub(crate) fn recent_file() -> Option<PathBuf> {
    let non_empty = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty());
    let config = non_empty("XDG_CONFIG_HOME")
        .map(PathBuf::from)
        .or_else(|| non_empty("HOME").map(|home| PathBuf::from(home).join(".config")))?;
    Some(config.join("raycaster").join("recent"))
}

/// The entries of `text` whose files exist, newest first, at most [`MAX_RECENT`].
fn parse(text: &str) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = Vec::new();
    for line in text.lines().map(str::trim).filter(|l| !l.is_empty()) {
        let path = PathBuf::from(line);
        if path.exists() && !out.contains(&path) {
            out.push(path);
        }
        if out.len() == MAX_RECENT {
            break;
        }
    }
    out
}

/// The largest list file read (a list of [`MAX_RECENT`] paths is far smaller).
const LIST_MAX_BYTES: u64 = 1 << 20;

/// The list in `file` (empty when it is missing or unreadable, and when it is
/// no regular file or too big: a named pipe there would block the viewer's
/// start, `/dev/zero` fill its memory).
pub(crate) fn load(file: &Path) -> Vec<PathBuf> {
    raycaster::files::read_text(file, LIST_MAX_BYTES)
        .map(|t| parse(&t))
        .unwrap_or_default()
}

/// Puts `path` (made absolute) first in the list in `file`, dropping missing
/// entries and the oldest beyond [`MAX_RECENT`]; returns the new list.
pub(crate) fn add(file: &Path, path: &Path) -> std::io::Result<Vec<PathBuf>> {
    let path = std::path::absolute(path)?;
    let mut list = vec![path.clone()];
    list.extend(load(file).into_iter().filter(|p| *p != path));
    list.truncate(MAX_RECENT);
    if let Some(dir) = file.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let mut text = String::new();
    for p in &list {
        // A path with a line break cannot be listed; it is simply not kept.
        let line = p.to_string_lossy();
        if !line.contains('\n') {
            text += &line;
            text.push('\n');
        }
    }
    write_file_atomically(file, text.as_bytes())?;
    Ok(list)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_list_that_is_a_pipe_or_a_device_reads_as_empty_at_once() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("recent");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(made.success());
        let started = std::time::Instant::now();
        assert!(load(&fifo).is_empty());
        let zero = dir.path().join("zero");
        std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
        assert!(load(&zero).is_empty());
        assert!(started.elapsed() < std::time::Duration::from_secs(5));
    }

    #[test]
    fn the_list_keeps_ten_newest_existing_files() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("cfg/raycaster/recent");
        assert!(load(&file).is_empty(), "no list yet");
        let mut files = Vec::new();
        for i in 0..12 {
            let f = dir.path().join(format!("v{i}.vol"));
            std::fs::write(&f, b"x").unwrap();
            add(&file, &f).unwrap();
            files.push(f);
        }
        let list = load(&file);
        assert_eq!(list.len(), MAX_RECENT);
        assert_eq!(list[0], files[11]);
        assert_eq!(list[9], files[2]);
        // Reopening moves an entry to the front without a duplicate.
        let list = add(&file, &files[5]).unwrap();
        assert_eq!(list[0], files[5]);
        assert_eq!(list.iter().filter(|p| **p == files[5]).count(), 1);
        // Missing files are skipped.
        std::fs::remove_file(&files[11]).unwrap();
        let list = load(&file);
        assert!(!list.contains(&files[11]));
        assert_eq!(list.len(), MAX_RECENT - 1);
    }
}
