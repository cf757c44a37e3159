//! Reading a user's input files safely: only regular files, at most [`MAX_INPUT_BYTES`], UTF-8.
//! A directory, a device such as `/dev/zero` or a FIFO is refused before it is opened (reading
//! `/dev/zero` would fill the memory, opening a FIFO would wait for a writer forever), and a
//! file is read through `take(MAX_INPUT_BYTES + 1)`, so even a file that grows while it is read
//! cannot make Tribo hold more than the cap.

use std::io::Read;
use std::path::Path;

/// The largest input file Tribo reads (rig, law set, oil, parameter and data files): 16 MiB.
/// The bundled files are a few KiB; a larger file is a mistake (a wrong path, a binary file).
pub const MAX_INPUT_BYTES: u64 = 16 << 20;

/// Why an input file could not be read. The messages do not name the file: the caller's error
/// does, with its own location format.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// Nothing exists at the path (a caller may then look for a bundled file of that name).
    #[error("no such file")]
    NotFound,
    /// The path is a directory, device, FIFO or socket.
    #[error("is not a regular file ({0}); give the path of a file")]
    NotRegular(&'static str),
    /// The file is larger than [`MAX_INPUT_BYTES`].
    #[error("is larger than the {} MiB an input file may have; is it the right file?", MAX_INPUT_BYTES >> 20)]
    TooLarge,
    /// The bytes are not UTF-8 text.
    #[error("is not UTF-8 text (byte {0} is not); save it as UTF-8")]
    NotUtf8(usize),
    /// Any other I/O failure (permissions, a failing disk).
    #[error("cannot be read ({0})")]
    Io(std::io::Error),
}

impl ReadError {
    /// Whether nothing exists at the path.
    pub fn is_not_found(&self) -> bool {
        matches!(self, ReadError::NotFound)
    }
}

/// What kind of file `t` is, in words, for messages ("a FIFO", "a directory", ...); shared by
/// the input readers and the result writers.
pub fn file_kind(t: std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_symlink() {
        "a symbolic link"
    } else if t.is_dir() {
        "a directory"
    } else if t.is_file() {
        "a regular file"
    } else {
        "a special file"
    }
}

fn io(e: std::io::Error) -> ReadError {
    if e.kind() == std::io::ErrorKind::NotFound {
        ReadError::NotFound
    } else {
        ReadError::Io(e)
    }
}

/// The bytes of the regular file at `path`, at most `cap` of them (more is [`ReadError::TooLarge`]).
pub fn read_bytes_capped(path: &Path, cap: u64) -> Result<Vec<u8>, ReadError> {
    // Checked before opening: opening a FIFO blocks until someone writes to it.
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(ReadError::NotRegular(file_kind(meta.file_type())));
    }
    if meta.len() > cap {
        return Err(ReadError::TooLarge);
    }
    let file = std::fs::File::open(path).map_err(io)?;
    let mut bytes = Vec::new();
    file.take(cap.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > cap {
        return Err(ReadError::TooLarge);
    }
    Ok(bytes)
}

/// The text of the regular file at `path`, at most [`MAX_INPUT_BYTES`], UTF-8 (a leading byte
/// order mark is dropped: spreadsheet programs write one).
pub fn read_text(path: &Path) -> Result<String, ReadError> {
    let bytes = read_bytes_capped(path, MAX_INPUT_BYTES)?;
    let mut text =
        String::from_utf8(bytes).map_err(|e| ReadError::NotUtf8(e.utf8_error().valid_up_to()))?;
    if text.starts_with('\u{feff}') {
        text.drain(..'\u{feff}'.len_utf8());
    }
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directories_devices_and_large_files_are_refused_without_reading_them() {
        let dir = tempfile::tempdir().expect("temp dir");
        let err = read_text(dir.path()).expect_err("a directory");
        assert!(matches!(err, ReadError::NotRegular("a directory")), "{err}");
        #[cfg(unix)]
        {
            let err = read_text(Path::new("/dev/zero")).expect_err("a device");
            assert!(
                matches!(err, ReadError::NotRegular("a character device")),
                "{err}"
            );
        }
        // A sparse file one byte over the cap: refused by its size, not read.
        let big = dir.path().join("big.toml");
        let f = std::fs::File::create(&big).expect("create");
        f.set_len(MAX_INPUT_BYTES + 1).expect("set_len");
        let err = read_text(&big).expect_err("too large");
        assert!(err.to_string().contains("16 MiB"), "{err}");
        // Exactly at the cap is fine for the byte reader, and a smaller cap is enforced.
        f.set_len(10).expect("set_len");
        assert_eq!(read_bytes_capped(&big, 10).expect("at the cap").len(), 10);
        assert!(matches!(
            read_bytes_capped(&big, 9),
            Err(ReadError::TooLarge)
        ));
        assert!(read_text(&dir.path().join("none"))
            .expect_err("missing")
            .is_not_found());
    }

    #[test]
    fn text_is_utf8_without_a_byte_order_mark() {
        let dir = tempfile::tempdir().expect("temp dir");
        let p = dir.path().join("a.csv");
        std::fs::write(&p, b"\xef\xbb\xbfspeed_rpm\n").expect("write");
        assert_eq!(read_text(&p).expect("reads"), "speed_rpm\n");
        std::fs::write(&p, b"ab\xffc").expect("write");
        let err = read_text(&p).expect_err("not UTF-8");
        assert!(matches!(err, ReadError::NotUtf8(2)), "{err}");
    }
}
