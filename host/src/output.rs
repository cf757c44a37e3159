//! Writing results so that a failed, interrupted or concurrent run never leaves a mix of old and
//! new results (`docs/reliability.md`, "Results are never half-written").
//!
//! - A single result file ([`AtomicFile`], [`write_atomic`]) is written to a temporary file in
//!   the same directory (a fresh random name, created exclusively, through `tempfile`) and
//!   renamed over the final name. The target must be a new name or a regular file: a symbolic
//!   link, a directory or a device is refused, never followed or replaced.
//! - A result directory ([`ResultDir`]: `compare`, `sweep`, `mass-response --out`, `run --csv`)
//!   is rendered whole into a fresh temporary directory beside it and swapped in with one
//!   atomic exchange, under an advisory lock, so the directory is always the whole old set or
//!   the whole new set, and files of an earlier set that the new one lacks go with the swap.
//!   tribo only ever replaces a directory it wrote (marked by [`MARKER`]) or an empty one.
//!
//! On every error path the temporary file or directory is removed; only a process killed
//! outright can leave one behind (a dot-file beside the result), and the next run into the same
//! result directory removes it.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use tempfile::NamedTempFile;
use tribo_config::files::file_kind as kind;

/// The file that marks a directory as a tribo result set and lists its files (TOML).
pub const MARKER: &str = ".tribo-results";

/// The marker while it is being written, renamed over [`MARKER`] once whole: a run killed
/// while writing its marker never leaves a partial one (which would make its leftover
/// unrecognisable, and so never removed).
const MARKER_PART: &str = ".tribo-results.part";

/// Test hook: milliseconds to sleep after each file rendered into a result directory's
/// temporary directory, once more before the swap and once after it (before the old set is
/// removed), so a test can kill a run at any point of its write phase
/// (`tests/robustness/commit.rs`). Unset in normal use.
pub const PAUSE_ENV: &str = "TRIBO_TEST_WRITE_PAUSE_MS";

/// How long a run waits for another run that is writing into the same result directory
/// before it gives up (the write phase itself takes milliseconds).
pub const LOCK_WAIT: Duration = Duration::from_secs(60);

/// The suffix of a result directory's temporary directory: `.NAME.XXXXXX.tribo-tmp` beside it.
const TEMP_SUFFIX: &str = ".tribo-tmp";

/// The number of random characters in a temporary directory's name.
const TEMP_RANDOM: usize = 6;

/// The largest marker file read (a real one is a few hundred bytes).
const MARKER_MAX_BYTES: u64 = 1 << 20;

/// Why results could not be written. Every message names the path and what was expected.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The target is a symbolic link; results are never written through one.
    #[error("{target} is a symbolic link; tribo does not follow links when it writes results: give the real path")]
    Symlink {
        /// The target as the user gave it (with its option, e.g. `--out DIR`).
        target: String,
    },
    /// A result directory's target exists but is not a directory.
    #[error("{target} is {found}, not a directory; a result directory must be a new name, an empty directory or one tribo wrote")]
    NotADirectory {
        /// The target as the user gave it.
        target: String,
        /// What is there instead ("a regular file", "a character device", ...).
        found: &'static str,
    },
    /// A result file's target exists but is not a regular file.
    #[error("{target} is {found}, not a regular file; tribo writes a result file only to a new name or over a regular file")]
    NotARegularFile {
        /// The target as the user gave it.
        target: String,
        /// What is there instead.
        found: &'static str,
    },
    /// The target directory holds files tribo did not write: it is never swapped away.
    #[error("{target} exists and holds files tribo did not write ({names}); choose a new directory or empty it")]
    Foreign {
        /// The target as the user gave it.
        target: String,
        /// The first few files that are not part of a tribo result set.
        names: String,
    },
    /// The target has no final name (`.`, `..`, `/`).
    #[error("{target} does not name a file or directory (it is `.`, ends in `..` or is a root): give the result's path by name, e.g. results/run1")]
    NoName {
        /// The target as the user gave it.
        target: String,
    },
    /// The directory a result file goes into does not exist (it is not created for a file).
    #[error("cannot write {target}: the directory {parent} does not exist")]
    MissingParent {
        /// The target as the user gave it.
        target: String,
        /// Its directory.
        parent: PathBuf,
    },
    /// A file name inside a result set that is not a plain name (a bug in the caller).
    #[error(
        "`{name}` is not a plain file name for a result (no `/`, not `.` or `..`, no leading `.`)"
    )]
    BadFileName {
        /// The name given.
        name: String,
    },
    /// Another run holds the result directory's lock for longer than [`LOCK_WAIT`].
    #[error("another tribo run is still writing into {target} (it holds the lock {lock}); gave up after {waited_s} s")]
    Busy {
        /// The target as the user gave it.
        target: String,
        /// The lock file.
        lock: PathBuf,
        /// How long this run waited.
        waited_s: u64,
    },
    /// The lock file beside the result directory is not a regular file.
    #[error("the lock file {lock} is {found}; tribo needs a regular file there (remove it and run again)")]
    LockFile {
        /// The lock file.
        lock: PathBuf,
        /// What is there instead.
        found: &'static str,
    },
    /// The result directory changed while the new set was being written (another program put
    /// something there); nothing was replaced.
    #[error(
        "{target} changed while tribo was writing the new results ({what}); nothing was replaced"
    )]
    Changed {
        /// The target as the user gave it.
        target: String,
        /// What changed.
        what: String,
    },
    /// The test hook [`PAUSE_ENV`] holds something other than a whole number.
    #[error("{PAUSE_ENV}=`{value}` is not a whole number of milliseconds")]
    PauseHook {
        /// The variable's value.
        value: String,
    },
    /// A result could not be rendered (a plot or table failed).
    #[error("rendering {what}: {error}")]
    Render {
        /// The file being rendered.
        what: String,
        /// The renderer's error (in the message, so not also a `source`).
        error: std::io::Error,
    },
    /// A file-system operation failed.
    #[error("{action} {path}: {error}")]
    Io {
        /// What was being done ("creating", "writing", ...).
        action: &'static str,
        /// The file or directory concerned.
        path: PathBuf,
        /// The operating system's error (in the message, so not also a `source`).
        error: std::io::Error,
    },
}

/// An `OutputError::Io` for `action` on `path`.
fn io_err<'a>(
    action: &'static str,
    path: &'a Path,
) -> impl FnOnce(std::io::Error) -> OutputError + 'a {
    move |error| OutputError::Io {
        action,
        path: path.to_path_buf(),
        error,
    }
}

/// The target as messages show it: `--out DIR`, or the bare path when no option is known.
fn show(flag: &str, path: &Path) -> String {
    if flag.is_empty() {
        path.display().to_string()
    } else {
        format!("{flag} {}", path.display())
    }
}

/// The directory `path` lives in (`.` for a bare name).
fn parent_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Make what was renamed or created in `dir` durable. Best effort: some file systems refuse
/// to sync a directory, and the rename itself is already atomic.
fn sync_dir(dir: &Path) {
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

/// Check that a single result file may be written at `path`: a new name or a regular file,
/// never a symbolic link (not followed), a directory or a device.
fn check_file_target(path: &Path) -> Result<(), OutputError> {
    let target = show("", path);
    if path.file_name().is_none() {
        return Err(OutputError::NoName { target });
    }
    match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(io_err("inspecting", path)(e)),
        Ok(m) if m.file_type().is_symlink() => Err(OutputError::Symlink { target }),
        Ok(m) if m.is_file() => Ok(()),
        Ok(m) => Err(OutputError::NotARegularFile {
            target,
            found: kind(m.file_type()),
        }),
    }
}

/// Write `bytes` to `path` atomically (temporary file + rename). On error `path` is left as it
/// was and no temporary file remains; a target that is not a regular file is refused.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    let mut f = AtomicFile::create(path)?;
    f.write_all(bytes).map_err(io_err("writing", path))?;
    f.commit()
}

/// A file written under a temporary name and renamed into place by [`AtomicFile::commit`];
/// dropped without commit, or if the commit fails, the temporary file is removed and `path` is
/// untouched.
pub struct AtomicFile {
    /// The temporary file (removed when dropped unless persisted).
    file: BufWriter<NamedTempFile>,
    /// The final name.
    path: PathBuf,
    /// Removes the temporary file if tribo is interrupted (SIGINT, SIGTERM, SIGHUP).
    interrupted: Option<tribo_isolate::TempGuard>,
}

/// Check before a long computation that `out` can take a result set (given as `flag`, e.g.
/// `--out`): the same refusals as [`ResultDir::create`] (a link, file, device, or a directory
/// of files tribo did not write), without creating anything. The check is repeated at write.
pub fn check_result_dir(out: &Path, flag: &str) -> Result<(), OutputError> {
    let target = show(flag, out);
    let Some(name) = out.file_name().map(|n| n.to_string_lossy().into_owned()) else {
        return Err(OutputError::NoName { target });
    };
    let checked = std::time::SystemTime::now();
    inspect_settled(out, &target, &name)?;
    CHECKED
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .push((out.to_path_buf(), checked));
    Ok(())
}

/// When each result directory of this command was found fit to be replaced
/// ([`check_result_dir`], before any law ran): what appears in it after that, while the laws
/// run, was put there by one of them, not by the user.
static CHECKED: std::sync::Mutex<Vec<(PathBuf, std::time::SystemTime)>> =
    std::sync::Mutex::new(Vec::new());

/// Entries of result directories that appeared while the laws ran and were removed at
/// writing time: (directory, name).
static PLANTED: std::sync::Mutex<Vec<(PathBuf, String)>> = std::sync::Mutex::new(Vec::new());

/// The entries removed from result directory `out` at writing time because they appeared
/// while the laws ran (a law, or a process it started, wrote them), taken.
pub fn take_planted(out: &Path) -> Vec<String> {
    let mut all = PLANTED.lock().unwrap_or_else(|p| p.into_inner());
    let (mine, rest): (Vec<_>, Vec<_>) = std::mem::take(&mut *all)
        .into_iter()
        .partition(|(d, _)| d == out);
    *all = rest;
    mine.into_iter().map(|(_, n)| n).collect()
}

/// Whether the entry `path` of result directory `dir` appeared (its inode changed) after `dir`
/// was checked before the laws ran.
fn appeared_since_check(dir: &Path, path: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let Some(since) = CHECKED
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
            .find(|(d, _)| d == dir)
            .map(|(_, t)| *t)
        else {
            return false;
        };
        let Ok(since) = since.duration_since(std::time::UNIX_EPOCH) else {
            return false;
        };
        std::fs::symlink_metadata(path).is_ok_and(|m| {
            let ctime = std::time::Duration::new(
                u64::try_from(m.ctime()).unwrap_or(0),
                u32::try_from(m.ctime_nsec()).unwrap_or(0),
            );
            ctime >= since
        })
    }
    #[cfg(not(unix))]
    {
        let _ = (dir, path);
        false
    }
}

/// [`inspect`] without taking the lock, so a refusal creates nothing; but strangers seen while
/// another tribo run may be swapping its set in are looked at again under the lock that run
/// holds (only where a lock has been taken before, so no lock file is created for a refusal).
fn inspect_settled(out: &Path, target: &str, name: &str) -> Result<Existing, OutputError> {
    match inspect(out, target) {
        Err(e @ OutputError::Foreign { .. }) => {
            let lock = parent_of(out).join(format!(".{name}.lock"));
            if !std::fs::symlink_metadata(&lock).is_ok_and(|m| m.is_file()) {
                return Err(e);
            }
            let _held = DirLock::acquire(&lock, target, LOCK_WAIT)?;
            inspect(out, target)
        }
        other => other,
    }
}

/// Check before a long computation that `path` can take a single result file (a new name or a
/// regular file in an existing directory), without creating anything.
pub fn check_result_file(path: &Path) -> Result<(), OutputError> {
    check_file_target(path)?;
    let dir = parent_of(path);
    match std::fs::metadata(dir) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(m) => Err(OutputError::NotADirectory {
            target: show("", dir),
            found: kind(m.file_type()),
        }),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(OutputError::MissingParent {
            target: show("", path),
            parent: dir.to_path_buf(),
        }),
        Err(e) => Err(io_err("inspecting", dir)(e)),
    }
}

impl AtomicFile {
    /// Start writing `path`: its directory must exist (it is not created), and `path` must be a
    /// new name or a regular file (a link, directory, device or pipe is refused). A temporary
    /// file with a random name is created exclusively beside it.
    pub fn create(path: &Path) -> Result<Self, OutputError> {
        check_result_file(path)?;
        let dir = parent_of(path);
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let prefix = format!(".{name}.");
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(".tmp");
        // The result gets the permissions `File::create` would give (0666 less the umask), not
        // the temporary file's private 0600.
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            builder.permissions(std::fs::Permissions::from_mode(0o666));
        }
        let file = builder
            .tempfile_in(dir)
            .map_err(io_err("creating a temporary file in", dir))?;
        Ok(Self {
            interrupted: removed_if_interrupted(file.path()),
            file: BufWriter::new(file),
            path: path.to_path_buf(),
        })
    }

    /// Flush, sync and rename into place (atomic on one file system). On error the temporary
    /// file is removed and `path` keeps its previous content. The target is checked again just
    /// before the rename, so one that became a link or device meanwhile is not replaced.
    pub fn commit(mut self) -> Result<(), OutputError> {
        // From here the temporary file becomes the result: an interruption must not remove it.
        drop(self.interrupted.take());
        let path = self.path;
        let file = self
            .file
            .into_inner()
            .map_err(|e| io_err("writing", &path)(e.into_error()))?;
        file.as_file()
            .sync_all()
            .map_err(io_err("syncing", file.path()))?;
        check_file_target(&path)?;
        file.persist(&path)
            .map_err(|e| io_err("renaming the result into", &path)(e.error))?;
        sync_dir(parent_of(&path));
        Ok(())
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.file.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

/// A guard removing `path` if tribo is interrupted before the guard is dropped (Unix).
fn removed_if_interrupted(path: &Path) -> Option<tribo_isolate::TempGuard> {
    #[cfg(unix)]
    {
        Some(tribo_isolate::register_temp(path))
    }
    #[cfg(not(unix))]
    {
        let _ = path;
        None
    }
}

/// The content of [`MARKER`]: which command wrote the set and its files. Deterministic (no
/// time, no paths), so a result set is byte-identical from run to run.
#[derive(serde::Serialize, serde::Deserialize)]
struct Manifest {
    /// The subcommand that wrote the set (`compare`, `sweep`, ...).
    command: String,
    /// The files of the set, in the order written (the marker itself not included).
    files: Vec<String>,
    /// Each file's content checksum ([`checksum`]), in the order of `files`: a file is replaced
    /// (deleted) only if it still is what tribo wrote, so a marker made by hand, or a result
    /// file someone edited, never costs anyone a file. Absent in markers of older tribos, whose
    /// sets are then refused once.
    #[serde(default)]
    sums: Vec<String>,
}

/// The checksum recorded for a result file: its length and 64-bit FNV-1a hash, in hex. Not a
/// defence against a forger, but no file someone wrote or changed matches it by accident.
fn checksum(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{}:{h:016x}", bytes.len())
}

/// Whether the listed result `path` may go with the old set: a regular file whose content has
/// checksum `sum`, or a symbolic link (removing a link removes no one's data; what it points
/// to is never followed nor touched).
fn verified(path: &Path, sum: &str) -> bool {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => true,
        Ok(m) if m.is_file() => std::fs::read(path).is_ok_and(|b| checksum(&b) == sum),
        _ => false,
    }
}

/// The first line of [`MARKER`]: says what the file is to whoever opens the directory.
const MARKER_HEADER: &str = "# Written by tribo: this directory is one result set, replaced as a whole by the next\n# tribo run into it. tribo refuses to replace it if it holds files not listed below.\n";

/// The manifest of the tribo result set in `dir`, if `dir` holds a readable marker.
fn read_manifest(dir: &Path) -> Option<Manifest> {
    let path = dir.join(MARKER);
    let meta = std::fs::symlink_metadata(&path).ok()?;
    if !meta.is_file() {
        return None;
    }
    let mut text = String::new();
    File::open(&path)
        .ok()?
        .take(MARKER_MAX_BYTES)
        .read_to_string(&mut text)
        .ok()?;
    toml::from_str(&text).ok()
}

/// Whether the existing directory `dir` may be replaced: it is empty, or a tribo result set
/// holding only the files its marker lists. Anything else is refused naming a few strangers.
fn check_replaceable(dir: &Path, target: &str) -> Result<(), OutputError> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map_err(io_err("reading", dir))?
        .map(|e| {
            e.map(|e| e.file_name().to_string_lossy().into_owned())
                .map_err(io_err("reading", dir))
        })
        .collect::<Result<_, _>>()?;
    if names.is_empty() {
        return Ok(());
    }
    names.sort();
    // Entries that appeared while the laws ran were planted by a law (a user's files were
    // refused before the run): removed, never followed, and reported, so one law's mischief
    // does not cost the other sets their results.
    let (planted, names): (Vec<String>, Vec<String>) = names
        .into_iter()
        .partition(|n| n != MARKER && appeared_since_check(dir, &dir.join(n)));
    PLANTED
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .extend(planted.iter().map(|n| (dir.to_path_buf(), n.clone())));
    for n in &planted {
        let path = dir.join(n);
        let removed = std::fs::remove_dir_all(&path).or_else(|_| std::fs::remove_file(&path));
        let _ = writeln!(
            std::io::stderr(),
            "warning: {target}: `{n}` appeared there while the laws ran (a law wrote it); {}",
            if removed.is_ok() {
                "it was removed and the results written"
            } else {
                "it could not be removed"
            }
        );
    }
    // A file is tribo's only if the marker lists it with a checksum its content still has.
    let manifest = read_manifest(dir);
    let strangers: Vec<String> = match &manifest {
        Some(m) => names
            .iter()
            .filter(|n| n.as_str() != MARKER)
            .filter_map(|n| match m.files.iter().position(|f| f == n) {
                None => Some(n.clone()),
                Some(i) => match m.sums.get(i) {
                    Some(sum) if verified(&dir.join(n), sum) => None,
                    Some(_) => Some(format!("{n} (changed since tribo wrote it)")),
                    None => Some(format!("{n} (listed without a checksum)")),
                },
            })
            .collect(),
        None => names.clone(),
    };
    if strangers.is_empty() {
        return Ok(());
    }
    const SHOWN: usize = 5;
    let mut shown: Vec<String> = strangers
        .iter()
        .take(SHOWN)
        .map(|s| s.to_string())
        .collect();
    if strangers.len() > SHOWN {
        shown.push(format!("... {} in all", strangers.len()));
    }
    Err(OutputError::Foreign {
        target: target.to_string(),
        names: shown.join(", "),
    })
}

/// What is at a result directory's path before it is replaced.
#[derive(Debug, PartialEq, Eq)]
enum Existing {
    /// Nothing: the new set is renamed into place.
    Absent,
    /// An empty directory or a tribo result set: swapped with the new set.
    Replaceable,
}

/// Inspect `out` without following a link: absent, or a directory that may be replaced.
fn inspect(out: &Path, target: &str) -> Result<Existing, OutputError> {
    let existing = inspect_kind(out, target)?;
    if existing == Existing::Replaceable {
        check_replaceable(out, target)?;
    }
    Ok(existing)
}

/// What kind of thing is at `out` (without following a link): absent or a directory; a link,
/// file or device is refused. The directory's contents are not looked at.
fn inspect_kind(out: &Path, target: &str) -> Result<Existing, OutputError> {
    match std::fs::symlink_metadata(out) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Existing::Absent),
        Err(e) => Err(io_err("inspecting", out)(e)),
        Ok(m) if m.file_type().is_symlink() => Err(OutputError::Symlink {
            target: target.to_string(),
        }),
        Ok(m) if !m.is_dir() => Err(OutputError::NotADirectory {
            target: target.to_string(),
            found: kind(m.file_type()),
        }),
        Ok(_) => Ok(Existing::Replaceable),
    }
}

/// Whether `file` is the name of one of `name`'s temporary directories:
/// `.NAME.XXXXXX.tribo-tmp` with exactly six random letters or digits (so `.a.b.XXXXXX...`,
/// belonging to `a.b`, is not taken for one of `a`'s).
fn is_temp_name(file: &str, name: &str) -> bool {
    file.strip_prefix('.')
        .and_then(|f| f.strip_prefix(name))
        .and_then(|f| f.strip_prefix('.'))
        .and_then(|f| f.strip_suffix(TEMP_SUFFIX))
        .is_some_and(|r| r.len() == TEMP_RANDOM && r.bytes().all(|b| b.is_ascii_alphanumeric()))
}

/// Remove temporary directories left beside `out` by runs that were killed. Called with the
/// lock held, so none of them belongs to a live run. Only real directories (never a link) that
/// carry the marker are removed whole; an empty one is removed; anything else is left alone.
/// Failures are ignored: a leftover harms nothing and the next run tries again.
fn remove_stale_temps(parent: &Path, name: &str) {
    let Ok(entries) = std::fs::read_dir(parent) else {
        return;
    };
    for entry in entries.flatten() {
        let file = entry.file_name();
        let Some(file) = file.to_str() else { continue };
        if !is_temp_name(file, name) {
            continue;
        }
        let path = parent.join(file);
        let Ok(meta) = std::fs::symlink_metadata(&path) else {
            continue;
        };
        if !meta.is_dir() {
            continue;
        }
        if read_manifest(&path).is_some() {
            let _ = remove_set(&path);
        } else {
            // Killed before its first marker was whole: removed only if nothing but tribo's
            // own marker files is in it.
            remove_unmarked(&path);
        }
    }
}

/// Remove the temporary directory `dir` that holds no readable marker if it is empty or holds
/// only regular files under the marker's two names (a run killed while writing its first
/// marker); anything else in it and it is left alone.
fn remove_unmarked(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut ours = Vec::new();
    for entry in entries {
        let Ok(entry) = entry else { return };
        let name = entry.file_name();
        let is_file = entry.file_type().is_ok_and(|t| t.is_file());
        if !is_file || (name != MARKER && name != MARKER_PART) {
            return;
        }
        ours.push(entry.path());
    }
    for file in ours {
        let _ = std::fs::remove_file(file);
    }
    let _ = std::fs::remove_dir(dir);
}

/// Remove the result set `dir` (a real directory holding a marker) so that an interruption at
/// any point leaves something [`remove_stale_temps`] recognises: the files first, then the
/// marker, then the empty directory. Never follows a link (a link inside is removed as a link;
/// std's `remove_dir_all` does not follow links either).
fn remove_set(dir: &Path) -> std::io::Result<()> {
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        if entry.file_name() == MARKER {
            continue;
        }
        let path = entry.path();
        if std::fs::symlink_metadata(&path)?.is_dir() {
            std::fs::remove_dir_all(&path)?;
        } else {
            std::fs::remove_file(&path)?;
        }
    }
    match std::fs::remove_file(dir.join(MARKER)) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e),
        _ => {}
    }
    std::fs::remove_dir(dir)
}

/// The advisory lock beside a result directory (`.NAME.lock` in its parent, never inside it,
/// since the directory itself is swapped). Held from before rendering until the swap is done;
/// released when dropped (or when the process dies). The lock file itself stays.
struct DirLock {
    /// The open lock file (the lock lives as long as it is open).
    #[cfg(unix)]
    _file: File,
}

impl DirLock {
    /// Take the lock `lock`, waiting up to `wait` for another run to release it.
    #[cfg(unix)]
    fn acquire(lock: &Path, target: &str, wait: Duration) -> Result<Self, OutputError> {
        use rustix::fs::{flock, FlockOperation};
        use std::os::unix::fs::OpenOptionsExt;
        // Never through a link (O_NOFOLLOW), never blocking on a FIFO planted there
        // (O_NONBLOCK), then refused unless it is a regular file.
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .mode(0o666)
            .custom_flags(
                (rustix::fs::OFlags::NOFOLLOW | rustix::fs::OFlags::NONBLOCK).bits() as i32,
            )
            .open(lock)
            .map_err(|e| match std::fs::symlink_metadata(lock) {
                Ok(m) if !m.is_file() => OutputError::LockFile {
                    lock: lock.to_path_buf(),
                    found: kind(m.file_type()),
                },
                _ => io_err("opening the lock file", lock)(e),
            })?;
        let meta = file.metadata().map_err(io_err("inspecting", lock))?;
        if !meta.is_file() {
            return Err(OutputError::LockFile {
                lock: lock.to_path_buf(),
                found: kind(meta.file_type()),
            });
        }
        let start = Instant::now();
        loop {
            match flock(&file, FlockOperation::NonBlockingLockExclusive) {
                Ok(()) => return Ok(Self { _file: file }),
                Err(e) if e == rustix::io::Errno::WOULDBLOCK || e == rustix::io::Errno::INTR => {
                    if start.elapsed() >= wait {
                        return Err(OutputError::Busy {
                            target: target.to_string(),
                            lock: lock.to_path_buf(),
                            waited_s: start.elapsed().as_secs(),
                        });
                    }
                    std::thread::sleep(Duration::from_millis(10));
                }
                Err(e) => return Err(io_err("locking", lock)(e.into())),
            }
        }
    }

    /// No advisory lock off Unix (documented in `docs/reliability.md`).
    #[cfg(not(unix))]
    fn acquire(_lock: &Path, _target: &str, _wait: Duration) -> Result<Self, OutputError> {
        Ok(Self {})
    }
}

/// Sleep for the test hook's pause, if any (none in normal use).
fn hook_pause(pause: Duration) {
    if !pause.is_zero() {
        std::thread::sleep(pause);
    }
}

/// The pause of the [`PAUSE_ENV`] test hook (zero when unset).
fn pause_from_env() -> Result<Duration, OutputError> {
    match std::env::var(PAUSE_ENV) {
        Err(_) => Ok(Duration::ZERO),
        Ok(v) => v
            .trim()
            .parse::<u64>()
            .map(Duration::from_millis)
            .map_err(|_| OutputError::PauseHook { value: v }),
    }
}

/// A result directory written as a whole: files go into a fresh temporary directory beside the
/// target (random name, created exclusively), and [`ResultDir::commit`] swaps it in with one
/// atomic exchange. Until then the target is untouched; dropped without commit, or on any
/// error, the temporary directory is removed. An advisory lock serialises runs into one target.
pub struct ResultDir {
    /// The temporary directory the set is rendered into (removed when dropped unless kept).
    /// Declared before the lock so it is removed before the lock is released.
    temp: tempfile::TempDir,
    /// The final path.
    out: PathBuf,
    /// The target as messages show it (`--out DIR`).
    target: String,
    /// The manifest written into the marker at commit.
    manifest: Manifest,
    /// The test hook's pause after each file and before the swap.
    pause: Duration,
    /// The advisory lock on `out`.
    _lock: DirLock,
    /// Removes the temporary directory if tribo is interrupted (SIGINT, SIGTERM, SIGHUP).
    interrupted: Option<tribo_isolate::TempGuard>,
}

impl ResultDir {
    /// Start a result set for `out`, written by `command` (recorded in the marker) and given by
    /// the user as `flag` (for messages, e.g. `--out`). `out` must be a new name, an empty
    /// directory or a directory tribo wrote; a link, file or device is refused. Its parent is
    /// created if missing. Waits up to [`LOCK_WAIT`] for another run writing into `out`.
    pub fn create(out: &Path, command: &str, flag: &str) -> Result<Self, OutputError> {
        Self::create_with(out, command, flag, LOCK_WAIT)
    }

    /// [`ResultDir::create`] with another wait for the lock.
    fn create_with(
        out: &Path,
        command: &str,
        flag: &str,
        wait: Duration,
    ) -> Result<Self, OutputError> {
        let target = show(flag, out);
        let pause = pause_from_env()?;
        let Some(name) = out.file_name().map(|n| n.to_string_lossy().into_owned()) else {
            return Err(OutputError::NoName { target });
        };
        let parent = parent_of(out);
        // Refused before anything is created (not even the lock file, which would otherwise
        // land beside a device such as /dev/null); strangers are confirmed under the lock.
        inspect_settled(out, &target, &name)?;
        std::fs::create_dir_all(parent).map_err(io_err("creating", parent))?;
        let lock = DirLock::acquire(&parent.join(format!(".{name}.lock")), &target, wait)?;
        // Checked under the lock, so no other tribo run changes it until the swap.
        inspect(out, &target)?;
        remove_stale_temps(parent, &name);
        let prefix = format!(".{name}.");
        let mut builder = tempfile::Builder::new();
        builder
            .prefix(&prefix)
            .suffix(TEMP_SUFFIX)
            .rand_bytes(TEMP_RANDOM);
        // The directory gets the permissions `create_dir` would give (0777 less the umask).
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            builder.permissions(std::fs::Permissions::from_mode(0o777));
        }
        let temp = builder
            .tempdir_in(parent)
            .map_err(io_err("creating a temporary directory in", parent))?;
        let dir = Self {
            interrupted: removed_if_interrupted(temp.path()),
            temp,
            out: out.to_path_buf(),
            target,
            manifest: Manifest {
                command: command.to_string(),
                files: Vec::new(),
                sums: Vec::new(),
            },
            pause,
            _lock: lock,
        };
        // Marked from the start, so a run killed midway leaves a directory the next run
        // recognises as its own leftover.
        dir.write_marker()?;
        Ok(dir)
    }

    /// The final path of the result set.
    pub fn path(&self) -> &Path {
        &self.out
    }

    /// The names of the files written so far, in order.
    pub fn files(&self) -> &[String] {
        &self.manifest.files
    }

    /// Write the marker (the manifest so far) into the temporary directory, replacing any:
    /// written whole under [`MARKER_PART`], then renamed over it, so a kill at any instant
    /// leaves the previous marker or the new one, never a partial one.
    fn write_marker(&self) -> Result<(), OutputError> {
        let part = self.temp.path().join(MARKER_PART);
        let path = self.temp.path().join(MARKER);
        let body = toml::to_string(&self.manifest).map_err(|e| OutputError::Render {
            what: MARKER.into(),
            error: std::io::Error::other(e),
        })?;
        // The temporary directory is this run's own, so the file is simply (re)written.
        let mut f = File::create(&part).map_err(io_err("creating", &part))?;
        f.write_all(MARKER_HEADER.as_bytes())
            .and_then(|()| f.write_all(body.as_bytes()))
            .and_then(|()| f.sync_all())
            .map_err(io_err("writing", &part))?;
        std::fs::rename(&part, &path).map_err(io_err("renaming the marker into", &path))
    }

    /// Add the file `name` (a plain name: no `/`, not hidden) with `bytes` to the set. Written
    /// into the temporary directory only, created exclusively and synced.
    pub fn write(&mut self, name: &str, bytes: &[u8]) -> Result<(), OutputError> {
        let plain = !name.is_empty()
            && !name.starts_with('.')
            && !name.contains('/')
            && !name.contains('\\')
            && !name.contains('\0');
        if !plain {
            return Err(OutputError::BadFileName {
                name: name.to_string(),
            });
        }
        let path = self.temp.path().join(name);
        let mut options = OpenOptions::new();
        options.write(true).create_new(true);
        #[cfg(unix)]
        {
            use std::os::unix::fs::OpenOptionsExt;
            options.mode(0o666);
        }
        let mut f = options.open(&path).map_err(io_err("creating", &path))?;
        f.write_all(bytes)
            .and_then(|()| f.sync_all())
            .map_err(io_err("writing", &path))?;
        self.manifest.files.push(name.to_string());
        self.manifest.sums.push(checksum(bytes));
        hook_pause(self.pause);
        Ok(())
    }

    /// Replace the target with the new set in one step. If the target did not exist the set is
    /// renamed into place (refusing to replace anything created meanwhile); otherwise the two
    /// are exchanged atomically (Linux `renameat2(RENAME_EXCHANGE)`) and the old set, now under
    /// the temporary name, is removed. On error the target is as it was and the temporary
    /// directory is removed.
    pub fn commit(mut self) -> Result<(), OutputError> {
        // From here the set is swapped in: an interruption leaves its temporary directory to
        // the next run (as a kill would), never half-removed under the swap.
        drop(self.interrupted.take());
        self.write_marker()?;
        sync_dir(self.temp.path());
        hook_pause(self.pause);
        // Checked again: a program other than tribo (which would wait for the lock) may have
        // put something there since `create`.
        let existing = inspect(&self.out, &self.target)?;
        let parent = parent_of(&self.out).to_path_buf();
        swap(self.temp, &self.out, &self.target, existing, self.pause)?;
        sync_dir(&parent);
        Ok(())
    }
}

/// Put the set in `temp` at `out`. See [`ResultDir::commit`].
#[cfg(any(target_os = "linux", target_os = "android"))]
fn swap(
    temp: tempfile::TempDir,
    out: &Path,
    target: &str,
    existing: Existing,
    pause: Duration,
) -> Result<(), OutputError> {
    use rustix::fs::{renameat_with, RenameFlags, CWD};
    let exchange = || {
        renameat_with(CWD, temp.path(), CWD, out, RenameFlags::EXCHANGE)
            .map_err(|e| io_err("swapping the new results into", out)(e.into()))
    };
    match existing {
        Existing::Absent => {
            match renameat_with(CWD, temp.path(), CWD, out, RenameFlags::NOREPLACE) {
                Ok(()) => {
                    // The set now lives at `out`: the temporary name is gone, nothing to remove.
                    let _ = temp.keep();
                    Ok(())
                }
                Err(e) if e == rustix::io::Errno::EXIST => Err(OutputError::Changed {
                    target: target.to_string(),
                    what: "it was created by another program".into(),
                }),
                Err(e) => Err(io_err("renaming the new results into", out)(e.into())),
            }
        }
        Existing::Replaceable => {
            exchange()?;
            // The old set is now under the temporary name. Whatever was swapped out must be
            // what `inspect` approved (a link or a stranger's directory put there in the
            // meantime is swapped back, untouched).
            let old_ok = std::fs::symlink_metadata(temp.path()).is_ok_and(|m| m.is_dir())
                && check_replaceable(temp.path(), target).is_ok();
            if !old_ok {
                exchange()?;
                return Err(OutputError::Changed {
                    target: target.to_string(),
                    what: "it was replaced by something tribo did not write".into(),
                });
            }
            hook_pause(pause);
            // Removing the old set: if that fails or is interrupted the new set is still whole,
            // and the next run removes the leftover (marked or empty, under the temporary name).
            let _ = remove_set(temp.path());
            drop(temp);
            Ok(())
        }
    }
}

/// Put the set in `temp` at `out` without an atomic exchange (systems without
/// `renameat2`): the old set is renamed aside, then the new one into place. A kill between the
/// two renames leaves no `out` and the old set under a temporary name (`docs/reliability.md`).
#[cfg(not(any(target_os = "linux", target_os = "android")))]
fn swap(
    temp: tempfile::TempDir,
    out: &Path,
    _target: &str,
    existing: Existing,
    _pause: Duration,
) -> Result<(), OutputError> {
    if existing == Existing::Replaceable {
        let parent = parent_of(out);
        let name = out
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        // A fresh name for the old set: created exclusively, then freed for the rename.
        let aside = tempfile::Builder::new()
            .prefix(&format!(".{name}."))
            .suffix(TEMP_SUFFIX)
            .rand_bytes(TEMP_RANDOM)
            .tempdir_in(parent)
            .map_err(io_err("creating a temporary directory in", parent))?
            .keep();
        std::fs::remove_dir(&aside).map_err(io_err("removing", &aside))?;
        std::fs::rename(out, &aside).map_err(io_err("moving the old results aside from", out))?;
        if let Err(e) = std::fs::rename(temp.path(), out) {
            let _ = std::fs::rename(&aside, out);
            return Err(io_err("renaming the new results into", out)(e));
        }
        let _ = temp.keep();
        let _ = std::fs::remove_dir_all(&aside);
        return Ok(());
    }
    std::fs::rename(temp.path(), out).map_err(io_err("renaming the new results into", out))?;
    let _ = temp.keep();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Names in `dir`, sorted.
    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .expect("read dir")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn commit_replaces_the_file_and_leaves_nothing_else() {
        let dir = tempfile::tempdir().expect("temporary directory");
        let path = dir.path().join("out.csv");
        std::fs::write(&path, "old").expect("write");
        write_atomic(&path, b"new").expect("atomic write");
        assert_eq!(std::fs::read(&path).expect("read"), b"new");
        assert_eq!(names(dir.path()), ["out.csv"]);
    }

    #[cfg(unix)]
    #[test]
    fn the_result_has_ordinary_permissions_not_the_temporary_files() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().expect("temporary directory");
        let atomic = dir.path().join("atomic.txt");
        let plain = dir.path().join("plain.txt");
        write_atomic(&atomic, b"x").expect("atomic write");
        std::fs::write(&plain, b"x").expect("plain write");
        let mode = |p: &Path| std::fs::metadata(p).expect("metadata").permissions().mode();
        assert_eq!(mode(&atomic) & 0o777, mode(&plain) & 0o777);
    }

    #[test]
    fn dropped_without_commit_the_previous_file_stays_and_no_temporary_remains() {
        let dir = tempfile::tempdir().expect("temporary directory");
        let path = dir.path().join("out.json");
        std::fs::write(&path, "previous").expect("write");
        {
            let mut f = AtomicFile::create(&path).expect("create");
            f.write_all(b"half a result").expect("write");
            assert_eq!(
                names(dir.path()).len(),
                2,
                "the temporary file exists while writing"
            );
        }
        assert_eq!(std::fs::read_to_string(&path).expect("read"), "previous");
        assert_eq!(names(dir.path()), ["out.json"]);
    }

    #[test]
    fn a_failed_rename_leaves_the_target_intact_and_no_temporary_file() {
        // The final name is a non-empty directory: refused, nothing written.
        let dir = tempfile::tempdir().expect("temporary directory");
        let path = dir.path().join("results");
        std::fs::create_dir(&path).expect("mkdir");
        std::fs::write(path.join("kept.txt"), "kept").expect("write");
        let err = write_atomic(&path, b"data").expect_err("cannot rename over a directory");
        assert!(!err.to_string().is_empty());
        assert_eq!(names(dir.path()), ["results"]);
        assert_eq!(
            std::fs::read_to_string(path.join("kept.txt")).expect("read"),
            "kept"
        );
    }

    #[test]
    fn a_missing_directory_is_an_error_not_a_panic() {
        let dir = tempfile::tempdir().expect("temporary directory");
        let path = dir.path().join("no-such-dir").join("out.csv");
        let err = write_atomic(&path, b"x").expect_err("no directory");
        assert!(matches!(err, OutputError::MissingParent { .. }), "{err}");
        assert!(err.to_string().contains("no-such-dir"), "{err}");
        assert!(names(dir.path()).is_empty());
    }

    #[test]
    fn a_bare_file_name_is_written_in_the_current_directory() {
        let f = AtomicFile::create(Path::new("relative-name.txt")).expect("create in .");
        drop(f);
        assert!(!Path::new("relative-name.txt").exists());
    }

    #[test]
    fn a_directory_target_is_refused_before_anything_is_written() {
        let dir = tempfile::tempdir().expect("temporary directory");
        let err = AtomicFile::create(dir.path()).err().expect("a directory");
        assert!(
            err.to_string()
                .contains("is a directory, not a regular file"),
            "{err}"
        );
    }

    #[cfg(unix)]
    #[test]
    fn a_symlinked_file_target_is_refused_and_its_target_untouched() {
        let dir = tempfile::tempdir().expect("temporary directory");
        let victim = dir.path().join("victim.txt");
        std::fs::write(&victim, "precious").expect("write");
        let link = dir.path().join("result.toml");
        std::os::unix::fs::symlink(&victim, &link).expect("symlink");
        let err = write_atomic(&link, b"overwritten").expect_err("a link");
        assert!(matches!(err, OutputError::Symlink { .. }), "{err}");
        assert!(err.to_string().contains("symbolic link"), "{err}");
        assert_eq!(std::fs::read_to_string(&victim).expect("read"), "precious");
        assert!(std::fs::symlink_metadata(&link)
            .expect("link")
            .file_type()
            .is_symlink());
        assert_eq!(names(dir.path()), ["result.toml", "victim.txt"]);
    }

    #[cfg(unix)]
    #[test]
    fn devices_and_pipes_are_refused_as_file_targets() {
        use std::os::unix::fs::FileTypeExt;
        let err = write_atomic(Path::new("/dev/null"), b"x").expect_err("a device");
        assert!(
            err.to_string().contains("/dev/null is a character device"),
            "{err}"
        );
        let meta = std::fs::symlink_metadata("/dev/null").expect("/dev/null");
        assert!(meta.file_type().is_char_device());

        let dir = tempfile::tempdir().expect("temporary directory");
        let fifo = dir.path().join("fifo");
        rustix::fs::mknodat(
            rustix::fs::CWD,
            &fifo,
            rustix::fs::FileType::Fifo,
            rustix::fs::Mode::from_raw_mode(0o600),
            0,
        )
        .expect("mkfifo");
        let err = write_atomic(&fifo, b"x").expect_err("a pipe");
        assert!(err.to_string().contains("a FIFO"), "{err}");
        assert_eq!(names(dir.path()), ["fifo"]);
    }

    /// A result set with `files` (name, content) committed to `out` by a fresh `ResultDir`.
    fn commit_set(out: &Path, files: &[(&str, &str)]) -> Result<(), OutputError> {
        let mut r = ResultDir::create(out, "test", "--out")?;
        for (name, text) in files {
            r.write(name, text.as_bytes())?;
        }
        r.commit()
    }

    /// Every file in `dir` but the marker, with its content.
    fn contents(dir: &Path) -> Vec<(String, String)> {
        names(dir)
            .into_iter()
            .filter(|n| n != MARKER)
            .map(|n| {
                let text = std::fs::read_to_string(dir.join(&n)).expect("read");
                (n, text)
            })
            .collect()
    }

    #[test]
    fn a_hand_made_marker_or_an_edited_file_never_gets_a_users_file_deleted() {
        let dir = tempfile::tempdir().expect("temp dir");
        let out = dir.path().join("results");
        std::fs::create_dir(&out).expect("mkdir");
        std::fs::write(out.join("thesis.docx"), "years of work").expect("write");
        for marker in [
            "command = \"compare\"\nfiles = [\"thesis.docx\"]\n",
            "command = \"compare\"\nfiles = [\"thesis.docx\"]\nsums = [\"13:0000000000000000\"]\n",
        ] {
            std::fs::write(out.join(MARKER), marker).expect("write");
            let e = commit_set(&out, &[("a.csv", "1")]).expect_err("refused");
            assert!(e.to_string().contains("thesis.docx"), "{e}");
            assert_eq!(
                std::fs::read_to_string(out.join("thesis.docx")).expect("kept"),
                "years of work"
            );
        }
        // A set tribo wrote, then a file edited by hand: refused, the edit kept.
        let set = dir.path().join("set");
        commit_set(&set, &[("a.csv", "1"), ("b.csv", "2")]).expect("first set");
        std::fs::write(set.join("b.csv"), "my notes").expect("edit");
        let e = commit_set(&set, &[("a.csv", "3")]).expect_err("refused");
        assert!(
            e.to_string()
                .contains("b.csv (changed since tribo wrote it)"),
            "{e}"
        );
        assert_eq!(
            std::fs::read_to_string(set.join("b.csv")).expect("kept"),
            "my notes"
        );
        // Untouched, it is replaced as before.
        std::fs::write(set.join("b.csv"), "2").expect("restore");
        commit_set(&set, &[("a.csv", "3")]).expect("replaced");
        assert_eq!(contents(&set), [("a.csv".to_string(), "3".to_string())]);
    }

    #[test]
    fn a_new_set_replaces_the_old_one_whole_and_stale_files_go() {
        let parent = tempfile::tempdir().expect("temporary directory");
        let out = parent.path().join("res");
        commit_set(&out, &[("a.csv", "1"), ("plot_x.svg", "x")]).expect("first set");
        assert_eq!(names(&out), [MARKER, "a.csv", "plot_x.svg"]);
        commit_set(&out, &[("a.csv", "2"), ("plot_y.svg", "y")]).expect("second set");
        assert_eq!(
            contents(&out),
            [
                ("a.csv".into(), "2".into()),
                ("plot_y.svg".into(), "y".into())
            ]
        );
        let manifest = read_manifest(&out).expect("marker");
        assert_eq!(manifest.files, ["a.csv", "plot_y.svg"]);
        assert_eq!(manifest.command, "test");
        // Beside it only the lock file: no temporary directory, no old set.
        assert_eq!(names(parent.path()), [".res.lock", "res"]);
    }

    #[test]
    fn an_empty_existing_directory_and_a_missing_parent_are_fine() {
        let parent = tempfile::tempdir().expect("temporary directory");
        let empty = parent.path().join("empty");
        std::fs::create_dir(&empty).expect("mkdir");
        commit_set(&empty, &[("a.csv", "1")]).expect("into an empty directory");
        assert_eq!(contents(&empty), [("a.csv".into(), "1".into())]);
        let deep = parent.path().join("x").join("y").join("res");
        commit_set(&deep, &[("a.csv", "1")]).expect("parents created");
        assert_eq!(contents(&deep), [("a.csv".into(), "1".into())]);
    }

    #[test]
    fn a_directory_with_files_tribo_did_not_write_is_refused_untouched() {
        let parent = tempfile::tempdir().expect("temporary directory");
        let out = parent.path().join("home");
        std::fs::create_dir(&out).expect("mkdir");
        std::fs::write(out.join("thesis.tex"), "years of work").expect("write");
        let err = commit_set(&out, &[("a.csv", "1")]).expect_err("not ours");
        let msg = err.to_string();
        assert!(
            msg.contains("--out") && msg.contains("holds files tribo did not write"),
            "{msg}"
        );
        assert!(
            msg.contains("thesis.tex") && msg.contains("choose a new directory"),
            "{msg}"
        );
        assert_eq!(names(&out), ["thesis.tex"]);
        assert_eq!(
            std::fs::read_to_string(out.join("thesis.tex")).expect("read"),
            "years of work"
        );
        // Refused before anything was created beside it.
        assert_eq!(names(parent.path()), ["home"]);

        // A tribo set to which a file was added by hand is refused too (the file would go).
        let set = parent.path().join("set");
        commit_set(&set, &[("a.csv", "1")]).expect("first set");
        std::fs::write(set.join("notes.txt"), "mine").expect("write");
        let err = commit_set(&set, &[("a.csv", "2")]).expect_err("a stranger inside");
        assert!(err.to_string().contains("notes.txt"), "{err}");
        assert_eq!(
            std::fs::read_to_string(set.join("a.csv")).expect("read"),
            "1"
        );
    }

    #[test]
    fn dot_and_root_are_refused_as_result_directories() {
        for p in [".", "..", "/", "a/.."] {
            let err = ResultDir::create(Path::new(p), "test", "--out")
                .err()
                .expect("no name");
            assert!(matches!(err, OutputError::NoName { .. }), "{p}: {err}");
        }
    }

    #[cfg(unix)]
    #[test]
    fn a_link_a_file_or_a_device_as_result_directory_is_refused() {
        let parent = tempfile::tempdir().expect("temporary directory");
        let real = parent.path().join("real");
        commit_set(&real, &[("a.csv", "1")]).expect("a real set");
        let link = parent.path().join("link");
        std::os::unix::fs::symlink(&real, &link).expect("symlink");
        let err = commit_set(&link, &[("a.csv", "2")]).expect_err("a link");
        assert!(matches!(err, OutputError::Symlink { .. }), "{err}");
        assert_eq!(contents(&real), [("a.csv".into(), "1".into())]);
        assert!(std::fs::symlink_metadata(&link)
            .expect("link")
            .file_type()
            .is_symlink());

        let file = parent.path().join("file");
        std::fs::write(&file, "data").expect("write");
        let err = commit_set(&file, &[("a.csv", "2")]).expect_err("a file");
        assert!(
            err.to_string()
                .contains("is a regular file, not a directory"),
            "{err}"
        );
        assert_eq!(std::fs::read_to_string(&file).expect("read"), "data");

        let err = commit_set(Path::new("/dev/null"), &[("a.csv", "2")]).expect_err("a device");
        assert!(err.to_string().contains("character device"), "{err}");
        // Refused before anything was created beside it, not even the lock file.
        assert!(std::fs::symlink_metadata("/dev/.null.lock").is_err());
        assert_eq!(names(parent.path()), [".real.lock", "file", "link", "real"]);
    }

    #[test]
    fn dropped_without_commit_the_old_set_stays_and_no_temporary_remains() {
        let parent = tempfile::tempdir().expect("temporary directory");
        let out = parent.path().join("res");
        commit_set(&out, &[("a.csv", "1")]).expect("first set");
        {
            let mut r = ResultDir::create(&out, "test", "--out").expect("create");
            r.write("a.csv", b"2").expect("write");
            r.write("b.csv", b"2").expect("write");
            assert_eq!(names(parent.path()).len(), 3, "lock, set and temporary");
        }
        assert_eq!(contents(&out), [("a.csv".into(), "1".into())]);
        assert_eq!(names(parent.path()), [".res.lock", "res"]);
    }

    #[test]
    fn a_commit_that_finds_the_directory_changed_replaces_nothing_and_cleans_up() {
        let parent = tempfile::tempdir().expect("temporary directory");
        let out = parent.path().join("res");
        commit_set(&out, &[("a.csv", "1")]).expect("first set");
        let mut r = ResultDir::create(&out, "test", "--out").expect("create");
        r.write("a.csv", b"2").expect("write");
        // Another program (not tribo: it takes no lock) adds a file meanwhile.
        std::fs::write(out.join("late.txt"), "late").expect("write");
        let err = r.commit().expect_err("changed");
        assert!(err.to_string().contains("late.txt"), "{err}");
        assert_eq!(names(&out), [MARKER, "a.csv", "late.txt"]);
        assert_eq!(
            std::fs::read_to_string(out.join("a.csv")).expect("read"),
            "1"
        );
        assert_eq!(names(parent.path()), [".res.lock", "res"]);
    }

    #[test]
    fn file_names_inside_a_set_must_be_plain() {
        let parent = tempfile::tempdir().expect("temporary directory");
        let out = parent.path().join("res");
        let mut r = ResultDir::create(&out, "test", "--out").expect("create");
        for bad in ["", "../x", "a/b", ".hidden", MARKER, ".."] {
            let err = r.write(bad, b"x").expect_err(bad);
            assert!(
                matches!(err, OutputError::BadFileName { .. }),
                "{bad}: {err}"
            );
        }
        drop(r);
        assert!(!out.exists());
        assert!(!parent.path().join("x").exists());
    }

    #[test]
    fn a_second_writer_waits_for_the_lock_and_gives_up_clearly() {
        let parent = tempfile::tempdir().expect("temporary directory");
        let out = parent.path().join("res");
        let held = ResultDir::create(&out, "test", "--out").expect("first writer");
        let start = Instant::now();
        let err = ResultDir::create_with(&out, "test", "--out", Duration::from_millis(300))
            .err()
            .expect("the lock is held");
        assert!(start.elapsed() >= Duration::from_millis(300));
        assert!(matches!(err, OutputError::Busy { .. }), "{err}");
        assert!(err.to_string().contains(".res.lock"), "{err}");
        // Released by the first writer, the lock is taken at once.
        drop(held);
        let second = ResultDir::create_with(&out, "test", "--out", Duration::ZERO);
        assert!(second.is_ok());
    }

    #[test]
    fn leftovers_of_killed_runs_are_removed_and_nothing_else() {
        let parent = tempfile::tempdir().expect("temporary directory");
        let p = parent.path();
        // A killed run's half-written set (marked) and one killed before its marker (empty).
        let marked = p.join(".res.Ab12Cd.tribo-tmp");
        std::fs::create_dir(&marked).expect("mkdir");
        std::fs::write(marked.join(MARKER), "command = \"x\"\nfiles = []\n").expect("write");
        std::fs::write(marked.join("a.csv"), "half").expect("write");
        let empty = p.join(".res.ZZ99zz.tribo-tmp");
        std::fs::create_dir(&empty).expect("mkdir");
        // Killed while writing its first marker: a partial one under the writing name, or an
        // empty one under the marker's own name (as an older tribo could leave).
        let partial = p.join(".res.Pp00pp.tribo-tmp");
        std::fs::create_dir(&partial).expect("mkdir");
        std::fs::write(partial.join(MARKER_PART), "# Written by tri").expect("write");
        let truncated = p.join(".res.Tt00tt.tribo-tmp");
        std::fs::create_dir(&truncated).expect("mkdir");
        std::fs::write(truncated.join(MARKER), "").expect("write");
        // Not a leftover to remove: an unreadable marker beside a file it does not vouch for.
        let unvouched = p.join(".res.Uu00uu.tribo-tmp");
        std::fs::create_dir(&unvouched).expect("mkdir");
        std::fs::write(unvouched.join(MARKER), "").expect("write");
        std::fs::write(unvouched.join("keep.txt"), "keep").expect("write");
        // Not leftovers: another result's temporary (`res.b`), an unmarked non-empty directory
        // and a link matching the pattern, pointing at a directory that must survive.
        let other = p.join(".res.b.Ab12Cd.tribo-tmp");
        std::fs::create_dir(&other).expect("mkdir");
        std::fs::write(other.join(MARKER), "command = \"x\"\nfiles = []\n").expect("write");
        let unmarked = p.join(".res.Qq11Qq.tribo-tmp");
        std::fs::create_dir(&unmarked).expect("mkdir");
        std::fs::write(unmarked.join("keep.txt"), "keep").expect("write");
        let victim = p.join("victim");
        std::fs::create_dir(&victim).expect("mkdir");
        std::fs::write(victim.join(MARKER), "command = \"x\"\nfiles = []\n").expect("write");
        std::fs::write(victim.join("precious.txt"), "precious").expect("write");
        #[cfg(unix)]
        std::os::unix::fs::symlink(&victim, p.join(".res.Link00.tribo-tmp")).expect("symlink");

        commit_set(&p.join("res"), &[("a.csv", "1")]).expect("a run");
        assert!(!marked.exists() && !empty.exists());
        assert!(!partial.exists() && !truncated.exists());
        assert_eq!(names(&unvouched), [MARKER, "keep.txt"]);
        assert!(other.exists() && unmarked.join("keep.txt").exists());
        assert_eq!(names(&victim), [MARKER, "precious.txt"]);
        #[cfg(unix)]
        assert!(std::fs::symlink_metadata(p.join(".res.Link00.tribo-tmp")).is_ok());
    }

    #[test]
    fn temporary_names_are_recognised_exactly() {
        assert!(is_temp_name(".res.Ab12Cd.tribo-tmp", "res"));
        assert!(!is_temp_name(".res.b.Ab12Cd.tribo-tmp", "res"));
        assert!(!is_temp_name(".res.Ab12C.tribo-tmp", "res"));
        assert!(!is_temp_name(".res.Ab-2Cd.tribo-tmp", "res"));
        assert!(!is_temp_name("res.Ab12Cd.tribo-tmp", "res"));
        assert!(!is_temp_name(".res.lock", "res"));
    }
}
