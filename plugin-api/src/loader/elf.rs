//! A look at an ELF file's headers before the dynamic loader maps it: a library cut short (a
//! copy interrupted, a full disk) maps without complaint, and the loader then touches pages past
//! the file's end and dies of SIGBUS, taking the process with it. Reading the headers and
//! checking that every segment and table they describe lies inside the file turns that into an
//! error naming the file. Files that are not ELF at all are left to the loader, which refuses
//! them cleanly.

use std::io::Read;
use std::path::Path;

/// Why a file is refused before it is mapped.
pub(crate) fn check(path: &Path) -> Result<(), String> {
    let Ok(mut file) = std::fs::File::open(path) else {
        // The loader says why (missing, no permission) in its own words.
        return Ok(());
    };
    let len = file.metadata().map(|m| m.len()).unwrap_or(0);
    let mut head = [0u8; 64];
    let got = read_up_to(&mut file, &mut head);
    if got < 4 || head[..4] != *b"\x7fELF" {
        return Ok(());
    }
    let wide = match head[4] {
        1 => false,
        2 => true,
        c => return Err(format!("its ELF header names an unknown class {c}")),
    };
    let little = match head[5] {
        1 => true,
        2 => false,
        d => return Err(format!("its ELF header names an unknown byte order {d}")),
    };
    let header_len = if wide { 64 } else { 52 };
    if (got as u64) < header_len || len < header_len {
        return Err(truncated(len, header_len, "its ELF header"));
    }
    let f = Fields { little };
    let (phoff, shoff, phentsize, phnum, shentsize, shnum) = if wide {
        (
            f.u64(&head[0x20..]),
            f.u64(&head[0x28..]),
            f.u16(&head[0x36..]),
            f.u16(&head[0x38..]),
            f.u16(&head[0x3a..]),
            f.u16(&head[0x3c..]),
        )
    } else {
        (
            u64::from(f.u32(&head[0x1c..])),
            u64::from(f.u32(&head[0x20..])),
            f.u16(&head[0x2a..]),
            f.u16(&head[0x2c..]),
            f.u16(&head[0x2e..]),
            f.u16(&head[0x30..]),
        )
    };
    let table_end =
        |off: u64, size: u16, n: u16| off.saturating_add(u64::from(size) * u64::from(n));
    let ph_end = table_end(phoff, phentsize, phnum);
    if ph_end > len {
        return Err(truncated(len, ph_end, "its program headers"));
    }
    if shoff != 0 {
        let sh_end = table_end(shoff, shentsize, shnum);
        if sh_end > len {
            return Err(truncated(len, sh_end, "its section headers"));
        }
    }
    let entry = usize::from(phentsize);
    let min_entry = if wide { 56 } else { 32 };
    if phnum == 0 || entry < min_entry {
        return Ok(());
    }
    let mut table = vec![0u8; entry * usize::from(phnum)];
    use std::io::Seek;
    if file.seek(std::io::SeekFrom::Start(phoff)).is_err()
        || read_up_to(&mut file, &mut table) < table.len()
    {
        return Err(truncated(len, ph_end, "its program headers"));
    }
    for ph in table.chunks_exact(entry) {
        let (offset, filesz) = if wide {
            (f.u64(&ph[8..]), f.u64(&ph[32..]))
        } else {
            (u64::from(f.u32(&ph[4..])), u64::from(f.u32(&ph[16..])))
        };
        let end = offset.saturating_add(filesz);
        if filesz > 0 && end > len {
            return Err(truncated(len, end, "a segment the loader maps"));
        }
    }
    Ok(())
}

fn truncated(len: u64, needed: u64, what: &str) -> String {
    format!("the file is truncated: it holds {len} bytes, but {what} reach to byte {needed}; copy or build the library again")
}

/// Read until `buf` is full or the file ends; the bytes read.
fn read_up_to(file: &mut std::fs::File, buf: &mut [u8]) -> usize {
    let mut n = 0;
    while n < buf.len() {
        match file.read(&mut buf[n..]) {
            Ok(0) | Err(_) => break,
            Ok(k) => n += k,
        }
    }
    n
}

/// Integers of the file's byte order.
struct Fields {
    little: bool,
}

impl Fields {
    fn u16(&self, b: &[u8]) -> u16 {
        let a = [b[0], b[1]];
        if self.little {
            u16::from_le_bytes(a)
        } else {
            u16::from_be_bytes(a)
        }
    }
    fn u32(&self, b: &[u8]) -> u32 {
        let a = [b[0], b[1], b[2], b[3]];
        if self.little {
            u32::from_le_bytes(a)
        } else {
            u32::from_be_bytes(a)
        }
    }
    fn u64(&self, b: &[u8]) -> u64 {
        let mut a = [0u8; 8];
        a.copy_from_slice(&b[..8]);
        if self.little {
            u64::from_le_bytes(a)
        } else {
            u64::from_be_bytes(a)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// This test binary is a whole ELF file: it passes, and every cut of it fails naming the
    /// truncation (a cut inside the magic is left to the loader).
    #[test]
    fn a_whole_elf_file_passes_and_cut_copies_are_truncated() {
        let exe = std::env::current_exe().expect("test binary");
        assert_eq!(check(&exe), Ok(()));
        let bytes = std::fs::read(&exe).expect("read");
        let dir = std::env::temp_dir().join(format!("tribo-elf-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        for cut in [10, 63, 3000, bytes.len() / 2, bytes.len() - 1] {
            let p = dir.join(format!("cut-{cut}"));
            std::fs::write(&p, &bytes[..cut]).expect("write");
            let e = check(&p).expect_err("truncated");
            assert!(
                e.contains("truncated") && e.contains(&format!("holds {cut} bytes")),
                "{cut}: {e}"
            );
        }
        let text = dir.join("text");
        std::fs::write(&text, "not a library").expect("write");
        assert_eq!(check(&text), Ok(()));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
