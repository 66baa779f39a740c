//! Opening input files (scene, mesh, profile) within octaray's size limit.
//!
//! An input is a regular file or a pipe (`/dev/stdin`, `<(generator)`), read to its
//! end, at most [`MAX_INPUT`] bytes. A regular file over the limit is refused from its
//! size before a byte is read; a pipe is refused once it has delivered more.
//! Directories and devices are refused before they are opened (/dev/zero would fill
//! gigabytes within seconds). Opening a FIFO waits for its writer,
//! as it does for any program.

use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

/// The largest input octaray reads: 4 GiB.
pub const MAX_INPUT: u64 = 4 << 30;

/// The error of an input larger than [`MAX_INPUT`].
fn too_large(size: Option<u64>) -> io::Error {
    let size = size.map_or(String::new(), |n| format!("{n} bytes: "));
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!("{size}larger than 4 GiB, octaray's limit for an input file"),
    )
}

/// Opens `path` for reading after the checks above; read it through [`Limited`].
pub fn open_input(path: &Path) -> io::Result<File> {
    let meta = std::fs::metadata(path)?;
    let kind = meta.file_type();
    #[cfg(unix)]
    let device = {
        use std::os::unix::fs::FileTypeExt;
        kind.is_char_device() || kind.is_block_device()
    };
    #[cfg(not(unix))]
    let device = false;
    if kind.is_dir() {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, "a directory"));
    }
    if device {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "a device, not a file",
        ));
    }
    if kind.is_file() && meta.len() > MAX_INPUT {
        return Err(too_large(Some(meta.len())));
    }
    File::open(path)
}

/// Reads a whole input file (see the module doc).
pub fn read_input(path: &Path) -> io::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    Limited::new(open_input(path)?).read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// A reader that fails (`InvalidData`) once more than [`MAX_INPUT`] bytes have come
/// through it: the limit on a stream whose size is not known in advance (a file that
/// grows while it is read included).
#[derive(Debug)]
pub struct Limited<R> {
    inner: R,
    read: u64,
}

impl<R: Read> Limited<R> {
    pub fn new(inner: R) -> Self {
        Limited { inner, read: 0 }
    }

    /// Bytes read so far.
    pub fn bytes_read(&self) -> u64 {
        self.read
    }
}

impl<R: Read> Read for Limited<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        // one byte past the limit tells a stream at the limit from one beyond it
        let room = (MAX_INPUT + 1 - self.read.min(MAX_INPUT + 1)) as usize;
        if room == 0 {
            return Err(too_large(None));
        }
        let want = buf.len().min(room);
        let n = self.inner.read(&mut buf[..want])?;
        self.read += n as u64;
        if self.read > MAX_INPUT {
            return Err(too_large(None));
        }
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reader of `n` bytes (whatever the buffer held), without the memory.
    struct Zeros(u64);

    impl Read for Zeros {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            let n = buf.len().min(self.0 as usize);
            self.0 -= n as u64;
            Ok(n)
        }
    }

    fn drain(n: u64) -> io::Result<u64> {
        io::copy(&mut Limited::new(Zeros(n)), &mut io::sink())
    }

    #[test]
    fn a_stream_at_the_limit_passes_and_one_byte_more_fails() {
        assert_eq!(drain(MAX_INPUT).unwrap(), MAX_INPUT);
        let e = drain(MAX_INPUT + 1).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidData);
        assert!(e.to_string().contains("larger than 4 GiB"), "{e}");
    }

    /// A sparse file of 4 GiB + 1 byte is refused from its size, before any read (it
    /// was read whole first: 19 s and 4.1 GB): only the size check knows the size.
    #[cfg(unix)]
    #[test]
    fn a_regular_file_over_the_limit_is_refused_from_its_size() {
        let path = std::env::temp_dir().join(format!("octaray-big-{}", std::process::id()));
        let f = File::create(&path).unwrap();
        f.set_len(MAX_INPUT + 1).unwrap();
        drop(f);
        let e = read_input(&path).unwrap_err();
        let _ = std::fs::remove_file(&path);
        assert!(e.to_string().contains("4294967297 bytes"), "{e}");
    }
}
