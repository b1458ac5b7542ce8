//! The file browser inside the viewer: a folder's sub-folders and the files the
//! viewer opens (volumes in every format it reads, sessions and two-level
//! scenes), without a desktop portal.

use std::io::{self, Read};
use std::path::{Path, PathBuf};

use raycaster::files::human_bytes;
use raycaster::import::FOREIGN_EXTENSIONS;

/// What a listed entry is, and what picking it does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum EntryKind {
    /// A folder: picking it shows its contents (and "Open folder" reads it as
    /// a DICOM series).
    Folder,
    /// A volume file (`.vol` or a foreign format): picking it opens it.
    Volume,
    /// A session (`.toml`): picking it restores it.
    Session,
    /// A two-level scene (`.toml` of `[[object]]` tables): picking it loads
    /// it over the open volume.
    Scene,
}

/// One entry of a folder listing.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Entry {
    /// The file or folder name.
    pub name: String,
    /// What it is.
    pub kind: EntryKind,
    /// Its size in bytes (0 for folders).
    pub size: u64,
}

impl Entry {
    /// The line the browser shows: `name/` for a folder, the name and size of
    /// a file.
    pub(crate) fn label(&self) -> String {
        match self.kind {
            EntryKind::Folder => format!("{}/", self.name),
            EntryKind::Volume => format!("{}   {}", self.name, human_bytes(self.size)),
            EntryKind::Session => format!("{}   (session)", self.name),
            EntryKind::Scene => format!("{}   (scene)", self.name),
        }
    }
}

/// What a file named `name` is to the viewer, if anything.
pub(crate) fn kind_of_file(name: &str) -> Option<EntryKind> {
    let lower = name.to_ascii_lowercase();
    if lower.ends_with(".vol") || FOREIGN_EXTENSIONS.iter().any(|(e, _)| lower.ends_with(e)) {
        Some(EntryKind::Volume)
    } else if lower.ends_with(".toml") {
        Some(EntryKind::Session)
    } else {
        None
    }
}

/// Whether the `.toml` file at `path` is a two-level scene (`[[object]]`
/// tables and no session's `version` or `[volume]` in its first 64 KiB) or a
/// session (anything else: its errors say what is wrong). Scenes were listed
/// as sessions, failed to restore, and left the session field naming them.
fn toml_kind(path: &Path) -> EntryKind {
    let mut head = Vec::new();
    let read = std::fs::File::open(path).and_then(|f| f.take(64 << 10).read_to_end(&mut head));
    if read.is_err() {
        return EntryKind::Session;
    }
    let text = String::from_utf8_lossy(&head);
    let (mut session, mut scene) = (false, false);
    for line in text.lines().map(str::trim) {
        let key = line.split('=').next().unwrap_or("").trim();
        session |= line.starts_with("[volume]") || (key == "version" && line.contains('='));
        scene |= line.starts_with("[[object]]");
    }
    if scene && !session {
        EntryKind::Scene
    } else {
        EntryKind::Session
    }
}

/// The sub-folders of `dir` and the files the viewer opens, folders first,
/// each group by name (case-insensitive); hidden entries (a leading `.`) and
/// other files are left out. Entries that cannot be inspected are skipped.
pub(crate) fn list(dir: &Path) -> io::Result<Vec<Entry>> {
    let mut entries = Vec::new();
    for item in std::fs::read_dir(dir)? {
        let Ok(item) = item else { continue };
        let name = item.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') {
            continue;
        }
        // Follows links: a link to a folder is a folder.
        let Ok(meta) = std::fs::metadata(item.path()) else {
            continue;
        };
        let kind = if meta.is_dir() {
            EntryKind::Folder
        } else if meta.is_file() {
            match kind_of_file(&name) {
                Some(EntryKind::Session) => toml_kind(&item.path()),
                Some(kind) => kind,
                None => continue,
            }
        } else {
            // FIFOs, sockets, devices: never offered.
            continue;
        };
        let size = if meta.is_file() { meta.len() } else { 0 };
        entries.push(Entry { name, kind, size });
    }
    entries.sort_by_cached_key(|e| {
        (
            e.kind != EntryKind::Folder,
            e.name.to_lowercase(),
            e.name.clone(),
        )
    });
    Ok(entries)
}

/// Where the browser starts: the folder of the typed path (the path itself
/// when it is a folder), else the working folder.
pub(crate) fn start_folder(typed: &str) -> PathBuf {
    let typed = Path::new(typed.trim());
    let candidate = if typed.is_dir() {
        Some(typed.to_path_buf())
    } else {
        typed
            .parent()
            .filter(|p| !p.as_os_str().is_empty() && p.is_dir())
            .map(Path::to_path_buf)
    };
    let folder = candidate
        .or_else(|| std::env::current_dir().ok())
        .unwrap_or_else(|| PathBuf::from("."));
    std::fs::canonicalize(&folder).unwrap_or(folder)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folders_first_then_openable_files_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir(d.join("scans")).unwrap();
        std::fs::create_dir(d.join("Archive")).unwrap();
        std::fs::create_dir(d.join(".cache")).unwrap();
        std::fs::write(d.join("b.vol"), [0u8; 1500]).unwrap();
        std::fs::write(d.join("A.NII.GZ"), [0u8; 10]).unwrap();
        std::fs::write(d.join("view.toml"), "version = 1").unwrap();
        std::fs::write(
            d.join("organs.toml"),
            "labels = \"l.vol\"\n[[object]]\nid = 1\n",
        )
        .unwrap();
        std::fs::write(d.join("notes.txt"), "x").unwrap();
        std::fs::write(d.join(".hidden.vol"), "x").unwrap();
        let entries = list(d).unwrap();
        let names: Vec<&str> = entries.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "Archive",
                "scans",
                "A.NII.GZ",
                "b.vol",
                "organs.toml",
                "view.toml"
            ]
        );
        let kinds: Vec<EntryKind> = entries.iter().map(|e| e.kind).collect();
        use EntryKind::*;
        assert_eq!(kinds, [Folder, Folder, Volume, Volume, Scene, Session]);
        assert_eq!(entries[4].label(), "organs.toml   (scene)");
        assert_eq!(entries[0].label(), "Archive/");
        assert_eq!(entries[3].label(), "b.vol   1.5 kB");
        assert_eq!(entries[2].label(), "A.NII.GZ   10 bytes");
    }

    #[test]
    fn a_missing_folder_is_an_error_and_the_start_falls_back() {
        let dir = tempfile::tempdir().unwrap();
        assert!(list(&dir.path().join("gone")).is_err());
        let file = dir.path().join("x.vol");
        std::fs::write(&file, "x").unwrap();
        let canonical = std::fs::canonicalize(dir.path()).unwrap();
        assert_eq!(start_folder(&file.display().to_string()), canonical);
        assert_eq!(start_folder(&dir.path().display().to_string()), canonical);
        let nowhere = dir.path().join("no/such/file.vol");
        let here = std::fs::canonicalize(std::env::current_dir().unwrap()).unwrap();
        assert_eq!(start_folder(&nowhere.display().to_string()), here);
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_is_never_offered() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe.vol");
        let status = std::process::Command::new("mkfifo").arg(&fifo).status();
        assert!(status.is_ok_and(|s| s.success()), "mkfifo");
        assert!(list(dir.path()).unwrap().is_empty());
    }
}
