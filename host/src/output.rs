//! Writing result files so a failed or interrupted run never leaves a half-written file under
//! the final name: write to a temporary file in the same directory (a fresh random name,
//! created exclusively, through `tempfile`), then rename it over the final name. On every error
//! path the temporary file is removed; only a process killed outright can leave one behind, as
//! a dot-file named after the result (`.comparison.json.XXXXXX.tmp`).

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use tempfile::NamedTempFile;

/// Write `bytes` to `path` atomically (temporary file + rename). On error `path` is left as it
/// was and no temporary file remains.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let mut f = AtomicFile::create(path)?;
    f.write_all(bytes)?;
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
}

impl AtomicFile {
    /// Start writing `path`: a temporary file is created in its directory, which must exist.
    pub fn create(path: &Path) -> std::io::Result<Self> {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
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
        let file = builder.tempfile_in(dir)?;
        Ok(Self {
            file: BufWriter::new(file),
            path: path.to_path_buf(),
        })
    }

    /// Flush, sync and rename into place (atomic on one file system). On error the temporary
    /// file is removed and `path` keeps its previous content.
    pub fn commit(self) -> std::io::Result<()> {
        let file = self.file.into_inner().map_err(|e| e.into_error())?;
        file.as_file().sync_all()?;
        file.persist(&self.path).map_err(|e| e.error)?;
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
        // The final name is a non-empty directory: the rename fails after the data is written.
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
        assert!(write_atomic(&path, b"x").is_err());
        assert!(names(dir.path()).is_empty());
    }

    #[test]
    fn a_bare_file_name_is_written_in_the_current_directory() {
        let f = AtomicFile::create(Path::new("relative-name.txt")).expect("create in .");
        drop(f);
        assert!(!Path::new("relative-name.txt").exists());
    }
}
