//! Opening input files safely: only regular files are read.
//!
//! A named pipe (FIFO) given as a volume would block a reader forever, and a device
//! or socket is never a volume. Every reader of user-named files (volumes, foreign
//! scans, transfer functions, scene files) opens them through [`open_regular`], which
//! opens without blocking and refuses anything that is not a regular file with a
//! clear [`std::io::Error`] (kind [`std::io::ErrorKind::InvalidInput`]).

use std::fs::File;
use std::io::Read;
use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
use std::path::{Path, PathBuf};

/// What kind of non-regular file `meta` describes, for messages.
fn kind_of(meta: &std::fs::Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_dir() {
        "a directory"
    } else if t.is_fifo() {
        "a named pipe (FIFO)"
    } else if t.is_socket() {
        "a socket"
    } else if t.is_block_device() || t.is_char_device() {
        "a device"
    } else {
        "not a regular file"
    }
}

/// The error for a file that is not a regular file.
fn not_regular(meta: &std::fs::Metadata) -> std::io::Error {
    let kind = kind_of(meta);
    let error_kind = if meta.is_dir() {
        std::io::ErrorKind::IsADirectory
    } else {
        std::io::ErrorKind::InvalidInput
    };
    let msg = if kind == "not a regular file" {
        kind.to_string()
    } else {
        format!("is {kind}, not a regular file")
    };
    std::io::Error::new(error_kind, msg)
}

/// Opens `path` for reading if it is a regular file (symbolic links are followed);
/// a directory, named pipe, socket or device is refused at once, without blocking.
pub fn open_regular(path: &Path) -> std::io::Result<File> {
    // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer. It has
    // no effect on regular files.
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)?;
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Err(not_regular(&meta));
    }
    Ok(file)
}

/// Checks, without opening it, that `path` is a regular file (links followed).
pub fn check_regular(path: &Path) -> std::io::Result<()> {
    let meta = std::fs::metadata(path)?;
    if meta.is_file() {
        Ok(())
    } else {
        Err(not_regular(&meta))
    }
}

/// Whether two paths name the same existing file (through links and `..`).
pub fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

/// Whether `a` and `b` name the same file, existing or not: the same name in
/// the same folder, however the folders are written (`x.vol` and `./x.vol`, a
/// linked folder). For two outputs of one command, or an output and a file
/// it reads.
pub fn same_target(a: &Path, b: &Path) -> bool {
    let place = |p: &Path| {
        let folder = parent_dir(p).canonicalize().ok();
        (folder, p.file_name().map(|n| n.to_os_string()))
    };
    let (pa, pb) = (place(a), place(b));
    pa.0.is_some() && pa == pb
}

/// Reads the regular file `path` as UTF-8 text, refusing files over `max_bytes`
/// (a text file of settings is small; a huge one is a mistake, not a setting).
pub fn read_text(path: &Path, max_bytes: u64) -> std::io::Result<String> {
    let file = open_regular(path)?;
    let len = file.metadata()?.len();
    if len > max_bytes {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("is {len} bytes; a text file of settings holds at most {max_bytes}"),
        ));
    }
    let mut text = String::new();
    file.take(max_bytes).read_to_string(&mut text)?;
    Ok(text)
}

/// The message the SIGBUS guard prints (a leaked buffer, swapped atomically: the
/// handler may only read it).
static SIGBUS_MESSAGE: std::sync::atomic::AtomicPtr<Vec<u8>> =
    std::sync::atomic::AtomicPtr::new(std::ptr::null_mut());

/// What the SIGBUS message says happened after the fault ([`guard_mapped_reads`]).
static SIGBUS_CONSEQUENCE: std::sync::Mutex<String> = std::sync::Mutex::new(String::new());

/// Makes a fault on a memory-mapped file (SIGBUS: another program truncated the
/// file while it was mapped) end the process with an `error:` line naming the file
/// ([`guard_mapped_file`]) and what that meant, `consequence` ("stopped, nothing
/// was written": outputs are written atomically, so none is left half-written),
/// and exit status 1, instead of a crash.
///
/// For programs (the `raycaster`, `volgen` and `viewer` binaries): call once, early.
#[allow(unsafe_code)] // libc calls without a safe wrapper; SAFETY notes inside
pub fn guard_mapped_reads(consequence: &str) {
    *SIGBUS_CONSEQUENCE.lock().unwrap_or_else(|e| e.into_inner()) = consequence.to_string();
    set_sigbus_message("a memory-mapped volume file".to_string());
    extern "C" fn on_sigbus(_: libc::c_int) {
        // Only async-signal-safe calls: atomic loads, write(2), unlink(2), _exit(2).
        let m = SIGBUS_MESSAGE.load(std::sync::atomic::Ordering::Acquire);
        if !m.is_null() {
            // SAFETY: the buffer is leaked, never freed; writing it to stderr.
            unsafe {
                let m = &*m;
                libc::write(2, m.as_ptr().cast(), m.len());
            }
        }
        remove_partial_outputs_at_fault();
        // SAFETY: ends the process at once, as the signal would have.
        unsafe { libc::_exit(1) };
    }
    // SAFETY: installs a handler that only calls async-signal-safe functions.
    unsafe {
        libc::signal(libc::SIGBUS, on_sigbus as *const () as libc::sighandler_t);
    }
}

/// Makes a write past the file-size limit (`ulimit -f`) fail with its error
/// ("File too large", EFBIG), said once and its partial output removed like any
/// failed write, instead of SIGXFSZ killing the process and leaving the
/// partial file behind.
///
/// For programs (the `raycaster`, `volgen` and `viewer` binaries): call once, early.
#[allow(unsafe_code)] // signal() has no safe wrapper in std
pub fn fail_writes_past_the_file_size_limit() {
    // SAFETY: setting a signal's disposition to "ignore"; no handler runs.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
}

/// Names `path` in the message of [`guard_mapped_reads`]: the file being mapped now.
pub fn guard_mapped_file(path: &Path) {
    set_sigbus_message(path.display().to_string());
}

fn set_sigbus_message(what: String) {
    let consequence = SIGBUS_CONSEQUENCE.lock().unwrap_or_else(|e| e.into_inner());
    let message = format!(
        "error: {what}: shrank or vanished while it was read (another program truncated it?); {consequence}\n"
    );
    // Leaked on purpose: the signal handler may be reading the previous one.
    let new = Box::into_raw(Box::new(message.into_bytes()));
    SIGBUS_MESSAGE.store(new, std::sync::atomic::Ordering::Release);
}

/// Creates the temporary file that will become `path`: hidden, beside it (so the
/// final rename is atomic), named `.NAME.PID.XXXXXX.partial` after it and the writing
/// process, with the usual mode for new files (the umask applies) rather than the
/// 0600 of temporary files.
///
/// Partial files of the same target left by a process of ours that no longer runs
/// (killed with SIGKILL, or a power cut) are removed first; errors name the target,
/// never the temporary file.
pub fn temp_file_beside(path: &Path) -> std::io::Result<tempfile::NamedTempFile> {
    let dir = parent_dir(path);
    if !dir.is_dir() {
        let (kind, msg) = if dir.exists() {
            let msg = format!("{} is not a directory", dir.display());
            (std::io::ErrorKind::NotADirectory, msg)
        } else {
            let msg = format!("directory {} does not exist", dir.display());
            (std::io::ErrorKind::NotFound, msg)
        };
        return Err(std::io::Error::new(kind, msg));
    }
    // The rename at the end would replace a device, a named pipe or a folder's
    // entry with a regular file (`--force` onto /dev/null): refused.
    if let Ok(meta) = std::fs::metadata(path)
        && !meta.is_file()
    {
        return Err(not_regular(&meta));
    }
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    remove_stale_partials(dir, &name);
    let tmp = tempfile::Builder::new()
        .prefix(&format!(".{name}.{}.", std::process::id()))
        .suffix(".partial")
        .permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666))
        .tempfile_in(dir)
        .map_err(without_temp_path)?;
    PARTIALS
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(tmp.path().to_path_buf());
    note_partial_for_faults(tmp.path());
    Ok(tmp)
}

/// The latest temporary files of [`temp_file_beside`] as C strings, for the
/// SIGBUS handler of [`guard_mapped_reads`], which may neither lock nor
/// allocate: a ring of leaked strings (a few dozen bytes per output written;
/// the oldest, long finished, are forgotten first).
static PARTIALS_AT_FAULT: [std::sync::atomic::AtomicPtr<libc::c_char>; 32] =
    [const { std::sync::atomic::AtomicPtr::new(std::ptr::null_mut()) }; 32];
static PARTIALS_AT_FAULT_NEXT: std::sync::atomic::AtomicUsize =
    std::sync::atomic::AtomicUsize::new(0);

fn note_partial_for_faults(path: &Path) {
    use std::os::unix::ffi::OsStrExt;
    let Ok(c) = std::ffi::CString::new(path.as_os_str().as_bytes()) else {
        return;
    };
    let slot = PARTIALS_AT_FAULT_NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
        % PARTIALS_AT_FAULT.len();
    // Leaked on purpose: the handler may be reading the string it replaces.
    PARTIALS_AT_FAULT[slot].store(c.into_raw(), std::sync::atomic::Ordering::Release);
}

/// Unlinks the noted temporary files (those renamed or deleted since are
/// gone: the unlink fails harmlessly); only async-signal-safe calls.
#[allow(unsafe_code)] // unlink(2) without a safe wrapper that takes no allocation
fn remove_partial_outputs_at_fault() {
    for slot in &PARTIALS_AT_FAULT {
        let p = slot.load(std::sync::atomic::Ordering::Acquire);
        if !p.is_null() {
            // SAFETY: `p` is a leaked, never freed C string; unlink(2) is
            // async-signal-safe.
            unsafe { libc::unlink(p) };
        }
    }
}

/// Every temporary file [`temp_file_beside`] made in this process: those of
/// finished outputs were renamed away or deleted since, the others are outputs
/// still being written.
static PARTIALS: std::sync::Mutex<Vec<std::path::PathBuf>> = std::sync::Mutex::new(Vec::new());

/// Deletes the temporary files of outputs still being written, for a process
/// about to exit at once (a second interrupt while the first cancels), so that
/// it leaves no partial file behind.
pub fn remove_partial_outputs() {
    for path in PARTIALS.lock().unwrap_or_else(|e| e.into_inner()).iter() {
        // (Gone already when its output was finished or dropped.)
        let _ = std::fs::remove_file(path);
    }
}

/// Why writing `path` without `--force` would replace something: an existing
/// file, or a symbolic link, even one to a missing file (`Path::exists` follows
/// links and says no; the write would then fail after the work, or replace the
/// link); `None` when nothing is there.
pub fn existing_output(path: &Path) -> Option<&'static str> {
    let meta = std::fs::symlink_metadata(path).ok()?;
    Some(if meta.file_type().is_symlink() && !path.exists() {
        "is a symbolic link to a missing file (pass --force to replace the link)"
    } else {
        "already exists (pass --force to replace it)"
    })
}

/// Why `path` cannot take an output a command is about to write, if it
/// cannot, in this order: it is a folder; no file can be created there (a
/// missing or read-only folder, a device or a pipe: found by creating and
/// dropping the temporary file the output will be written to,
/// [`temp_file_beside`]), which `--force` would not mend; or something is
/// there already, unless `force` ([`existing_output`]). Front ends ask before
/// any work, so a long render or generation is never lost to its output; the
/// reason follows the path in their messages.
pub fn output_problem(path: &Path, force: bool) -> Option<String> {
    if path.is_dir() {
        return Some("is a directory; name a file".to_string());
    }
    if let Err(e) = temp_file_beside(path) {
        return Some(format!("cannot write there: {e}"));
    }
    (!force)
        .then(|| existing_output(path))
        .flatten()
        .map(str::to_string)
}

/// Whether `path` is named like a TOML file (`.toml`, any case): a session or
/// a two-level scene, which front ends name when one that exists is given as a
/// volume.
pub fn is_toml_name(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"))
}

/// Why `path` cannot name a PNG image we write, if it cannot: its name is
/// only `.png`, or it does not end in `.png` (any case). The CLI's `-o` and
/// the viewer's *Save PNG* share the rule: PNG data under another extension
/// would mislead whatever opens the file by its name.
pub fn png_name_problem(path: &Path) -> Option<&'static str> {
    if path
        .file_name()
        .is_some_and(|n| n.eq_ignore_ascii_case(".png"))
    {
        return Some("the image needs a name before .png");
    }
    let is_png = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    (!is_png).then_some("only PNG images are written; name the file with .png")
}

/// The folder `path` is in (`.` for a bare name).
pub fn parent_dir(path: &Path) -> &Path {
    path.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// How a file in folder `dir` names `held`, a path as this process holds it
/// (absolute, or relative to the working directory, as `dir` is): relative to
/// `dir` where that reaches the same file, so that the two can move together,
/// else absolute. (Session and scene files read their relative paths from
/// their own folder.)
pub fn path_for_file_in(dir: &Path, held: &Path) -> PathBuf {
    match std::env::current_dir() {
        Ok(cwd) => path_for_file_in_from(&cwd, dir, held),
        Err(_) => held.to_path_buf(),
    }
}

/// [`path_for_file_in`] with `cwd` as the working directory.
fn path_for_file_in_from(cwd: &Path, dir: &Path, held: &Path) -> PathBuf {
    if held.is_absolute() {
        return held.to_path_buf();
    }
    let (target, base) = (cwd.join(held), cwd.join(dir));
    let (normal_target, normal_base) = (lexically_normal(&target), lexically_normal(&base));
    let common = normal_target
        .components()
        .zip(normal_base.components())
        .take_while(|(a, b)| a == b)
        .count();
    let mut relative = PathBuf::new();
    for _ in normal_base.components().skip(common) {
        relative.push("..");
    }
    for c in normal_target.components().skip(common) {
        relative.push(c);
    }
    // Through a symbolic link `..` leads elsewhere than the lexical parent:
    // the relative form only where it reaches the file itself.
    match (
        std::fs::canonicalize(base.join(&relative)),
        std::fs::canonicalize(&target),
    ) {
        (Ok(a), Ok(b)) if a == b => relative,
        _ => target,
    }
}

/// `path` with `.` left out and each `..` taking the component before it
/// away (at the root it stays the root).
fn lexically_normal(path: &Path) -> PathBuf {
    use std::path::Component;
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if matches!(out.components().next_back(), Some(Component::Normal(_))) {
                    out.pop();
                } else if !out.has_root() {
                    out.push("..");
                }
            }
            other => out.push(other),
        }
    }
    out
}

/// The error without the temporary file's name `tempfile` adds ("… at path
/// .a.vol.1234.Xy7.partial"): users know the target, not our scratch names.
fn without_temp_path(e: std::io::Error) -> std::io::Error {
    if let Some(cause) = e.get_ref().and_then(|inner| inner.source()) {
        return std::io::Error::new(e.kind(), cause.to_string());
    }
    // (`tempfile`'s error has no source: its text ends with the path.)
    let text = e.to_string();
    match text.find(" at path \"") {
        Some(end) => std::io::Error::new(e.kind(), text[..end].to_string()),
        None => e,
    }
}

/// Removes `.NAME.PID.XXXXXX.partial` files in `dir` whose process is gone,
/// and the partial files of those (`..NAME.PID.XXXXXX.partial.PID.YYYYYY.partial`:
/// an output staged under a partial name, as `volgen generate` stages a
/// volume and its labels, was itself being written). Best effort: a file
/// that cannot be removed stays.
fn remove_stale_partials(dir: &Path, name: &str) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let prefix = format!(".{name}.");
    let nested = format!("..{name}.");
    for entry in entries.flatten() {
        let file_name = entry.file_name();
        let Some(file_name) = file_name.to_str() else {
            continue;
        };
        let Some(pid) = file_name
            .strip_prefix(&prefix)
            .and_then(partial_pid)
            .or_else(|| file_name.strip_prefix(&nested).and_then(nested_partial_pid))
        else {
            continue;
        };
        if pid <= 0 || process_alive(pid) {
            continue;
        }
        if entry.file_type().is_ok_and(|t| t.is_file()) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// The process of a partial file's name after its target's, `PID.XXXXXX.partial`
/// (the random part has no dot).
fn partial_pid(rest: &str) -> Option<i32> {
    let (pid, random) = rest.strip_suffix(".partial")?.split_once('.')?;
    (!random.contains('.')).then(|| pid.parse().ok())?
}

/// The process of a partial file of a partial file, `PID.XXXXXX.partial.PID.YYYYYY.partial`
/// after its target's name (one process wrote both).
fn nested_partial_pid(rest: &str) -> Option<i32> {
    let (outer, inner) = rest.split_once(".partial.")?;
    let pid = partial_pid(&format!("{outer}.partial"))?;
    (partial_pid(inner)? == pid).then_some(pid)
}

/// Whether process `pid` exists (it may belong to another user).
#[allow(unsafe_code)] // libc calls without a safe wrapper; SAFETY notes inside
fn process_alive(pid: i32) -> bool {
    // SAFETY: kill with signal 0 only checks for the process; it sends nothing.
    let r = unsafe { libc::kill(pid, 0) };
    r == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

/// Bytes free for an unprivileged user on the file system holding `dir`.
#[allow(unsafe_code)] // libc calls without a safe wrapper; SAFETY notes inside
pub fn free_space(dir: &Path) -> std::io::Result<u64> {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(dir.as_os_str().as_bytes())
        .map_err(|_| std::io::Error::from(std::io::ErrorKind::InvalidInput))?;
    // SAFETY: a zeroed statvfs is a valid value; statvfs fills it for a valid path.
    let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
    if unsafe { libc::statvfs(c.as_ptr(), &mut st) } != 0 {
        return Err(std::io::Error::last_os_error());
    }
    // u64 on 64-bit Linux, narrower types elsewhere.
    #[allow(clippy::useless_conversion)]
    let (blocks, size) = (u64::from(st.f_bavail), u64::from(st.f_frsize));
    Ok(blocks.saturating_mul(size))
}

/// Refuses to start writing `bytes` into a new file beside `path` when its file
/// system has less free space (checked up front, so a doomed job fails at once).
pub fn check_free_space(path: &Path, bytes: u64) -> std::io::Result<()> {
    check_free_space_in(parent_dir(path), bytes)
}

/// [`check_free_space`] for `bytes` written into folder `dir` (a temporary
/// file there).
pub fn check_free_space_in(dir: &Path, bytes: u64) -> std::io::Result<()> {
    let free = free_space(dir)?;
    if bytes > free {
        return Err(std::io::Error::new(
            std::io::ErrorKind::StorageFull,
            format!(
                "needs {} but {} has only {} free",
                human_bytes(bytes),
                dir.display(),
                human_bytes(free)
            ),
        ));
    }
    Ok(())
}

/// `1.5 GB`-style sizes for messages (decimal units, as `df -H`).
pub fn human_bytes(n: u64) -> String {
    let units = ["bytes", "kB", "MB", "GB", "TB", "PB", "EB"];
    let mut v = n as f64;
    let mut u = 0;
    while v >= 1000.0 && u + 1 < units.len() {
        v /= 1000.0;
        u += 1;
    }
    if u == 0 {
        format!("{n} bytes")
    } else {
        format!("{v:.1} {}", units[u])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_is_named_from_another_folder_relative_where_that_reaches_it() {
        let root = tempfile::tempdir().unwrap();
        let cwd = root.path().join("work");
        for d in ["work/v", "s/h", "sub/deep"] {
            std::fs::create_dir_all(root.path().join(d)).unwrap();
        }
        std::fs::write(root.path().join("shapes.vol"), b"x").unwrap();
        std::fs::write(cwd.join("v/a.vol"), b"x").unwrap();
        let named =
            |dir: &str, held: &str| path_for_file_in_from(&cwd, Path::new(dir), Path::new(held));
        // Held as the viewer holds a session's path: its folder joined.
        assert_eq!(
            named("../sub/deep", "../s/h/../../shapes.vol"),
            Path::new("../../shapes.vol")
        );
        assert_eq!(named(".", "v/a.vol"), Path::new("v/a.vol"));
        assert_eq!(named("", "./v/a.vol"), Path::new("v/a.vol"));
        assert_eq!(named("v", "v/a.vol"), Path::new("a.vol"));
        assert_eq!(named("../s/h", "v/a.vol"), Path::new("../../work/v/a.vol"));
        // Absolute paths stay; a file that is not there is named absolutely.
        assert_eq!(named("v", "/data/x.vol"), Path::new("/data/x.vol"));
        assert_eq!(named("v", "gone.vol"), cwd.join("gone.vol"));
        // Through a link, `..` is the link target's parent: absolute then.
        std::os::unix::fs::symlink(root.path().join("s/h"), cwd.join("link")).unwrap();
        let through = named("link", "v/a.vol");
        assert_eq!(through, cwd.join("v/a.vol"));
        assert_eq!(
            std::fs::canonicalize(cwd.join("link").join(&through)).unwrap(),
            std::fs::canonicalize(cwd.join("v/a.vol")).unwrap()
        );
    }

    #[test]
    fn a_link_to_a_missing_file_is_an_existing_output() {
        let dir = tempfile::tempdir().unwrap();
        let (file, dangling, free) = (
            dir.path().join("a.png"),
            dir.path().join("b.png"),
            dir.path().join("c.png"),
        );
        std::fs::write(&file, b"x").unwrap();
        std::os::unix::fs::symlink(dir.path().join("missing.png"), &dangling).unwrap();
        assert_eq!(
            existing_output(&file),
            Some("already exists (pass --force to replace it)")
        );
        assert!(
            existing_output(&dangling)
                .unwrap()
                .contains("link to a missing file")
        );
        assert_eq!(existing_output(&free), None);
    }

    /// What both command-line tools say of an output before any work, in
    /// order: a folder, an unwritable place (whatever `force` says), an
    /// existing file or link unless forced.
    #[test]
    fn outputs_are_checked_folder_place_then_existence() {
        let dir = tempfile::tempdir().unwrap();
        let (file, folder, free) = (
            dir.path().join("a.vol"),
            dir.path().join("d.vol"),
            dir.path().join("c.vol"),
        );
        std::fs::write(&file, b"x").unwrap();
        std::fs::create_dir(&folder).unwrap();
        for force in [false, true] {
            assert_eq!(
                output_problem(&folder, force).as_deref(),
                Some("is a directory; name a file")
            );
            let nowhere = output_problem(&dir.path().join("missing/x.vol"), force).unwrap();
            assert!(nowhere.starts_with("cannot write there: "), "{nowhere}");
            assert_eq!(output_problem(&free, force), None);
        }
        assert!(
            output_problem(&file, false)
                .unwrap()
                .contains("already exists")
        );
        assert_eq!(output_problem(&file, true), None);
        assert!(!dir.path().read_dir().unwrap().any(|e| {
            let name = e.unwrap().file_name();
            !["a.vol", "d.vol"].contains(&name.to_str().unwrap())
        }));
    }

    #[test]
    fn png_names_end_in_png_and_have_a_stem() {
        for ok in ["a.png", "dir/shot.PNG", "x.y.Png"] {
            assert_eq!(png_name_problem(Path::new(ok)), None, "{ok}");
        }
        assert_eq!(
            png_name_problem(Path::new("dir/.png")),
            Some("the image needs a name before .png")
        );
        for bad in ["a.jpg", "shot", "png", "a.png.tmp", "dir/"] {
            assert!(png_name_problem(Path::new(bad)).is_some(), "{bad}");
        }
    }

    #[test]
    fn stale_partials_of_dead_processes_are_removed_live_ones_kept() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("a.vol");
        // A pid that cannot exist (above the kernel's pid_max limit of 2^22).
        let dead = dir.path().join(".a.vol.99999999.AbC123.partial");
        let live = dir
            .path()
            .join(format!(".a.vol.{}.XyZ789.partial", std::process::id()));
        let other = dir.path().join(".b.vol.99999999.AbC123.partial");
        // A staged output's own partial file, of the same dead process.
        let nested = dir
            .path()
            .join("..a.vol.99999999.AbC123.partial.99999999.QrS456.partial");
        // Names like ours that are not (a dotted random part; two processes).
        let lookalikes = [
            ".a.vol.99999999.Ab.C.partial",
            "..a.vol.99999999.AbC123.partial.99999998.QrS456.partial",
        ]
        .map(|n| dir.path().join(n));
        for p in [&dead, &live, &other, &nested]
            .into_iter()
            .chain(&lookalikes)
        {
            std::fs::write(p, b"x").unwrap();
        }
        let tmp = temp_file_beside(&target).unwrap();
        let name = tmp
            .path()
            .file_name()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        assert!(
            name.starts_with(&format!(".a.vol.{}.", std::process::id())),
            "{name}"
        );
        assert!(!dead.exists());
        assert!(!nested.exists());
        assert!(lookalikes.iter().all(|p| p.exists()));
        assert!(live.exists());
        assert!(other.exists());
        let e = temp_file_beside(&dir.path().join("nodir/a.vol")).unwrap_err();
        assert!(e.to_string().contains("nodir"), "{e}");
        // A folder no file can be made in (even by root): the error is the
        // system's, without our temporary file's name.
        let e = temp_file_beside(Path::new("/proc/a.vol")).unwrap_err();
        assert!(!e.to_string().contains("partial"), "{e}");
    }

    #[test]
    fn free_space_is_checked_up_front() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("a.vol");
        assert!(check_free_space(&target, 1).is_ok());
        let e = check_free_space(&target, u64::MAX / 2).unwrap_err();
        assert!(e.to_string().contains("free"), "{e}");
        assert_eq!(human_bytes(999), "999 bytes");
        assert_eq!(human_bytes(1_500_000_000), "1.5 GB");
    }

    #[test]
    #[allow(unsafe_code)] // libc calls without a safe wrapper; SAFETY notes inside
    fn fifos_directories_and_devices_are_refused_without_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe.vol");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0);
        let e = open_regular(&fifo).unwrap_err();
        assert!(e.to_string().contains("named pipe"), "{e}");
        assert!(check_regular(&fifo).is_err());
        let e = open_regular(dir.path()).unwrap_err();
        assert!(e.to_string().contains("directory"), "{e}");
        let e = open_regular(Path::new("/dev/null")).unwrap_err();
        assert!(e.to_string().contains("device"), "{e}");
        let file = dir.path().join("a.txt");
        std::fs::write(&file, "hello").unwrap();
        assert_eq!(read_text(&file, 100).unwrap(), "hello");
        assert!(read_text(&file, 3).is_err());
        // Nor are they replaced by an output (its rename would turn them into
        // regular files): `--force` onto /dev/null once did.
        for (target, kind) in [
            (fifo.as_path(), "named pipe"),
            (Path::new("/dev/null"), "device"),
        ] {
            let e = temp_file_beside(target).unwrap_err();
            assert!(e.to_string().contains(kind), "{e}");
        }
        std::fs::create_dir(dir.path().join("d.png")).unwrap();
        let e = temp_file_beside(&dir.path().join("d.png")).unwrap_err();
        assert!(e.to_string().contains("directory"), "{e}");
        assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
        assert!(
            temp_file_beside(&file).is_ok(),
            "a regular file is replaced"
        );
    }
}
