//! Opening input files safely: only regular files are read, and never more than a bound that
//! depends on the kind of input.
//!
//! A path such as `/dev/zero` (endless), `/dev/stdin` or a FIFO without a writer (blocks for
//! ever) would otherwise be read until memory runs out, or hang. The checks:
//!
//! - the path must name a regular file (symbolic links are followed);
//! - the file is opened with `O_NONBLOCK`, so a FIFO swapped in after the check cannot block
//!   the open, and is checked again on the open descriptor;
//! - its size must be at most the bound of its [`InputKind`], and reading stops with an error
//!   if the file grows past the bound while it is read.
//!
//! Errors are `std::io::Error`s whose message names the problem and the bound, so that the
//! readers' existing error types (which name the path) carry them unchanged.

use std::fs::File;
use std::io::{self, Read};
use std::os::unix::fs::OpenOptionsExt;
use std::path::Path;

/// One GiB.
const GIB: u64 = 1 << 30;
/// One MiB.
const MIB: u64 = 1 << 20;

/// What an input file holds; each kind has its own size bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputKind {
    /// SeaDronesSee / COCO JSON: annotations and detections. The whole SeaDronesSee-MOT
    /// training set's annotation file is a few hundred MB; 2 GiB leaves room for bigger data
    /// sets while keeping the parsed form within a companion computer's or workstation's memory.
    Json,
    /// MOTChallenge text: ground truth, results and detections. 2 GiB is about 40 million
    /// rows, far beyond any published benchmark sequence.
    MotText,
    /// Small text configuration (TOML parameters, `seqinfo.ini`). Hand-written files; 16 MiB
    /// is thousands of times the size of any real one.
    Config,
}

impl InputKind {
    /// The largest file of this kind that is read (bytes).
    pub const fn max_bytes(self) -> u64 {
        match self {
            Self::Json | Self::MotText => 2 * GIB,
            Self::Config => 16 * MIB,
        }
    }

    /// The bound in words, for error messages.
    fn describe(self) -> &'static str {
        match self {
            Self::Json => "the 2 GiB limit for JSON inputs",
            Self::MotText => "the 2 GiB limit for MOTChallenge text inputs",
            Self::Config => "the 16 MiB limit for configuration files",
        }
    }
}

/// The error for a file larger than its kind's bound.
fn too_large(kind: InputKind, size: Option<u64>) -> io::Error {
    let message = match size {
        Some(size) => format!("the file is {size} bytes, more than {}", kind.describe()),
        None => format!("the file grew past {} while it was read", kind.describe()),
    };
    io::Error::new(io::ErrorKind::InvalidData, message)
}

/// What a non-regular file is, in words.
fn file_type_name(ft: std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if ft.is_dir() {
        "a directory"
    } else if ft.is_char_device() {
        "a character device"
    } else if ft.is_block_device() {
        "a block device"
    } else if ft.is_fifo() {
        "a FIFO (named pipe)"
    } else if ft.is_socket() {
        "a socket"
    } else {
        "not a regular file"
    }
}

/// Checks a file's metadata: a regular file no larger than `kind`'s bound.
fn check_metadata(meta: &std::fs::Metadata, kind: InputKind) -> io::Result<()> {
    if !meta.file_type().is_file() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{}; inputs must be regular files",
                file_type_name(meta.file_type())
            ),
        ));
    }
    if meta.len() > kind.max_bytes() {
        return Err(too_large(kind, Some(meta.len())));
    }
    Ok(())
}

/// A reader that fails once more than its bound has been read.
#[derive(Debug)]
pub struct BoundedFile {
    file: File,
    remaining: u64,
    kind: InputKind,
}

impl Read for BoundedFile {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        // One byte more than allowed, to tell "exactly at the bound" from "past it".
        let want = usize::try_from(self.remaining.saturating_add(1))
            .unwrap_or(usize::MAX)
            .min(buf.len());
        let n = self.file.read(&mut buf[..want])?;
        let n64 = n as u64;
        if n64 > self.remaining {
            return Err(too_large(self.kind, None));
        }
        self.remaining -= n64;
        Ok(n)
    }
}

/// Opens `path` for reading if it is a regular file within `kind`'s size bound.
///
/// Errors (plain `io::Error`s, to be wrapped with the path by the caller): the OS's when the
/// file cannot be opened; `InvalidInput` for a directory, device, FIFO or socket; `InvalidData`
/// for a file over the bound (also when it grows past it while being read).
pub fn open(path: &Path, kind: InputKind) -> io::Result<BoundedFile> {
    // Checked before opening: opening a FIFO for reading blocks until a writer comes.
    check_metadata(&std::fs::metadata(path)?, kind)?;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)?;
    // Checked again on what was opened, in case the path changed in between.
    check_metadata(&file.metadata()?, kind)?;
    Ok(BoundedFile {
        file,
        remaining: kind.max_bytes(),
        kind,
    })
}

/// Reads a whole regular file of `kind` as UTF-8 text (see [`open`] for the checks).
pub fn read_to_string(path: &Path, kind: InputKind) -> io::Result<String> {
    let mut reader = open(path, kind)?;
    let mut text = String::new();
    reader.read_to_string(&mut text)?;
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_regular_files() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        std::fs::write(&p, "hello").unwrap();
        assert_eq!(read_to_string(&p, InputKind::Config).unwrap(), "hello");
    }

    #[test]
    fn refuses_devices_directories_and_fifos() {
        let e = read_to_string(Path::new("/dev/zero"), InputKind::Json).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
        assert!(e.to_string().contains("character device"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        let e = read_to_string(dir.path(), InputKind::Json).unwrap_err();
        assert!(e.to_string().contains("directory"), "{e}");
        let fifo = dir.path().join("fifo");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: `c` is a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let e = read_to_string(&fifo, InputKind::MotText).unwrap_err();
        assert!(e.to_string().contains("FIFO"), "{e}");
    }

    #[test]
    fn refuses_files_over_the_bound() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big.toml");
        // Sparse: takes no disk space.
        let f = File::create(&p).unwrap();
        f.set_len(InputKind::Config.max_bytes() + 1).unwrap();
        let e = read_to_string(&p, InputKind::Config).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidData);
        assert!(e.to_string().contains("16 MiB"), "{e}");
        // Exactly at the bound is read (zero bytes are valid UTF-8).
        f.set_len(InputKind::Config.max_bytes()).unwrap();
        assert_eq!(
            read_to_string(&p, InputKind::Config).unwrap().len() as u64,
            InputKind::Config.max_bytes()
        );
    }

    #[test]
    fn bounded_reader_stops_past_the_bound() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a");
        std::fs::write(&p, "0123456789").unwrap();
        let mut r = BoundedFile {
            file: File::open(&p).unwrap(),
            remaining: 4,
            kind: InputKind::Config,
        };
        let mut s = String::new();
        let e = r.read_to_string(&mut s).unwrap_err();
        assert!(e.to_string().contains("grew past"), "{e}");
    }
}
