//! Temporary files being written (an image or a cache file before its rename), listed
//! so that an interrupted process removes them ([`remove_all`], from a signal's
//! handler) instead of leaving them behind.

use std::fs::{self, File};
use std::io;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU32, Ordering};

/// The temporary files of this process not yet renamed or removed.
static LIST: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// A fresh temporary file beside `path` (in its directory), listed until [`forget`].
/// Short name (a long target name plus a suffix would pass the 255-byte limit),
/// created exclusively (never truncating or following another process's file: two
/// processes of the same PID, in two containers sharing a directory, take different
/// names).
pub fn create_beside(path: &Path) -> io::Result<(File, PathBuf)> {
    static COUNT: AtomicU32 = AtomicU32::new(0);
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty());
    loop {
        let n = COUNT.fetch_add(1, Ordering::Relaxed);
        let name = format!(".octaray-{}-{n}.tmp", std::process::id());
        let tmp = dir.map_or_else(|| PathBuf::from(&name), |d| d.join(&name));
        // (held while the file is made: no file appears once `remove_all` holds it)
        let mut list = LIST.lock().unwrap_or_else(|e| e.into_inner());
        match fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
        {
            Ok(file) => {
                list.push(tmp.clone());
                return Ok((file, tmp));
            }
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
}

/// Forgets a temporary file (renamed into place, or removed).
pub fn forget(tmp: &Path) {
    if let Ok(mut list) = LIST.lock() {
        list.retain(|p| p != tmp);
    }
}

/// Removes the temporary files still being written, for a process about to end (a
/// signal's handler). The returned lock keeps any new temporary file from appearing:
/// end the process while holding it.
pub fn remove_all() -> impl Sized {
    let list = LIST.lock().unwrap_or_else(|e| e.into_inner());
    for p in list.iter() {
        let _ = fs::remove_file(p);
    }
    list
}

/// Writes `path` whole or not at all: `write` fills a temporary file beside it, which
/// is then renamed over it (and removed on any error).
pub fn write_renamed(
    path: &Path,
    write: impl FnOnce(&mut File) -> io::Result<()>,
) -> io::Result<()> {
    let (mut file, tmp) = create_beside(path)?;
    let done = write(&mut file).and_then(|_| {
        drop(file);
        fs::rename(&tmp, path)
    });
    if done.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    forget(&tmp);
    done
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_write_replaces_the_file_and_leaves_no_temporary() {
        let d = std::env::temp_dir().join(format!("octaray-temporaries-{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        let path = d.join("f.bin");
        fs::write(&path, b"old contents, longer").unwrap();
        write_renamed(&path, |f| io::Write::write_all(f, b"new")).unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"new");
        let names: Vec<_> = fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("f.bin")]);
        // into a directory that does not exist: an error, nothing listed
        assert!(write_renamed(&d.join("none").join("f.bin"), |_| Ok(())).is_err());
        // a failed write leaves the file as it was
        let failed = write_renamed(&path, |f| {
            io::Write::write_all(f, b"half")?;
            Err(io::Error::other("full"))
        });
        assert!(failed.is_err());
        assert_eq!(fs::read(&path).unwrap(), b"new");
        assert!(LIST.lock().unwrap().iter().all(|p| !p.starts_with(&d)));
        fs::remove_dir_all(&d).unwrap();
    }
}
