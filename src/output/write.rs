//! Writing images whole or not at all: encode to a temporary file in the target
//! directory, then rename it into place. Default names (`Output_11.bmp`, ...) are
//! claimed with a hard link, which fails instead of overwriting if the name was taken
//! in the meantime.

use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use image::ImageFormat;

use super::Framebuffer;

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{path}: unsupported image extension (use .bmp or .png)")]
    Extension { path: String },
    #[error("{path}: {source}")]
    Io { path: String, source: io::Error },
    #[error("{path}: {source}")]
    Encode {
        path: String,
        source: image::ImageError,
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

/// Encodes `fb` to a temporary file beside `path`; returns the temporary path.
fn write_temp(fb: &Framebuffer, path: &Path) -> Result<PathBuf, OutputError> {
    let format = format_for(path)?;
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty());
    let name = path
        .file_name()
        .map_or_else(|| "image".into(), |n| n.to_string_lossy().into_owned());
    let tmp_name = format!(".{name}.tmp-{}", std::process::id());
    let tmp = dir.map_or_else(|| PathBuf::from(&tmp_name), |d| d.join(&tmp_name));
    if format == ImageFormat::Bmp {
        return match fs::write(&tmp, super::bmp::encode(fb)) {
            Ok(()) => Ok(tmp),
            Err(source) => {
                let _ = fs::remove_file(&tmp);
                Err(OutputError::Io {
                    path: path.display().to_string(),
                    source,
                })
            }
        };
    }
    let result = image::save_buffer_with_format(
        &tmp,
        fb.as_bytes(),
        fb.width,
        fb.height,
        image::ExtendedColorType::Rgb8,
        format,
    );
    if let Err(source) = result {
        let _ = fs::remove_file(&tmp);
        return Err(OutputError::Encode {
            path: path.display().to_string(),
            source,
        });
    }
    Ok(tmp)
}

/// Writes `fb` to `path` (BMP or PNG by extension), replacing any existing file
/// atomically.
pub fn write_image(fb: &Framebuffer, path: &Path) -> Result<(), OutputError> {
    let tmp = write_temp(fb, path)?;
    fs::rename(&tmp, path).map_err(|source| {
        let _ = fs::remove_file(&tmp);
        OutputError::Io {
            path: path.display().to_string(),
            source,
        }
    })
}

/// Writes `fb` to `path` only if no file of that name exists; `Ok(false)` if one does.
pub fn write_image_no_clobber(fb: &Framebuffer, path: &Path) -> Result<bool, OutputError> {
    if path.exists() {
        return Ok(false);
    }
    let tmp = write_temp(fb, path)?;
    let linked = fs::hard_link(&tmp, path);
    let _ = fs::remove_file(&tmp);
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

/// The first `Output_1N.bmp` in `dir` that does not exist yet.
pub fn next_free_output(dir: &Path) -> PathBuf {
    (1..)
        .map(|n| dir.join(output_name(n)))
        .find(|p| !p.exists())
        .expect("some name is free")
}

/// Writes `fb` under the next free `Output_1N.bmp` in `dir`, never overwriting.
pub fn write_next_output(fb: &Framebuffer, dir: &Path) -> Result<PathBuf, OutputError> {
    loop {
        let path = next_free_output(dir);
        if write_image_no_clobber(fb, &path)? {
            return Ok(path);
        }
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
        // No temporary files are left behind.
        let leftovers = fs::read_dir(&dir)
            .unwrap()
            .filter(|e| {
                e.as_ref()
                    .unwrap()
                    .file_name()
                    .to_string_lossy()
                    .starts_with('.')
            })
            .count();
        assert_eq!(leftovers, 0);
    }

    fn tempfile_dir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("octaray-write-{tag}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        d
    }
}
