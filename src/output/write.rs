//! Writing images whole or not at all: encode to a temporary file in the target
//! directory, then rename it into place. Default names (`Output_11.bmp`, ...) are
//! claimed with a hard link, which fails instead of overwriting if the name was taken
//! in the meantime.

use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use image::ImageFormat;

use super::Framebuffer;
use super::tile::TileMeta;

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{path}: unsupported image extension (use .bmp or .png)")]
    Extension { path: String },
    #[error("{path}: {source}")]
    Io { path: String, source: io::Error },
    #[error("{path}: {source}")]
    Encode {
        path: String,
        source: png::EncodingError,
    },
}

fn format_for(path: &Path) -> Result<ImageFormat, OutputError> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .as_deref()
    {
        Some("bmp") => Ok(ImageFormat::Bmp),
        Some("png") => Ok(ImageFormat::Png),
        _ => Err(OutputError::Extension {
            path: path.display().to_string(),
        }),
    }
}

/// What can be known about writing `path` before any work: an image extension
/// (with `image`), not a directory, in an existing directory, not a file without
/// write permission, not a symbolic link to nothing ([`write_target`]). Checked
/// before a render, so that a typo costs no render time.
pub fn check_output(path: &Path, image: bool) -> Result<(), OutputError> {
    if image {
        format_for(path)?;
    }
    let io = |message: &str| OutputError::Io {
        path: path.display().to_string(),
        source: io::Error::new(io::ErrorKind::InvalidInput, message),
    };
    if path.is_dir() {
        return Err(io("is a directory"));
    }
    let text = path.as_os_str().to_string_lossy();
    if text.ends_with('/') || text.ends_with("/.") {
        return Err(io("names a directory (ends with /)"));
    }
    if path.file_name().is_some_and(|n| n.len() > NAME_MAX) {
        return Err(io("file name too long (at most 255 bytes)"));
    }
    let target = write_target(path)?;
    let dir = target.parent().filter(|p| !p.as_os_str().is_empty());
    if dir.is_some_and(|d| !d.is_dir()) {
        return Err(io("no such directory"));
    }
    check_dir(&target).map_err(|e| named(e, path))
}

/// The longest file name most file systems take (bytes).
const NAME_MAX: usize = 255;

/// Whether a file can be made beside `path` (a directory without write permission,
/// a read-only file system): one is, and removed.
fn check_dir(path: &Path) -> Result<(), OutputError> {
    let probe = write_temp_bytes(path, b"", None)?;
    let _ = fs::remove_file(&probe);
    forget_temp(&probe);
    Ok(())
}

/// What can be known before any work about writing the next free `Output_1N.bmp` in
/// `dir` ([`write_next_output`]): that a file can be made there.
pub fn check_output_dir(dir: &Path) -> Result<(), OutputError> {
    check_dir(&dir.join(output_name(1)))
}

/// Whether `a` and `b` name the same file once written (through symbolic links, from
/// any directory): two outputs of one command must not.
pub fn same_file(a: &Path, b: &Path) -> bool {
    let resolve = |p: &Path| {
        let p = fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
        let dir = p.parent().filter(|d| !d.as_os_str().is_empty());
        let dir = dir.map_or_else(|| fs::canonicalize("."), fs::canonicalize);
        match (dir, p.file_name()) {
            (Ok(d), Some(n)) => d.join(n),
            _ => p,
        }
    };
    resolve(a) == resolve(b)
}

/// `e` reported under the name the user gave (not the file a link led to).
fn named(e: OutputError, path: &Path) -> OutputError {
    match e {
        OutputError::Io { source, .. } => OutputError::Io {
            path: path.display().to_string(),
            source,
        },
        e => e,
    }
}

/// The file that writing `path` replaces: `path` itself, or, for a symbolic link, the
/// file it names (the link stays, as `cp` leaves it; a rename would put a file in its
/// place). Refused: a link to nothing (as `cp` refuses to write through one), anything
/// but a regular file (a link to a device or a directory), and a file this process may
/// not write (replacing it by a rename would pass over that; tested by opening it for
/// writing, which changes nothing).
fn write_target(path: &Path) -> Result<PathBuf, OutputError> {
    let error = |source: io::Error| OutputError::Io {
        path: path.display().to_string(),
        source,
    };
    let target = match fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => fs::canonicalize(path).map_err(|e| {
            error(if e.kind() == io::ErrorKind::NotFound {
                io::Error::new(e.kind(), "a symbolic link to nothing: not written through")
            } else {
                e
            })
        })?,
        _ => path.to_path_buf(),
    };
    let meta = fs::metadata(&target);
    if meta.as_ref().is_ok_and(|m| !m.is_file()) {
        // a directory, a device, a pipe: a rename would put a file in its place
        return Err(error(io::Error::new(
            io::ErrorKind::InvalidInput,
            "not a regular file: not replaced",
        )));
    }
    if meta.is_ok() {
        fs::OpenOptions::new()
            .write(true)
            .open(&target)
            .map_err(|e| {
                error(if e.kind() == io::ErrorKind::PermissionDenied {
                    io::Error::new(e.kind(), "no write permission: not replaced")
                } else {
                    e
                })
            })?;
    }
    Ok(target)
}

/// Removes the temporary files still being written, for a process about to end (a
/// signal's handler). The returned lock keeps any new temporary file from appearing:
/// end the process while holding it.
pub fn remove_temporaries() -> impl Sized {
    crate::temporaries::remove_all()
}

/// Writes `bytes` to a fresh temporary file beside `path` ([`crate::temporaries`]),
/// taking the permissions and (where this process may set them, as root) the owner and
/// group of `like`, the file it replaces, before the bytes are written; returns its path.
fn write_temp_bytes(
    path: &Path,
    bytes: &[u8],
    like: Option<&fs::Metadata>,
) -> Result<PathBuf, OutputError> {
    let io_error = |source| OutputError::Io {
        path: path.display().to_string(),
        source,
    };
    let (mut file, tmp) = crate::temporaries::create_beside(path).map_err(io_error)?;
    if let Some(like) = like {
        // (best effort: the mode bits and owner this user may set)
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            let _ = std::os::unix::fs::fchown(&file, Some(like.uid()), Some(like.gid()));
        }
        let _ = file.set_permissions(like.permissions());
    }
    match io::Write::write_all(&mut file, bytes) {
        Ok(()) => Ok(tmp),
        Err(e) => {
            let _ = fs::remove_file(&tmp);
            forget_temp(&tmp);
            Err(io_error(e))
        }
    }
}

/// Forgets a temporary file (renamed into place, or removed).
fn forget_temp(tmp: &Path) {
    crate::temporaries::forget(tmp);
}

/// The encoded image, BMP or PNG by the extension of `path`.
fn encode(fb: &Framebuffer, path: &Path) -> Result<Vec<u8>, OutputError> {
    encode_with(fb, path, None)
}

/// [`encode`], with `meta` recorded in a PNG (a BMP has no place for it).
fn encode_with(
    fb: &Framebuffer,
    path: &Path,
    meta: Option<&TileMeta>,
) -> Result<Vec<u8>, OutputError> {
    if format_for(path)? == ImageFormat::Bmp {
        return Ok(super::bmp::encode(fb));
    }
    super::tile::encode_png(fb, meta).map_err(|source| OutputError::Encode {
        path: path.display().to_string(),
        source,
    })
}

/// Writes `bytes` to `path` whole or not at all: a temporary file beside it, then a
/// rename over it (an existing file is replaced atomically, keeping its permissions,
/// or left as it was; a symbolic link is written through, [`write_target`]).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    let target = write_target(path)?;
    let like = fs::metadata(&target).ok();
    let tmp = write_temp_bytes(&target, bytes, like.as_ref()).map_err(|e| named(e, path))?;
    let mut renamed = fs::rename(&tmp, &target);
    if renamed.is_err() {
        let _ = fs::remove_file(&tmp);
        // A file that may be written but not replaced: a bind mount (a container's
        // `-v out.bmp:/out.bmp`, EBUSY) or another user's file in a sticky directory
        // (EPERM). Written in place, as `cp` writes, whole but not atomically.
        if let (Some(like), Err(e)) = (&like, &renamed)
            && like.is_file()
            && matches!(
                e.kind(),
                io::ErrorKind::ResourceBusy | io::ErrorKind::PermissionDenied
            )
        {
            renamed = fs::OpenOptions::new()
                .write(true)
                .truncate(true)
                .open(&target)
                .and_then(|mut f| io::Write::write_all(&mut f, bytes));
        }
    }
    forget_temp(&tmp);
    renamed.map_err(|source| OutputError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// Writes `fb` to `path` (BMP or PNG by extension), replacing any existing file
/// atomically.
pub fn write_image(fb: &Framebuffer, path: &Path) -> Result<(), OutputError> {
    write_atomic(path, &encode(fb, path)?)
}

/// [`write_image`] of a piece of a frame: a PNG records `meta` (where the piece
/// belongs, [`super::tile`]); a BMP is the pixels alone.
pub fn write_tile(fb: &Framebuffer, path: &Path, meta: &TileMeta) -> Result<(), OutputError> {
    write_atomic(path, &encode_with(fb, path, Some(meta))?)
}

/// Whether `path` is a PNG name (pieces of frames record where they belong only there).
pub fn is_png(path: &Path) -> bool {
    matches!(format_for(path), Ok(ImageFormat::Png))
}

/// Writes `fb` to `path` only if no file of that name exists; `Ok(false)` if one does
/// (or any directory entry: a dangling symbolic link counts as taken).
pub fn write_image_no_clobber(fb: &Framebuffer, path: &Path) -> Result<bool, OutputError> {
    write_bytes_no_clobber(&encode(fb, path)?, path)
}

/// [`write_image_no_clobber`] of encoded bytes.
fn write_bytes_no_clobber(bytes: &[u8], path: &Path) -> Result<bool, OutputError> {
    if fs::symlink_metadata(path).is_ok() {
        return Ok(false);
    }
    let tmp = write_temp_bytes(path, bytes, None)?;
    let linked = fs::hard_link(&tmp, path);
    let _ = fs::remove_file(&tmp);
    forget_temp(&tmp);
    match linked {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == io::ErrorKind::AlreadyExists => Ok(false),
        Err(source) => Err(OutputError::Io {
            path: path.display().to_string(),
            source,
        }),
    }
}

/// The assignment's capture names: `Output_11.bmp`, `Output_12.bmp`, ... (the n-th
/// is `Output_1{n}.bmp`).
pub fn output_name(n: u32) -> String {
    format!("Output_1{n}.bmp")
}

/// The first `Output_1N.bmp` in `dir` with no directory entry yet.
pub fn next_free_output(dir: &Path) -> PathBuf {
    next_free_from(dir, 1).1
}

fn next_free_from(dir: &Path, first: u32) -> (u32, PathBuf) {
    (first..)
        .map(|n| (n, dir.join(output_name(n))))
        .find(|(_, p)| fs::symlink_metadata(p).is_err())
        .expect("some name is free")
}

/// Writes `fb` under the next free `Output_1N.bmp` in `dir`, never overwriting: a name
/// taken meanwhile (by another process) is skipped, not retried.
pub fn write_next_output(fb: &Framebuffer, dir: &Path) -> Result<PathBuf, OutputError> {
    let bytes = encode(fb, &dir.join(output_name(1)))?;
    let mut first = 1;
    loop {
        let (n, path) = next_free_from(dir, first);
        if write_bytes_no_clobber(&bytes, &path)? {
            return Ok(path);
        }
        first = n + 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny() -> Framebuffer {
        let mut fb = Framebuffer::new(3, 2);
        fb.pixels[0] = [255, 0, 0];
        fb.pixels[5] = [1, 2, 3];
        fb
    }

    #[test]
    fn bmp_and_png_round_trip() {
        let dir = tempfile_dir("roundtrip");
        for ext in ["bmp", "png"] {
            let p = dir.join(format!("x.{ext}"));
            write_image(&tiny(), &p).unwrap();
            assert_eq!(Framebuffer::load(&p).unwrap(), tiny());
        }
        assert!(matches!(
            write_image(&tiny(), &dir.join("x.jpg")),
            Err(OutputError::Extension { .. })
        ));
    }

    #[test]
    fn default_names_never_overwrite() {
        let dir = tempfile_dir("names");
        fs::write(dir.join("Output_11.bmp"), b"mine").unwrap();
        let p = write_next_output(&tiny(), &dir).unwrap();
        assert_eq!(p.file_name().unwrap(), "Output_12.bmp");
        assert_eq!(fs::read(dir.join("Output_11.bmp")).unwrap(), b"mine");
        let p = write_next_output(&tiny(), &dir).unwrap();
        assert_eq!(p.file_name().unwrap(), "Output_13.bmp");
        assert_eq!(temporaries_in(&dir), 0);
    }

    /// A dangling symbolic link named Output_11.bmp is a taken name: skipped, not
    /// written through, not retried forever.
    #[cfg(unix)]
    #[test]
    fn dangling_links_take_their_names() {
        let dir = tempfile_dir("links");
        std::os::unix::fs::symlink(dir.join("nowhere"), dir.join("Output_11.bmp")).unwrap();
        let p = write_next_output(&tiny(), &dir).unwrap();
        assert_eq!(p.file_name().unwrap(), "Output_12.bmp");
        assert!(!dir.join("nowhere").exists());
    }

    /// A name of 250 bytes (legal) is written: the temporary name stays short.
    #[test]
    fn long_names_are_written() {
        let dir = tempfile_dir("long");
        let p = dir.join(format!("{}.bmp", "n".repeat(246)));
        write_image(&tiny(), &p).unwrap();
        assert_eq!(Framebuffer::load(&p).unwrap(), tiny());
    }

    #[test]
    fn outputs_are_checked_before_any_work() {
        let dir = tempfile_dir("check");
        assert!(check_output(&dir.join("a.bmp"), true).is_ok());
        assert!(check_output(&dir.join("a.md"), false).is_ok());
        assert!(matches!(
            check_output(&dir.join("a.jpg"), true),
            Err(OutputError::Extension { .. })
        ));
        assert!(check_output(&dir.join("missing/a.bmp"), true).is_err());
        // names the rename would refuse only after the render
        let text = dir.display().to_string();
        for bad in [format!("{text}/a.bmp/"), format!("{text}/a.bmp/.")] {
            assert!(check_output(Path::new(&bad), true).is_err(), "{bad}");
        }
        let long = dir.join(format!("{}.bmp", "n".repeat(252)));
        assert!(check_output(&long, true).is_err());
        assert!(check_output(&dir.join(format!("{}.bmp", "n".repeat(251))), true).is_ok());
        assert!(check_output_dir(&dir).is_ok());
        assert!(check_output_dir(&dir.join("missing")).is_err());
        fs::create_dir_all(dir.join("d.bmp")).unwrap();
        assert!(check_output(&dir.join("d.bmp"), true).is_err());
    }

    /// Replacing a file keeps its permissions; a symbolic link stays a link and its
    /// file gets the image; a link to nothing and a file without write permission are
    /// refused, up front and when writing, and left as they were.
    #[cfg(unix)]
    #[test]
    fn replaced_files_keep_their_mode_and_links_are_written_through() {
        use std::os::unix::fs::{FileTypeExt, PermissionsExt, symlink};
        let dir = tempfile_dir("replace");
        let mode = |p: &Path| fs::metadata(p).unwrap().permissions().mode() & 0o777;
        let kept = dir.join("kept.bmp");
        fs::write(&kept, b"old").unwrap();
        // (a mode no umask gives a new file)
        fs::set_permissions(&kept, fs::Permissions::from_mode(0o604)).unwrap();
        write_image(&tiny(), &kept).unwrap();
        assert_eq!(mode(&kept), 0o604);
        assert_eq!(Framebuffer::load(&kept).unwrap(), tiny());

        let (real, link) = (dir.join("real.bmp"), dir.join("link.bmp"));
        fs::write(&real, b"old").unwrap();
        symlink(&real, &link).unwrap();
        assert!(check_output(&link, true).is_ok());
        write_image(&tiny(), &link).unwrap();
        assert!(
            fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(Framebuffer::load(&real).unwrap(), tiny());

        let device = dir.join("null.bmp");
        symlink("/dev/null", &device).unwrap();
        assert!(check_output(&device, true).is_err());
        assert!(write_image(&tiny(), &device).is_err());
        assert!(
            fs::metadata("/dev/null")
                .unwrap()
                .file_type()
                .is_char_device()
        );

        let dangling = dir.join("dangling.bmp");
        symlink(dir.join("nowhere.bmp"), &dangling).unwrap();
        assert!(check_output(&dangling, true).is_err());
        assert!(write_image(&tiny(), &dangling).is_err());
        assert!(!dir.join("nowhere.bmp").exists());
        assert!(
            fs::symlink_metadata(&dangling)
                .unwrap()
                .file_type()
                .is_symlink()
        );

        // a file this process may not write is left alone (root may write any file,
        // and then replaces it, as `cp` would)
        let locked = dir.join("locked.bmp");
        fs::write(&locked, b"mine").unwrap();
        fs::set_permissions(&locked, fs::Permissions::from_mode(0o444)).unwrap();
        if fs::OpenOptions::new().write(true).open(&locked).is_err() {
            assert!(check_output(&locked, true).is_err());
            assert!(write_image(&tiny(), &locked).is_err());
            assert_eq!(fs::read(&locked).unwrap(), b"mine");
        } else {
            assert!(check_output(&locked, true).is_ok());
            write_image(&tiny(), &locked).unwrap();
            assert_eq!(Framebuffer::load(&locked).unwrap(), tiny());
            assert_eq!(mode(&locked), 0o444);
        }
        assert_eq!(temporaries_in(&dir), 0);
    }

    /// Two outputs name the same file through `..`, a symbolic link or not at all.
    #[cfg(unix)]
    #[test]
    fn same_files_are_told_apart() {
        let dir = tempfile_dir("same");
        fs::create_dir_all(dir.join("sub")).unwrap();
        let a = dir.join("a.png");
        assert!(same_file(&a, &dir.join("sub/../a.png")));
        std::os::unix::fs::symlink(&a, dir.join("link.png")).unwrap();
        fs::write(&a, b"x").unwrap();
        assert!(same_file(&dir.join("link.png"), &a));
        assert!(!same_file(&a, &dir.join("b.png")));
    }

    /// Temporary files left behind in `dir` (their names start with a dot).
    fn temporaries_in(dir: &Path) -> usize {
        fs::read_dir(dir)
            .unwrap()
            .filter(|e| {
                let name = e.as_ref().unwrap().file_name();
                name.to_string_lossy().starts_with('.')
            })
            .count()
    }

    /// An empty directory of this test process, removed when dropped.
    fn tempfile_dir(tag: &str) -> TestDir {
        let d = std::env::temp_dir().join(format!("octaray-write-{tag}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        TestDir(d)
    }

    struct TestDir(PathBuf);

    impl std::ops::Deref for TestDir {
        type Target = Path;
        fn deref(&self) -> &Path {
            &self.0
        }
    }

    impl Drop for TestDir {
        fn drop(&mut self) {
            let _ = fs::remove_dir_all(&self.0);
        }
    }
}
