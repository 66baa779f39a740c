//! Camera path files: one camera per line, the frames of an animation
//! (`docs/camera-path.md`).
//!
//! ```text
//! // eye x y z        look-at x y z     up x y z   fov (vertical, degrees)
//! 100 100 50          0 0 10            0 0 1      80
//! 98.5 101.2 50.4     0 0 10            0 0 1      80
//! ```
//!
//! Ten whitespace-separated numbers a line, `//` comments to the end of the line, blank
//! lines skipped; lines end at LF, CRLF or a lone CR. Frame k is the k-th camera (from
//! 0), whatever the line it is on. Errors name file, line, column and field. The
//! module stands alone (its own line splitting and errors), beside the scene format.

use std::fmt;
use std::path::Path;

use glam::DVec3;

use super::Camera;

/// One line of a camera path: what `octaray render --eye --look-at --up --fov` takes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathCamera {
    pub eye: DVec3,
    pub look_at: DVec3,
    pub up: DVec3,
    /// Vertical field of view in degrees, in (0, 180).
    pub fov_y_deg: f64,
    /// The line of the file it is on (1-based).
    pub line: usize,
}

impl PathCamera {
    /// The camera, built as `octaray render --eye --look-at --up --fov` builds it
    /// ([`Camera::look_at`]); the parser has checked that it exists.
    pub fn camera(&self) -> Camera {
        Camera::look_at(self.eye, self.look_at, self.up, self.fov_y_deg)
            .expect("checked when the path was read")
    }
}

/// A rejected camera path: `file:line:col: field: message`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CameraPathError {
    pub file: String,
    /// 1-based (0: the file as a whole, e.g. unreadable).
    pub line: usize,
    /// 1-based, in characters.
    pub col: usize,
    /// What was being read, e.g. `camera 3: fov`.
    pub field: String,
    pub message: String,
}

impl fmt::Display for CameraPathError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:{}: {}: {}",
            self.file, self.line, self.col, self.field, self.message
        )
    }
}

impl std::error::Error for CameraPathError {}

/// The fields of a line, in order.
const FIELDS: [&str; 10] = [
    "eye x",
    "eye y",
    "eye z",
    "look-at x",
    "look-at y",
    "look-at z",
    "up x",
    "up y",
    "up z",
    "fov",
];

/// Reads a camera path file (a regular file or a pipe, as scene files).
pub fn read_camera_path(path: &Path) -> Result<Vec<PathCamera>, CameraPathError> {
    let name = path.display().to_string();
    let bytes = super::read_input(path).map_err(|e| CameraPathError {
        file: name.clone(),
        line: 0,
        col: 0,
        field: "file".into(),
        message: format!("cannot read: {e}"),
    })?;
    parse_camera_path(&String::from_utf8_lossy(&bytes), &name)
}

/// Parses camera path text; `file` is only used in messages. Bytes that were not
/// UTF-8 (read as U+FFFD) are harmless in comments and fail as "not a number" in a
/// value.
pub fn parse_camera_path(text: &str, file: &str) -> Result<Vec<PathCamera>, CameraPathError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut cameras = Vec::new();
    for (line_no, line) in lines(text) {
        let tokens = tokens(line);
        if tokens.is_empty() {
            continue;
        }
        let who = format!("camera {}", cameras.len() + 1);
        let error = |col: usize, field: &str, message: String| CameraPathError {
            file: file.into(),
            line: line_no,
            col,
            field: format!("{who}: {field}"),
            message,
        };
        let mut v = [0.0; 10];
        for (k, (out, field)) in v.iter_mut().zip(FIELDS).enumerate() {
            let Some(&(col, token)) = tokens.get(k) else {
                let end = line.chars().count() + 1;
                return Err(error(
                    end,
                    field,
                    format!(
                        "expected 10 numbers (eye, look-at, up, fov), found {}",
                        tokens.len()
                    ),
                ));
            };
            *out = match token.parse::<f64>() {
                Ok(x) if x.is_finite() => x,
                Ok(_) => {
                    return Err(error(
                        col,
                        field,
                        format!("expected a finite number, got '{token}'"),
                    ));
                }
                Err(_) => {
                    return Err(error(
                        col,
                        field,
                        format!("expected a number, found '{token}'"),
                    ));
                }
            };
        }
        if let Some(&(col, token)) = tokens.get(10) {
            return Err(error(
                col,
                "end of line",
                format!("expected 10 numbers a line, found more: '{token}'"),
            ));
        }
        let col = |k: usize| tokens[k].0;
        let camera = PathCamera {
            eye: DVec3::new(v[0], v[1], v[2]),
            look_at: DVec3::new(v[3], v[4], v[5]),
            up: DVec3::new(v[6], v[7], v[8]),
            fov_y_deg: v[9],
            line: line_no,
        };
        if !(camera.fov_y_deg > 0.0 && camera.fov_y_deg < 180.0) {
            return Err(error(
                col(9),
                "fov",
                format!("expected a field of view in (0, 180) degrees, got {}", v[9]),
            ));
        }
        if Camera::look_at(camera.eye, camera.look_at, camera.up, camera.fov_y_deg).is_none() {
            let look = camera.look_at - camera.eye;
            let (at, field, message) = if !look.is_finite() {
                (
                    col(3),
                    "look-at",
                    "the view direction overflows (eye and look-at too far apart)",
                )
            } else if look == DVec3::ZERO {
                (
                    col(3),
                    "look-at",
                    "the view direction is zero (the eye is the point looked at)",
                )
            } else {
                (col(6), "up", "parallel to the view direction (or zero)")
            };
            return Err(error(at, field, message.into()));
        }
        cameras.push(camera);
    }
    Ok(cameras)
}

/// The lines of `text` with their 1-based numbers (the scene format's line ends).
fn lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    super::text::lines(text)
        .enumerate()
        .map(|(i, l)| (i + 1, l))
}

/// The tokens of one line and their 1-based columns (in characters): split at
/// whitespace, up to a `//` comment (which also ends a token: `1//x` is `1`).
fn tokens(line: &str) -> Vec<(usize, &str)> {
    let line = line.find("//").map_or(line, |i| &line[..i]);
    let mut out = Vec::new();
    let mut start: Option<(usize, usize)> = None;
    for (col, (i, c)) in line.char_indices().enumerate() {
        if c.is_whitespace() {
            if let Some((s, sc)) = start.take() {
                out.push((sc, &line[s..i]));
            }
        } else if start.is_none() {
            start = Some((i, col + 1));
        }
    }
    if let Some((s, sc)) = start {
        out.push((sc, &line[s..]));
    }
    out
}

/// The line of a camera path that gives `camera`: eye, eye + look, up, fov, each number
/// written so that it reads back exactly. Rendering the line gives the camera again up
/// to the rounding of normalising `look`.
pub fn format_line(camera: &Camera) -> String {
    let v = |p: DVec3| format!("{:?} {:?} {:?}", p.x, p.y, p.z);
    format!(
        "{}  {}  {}  {:?}",
        v(camera.eye),
        v(camera.eye + camera.look),
        v(camera.up),
        camera.fov_y_deg
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<PathCamera>, CameraPathError> {
        parse_camera_path(text, "path.txt")
    }

    fn error(text: &str) -> String {
        parse(text).expect_err("an error").to_string()
    }

    #[test]
    fn cameras_are_read_one_a_line_with_comments_and_blank_lines() {
        let text = "// a flight\n\n100 100 50  0 0 10  0 0 1  80  // first\n  \t\n\
                    1e2 -3.5 7 0 0 0 0 0 1 45.5\n";
        let path = parse(text).unwrap();
        assert_eq!(path.len(), 2);
        assert_eq!(path[0].eye, DVec3::new(100.0, 100.0, 50.0));
        assert_eq!(path[0].look_at, DVec3::new(0.0, 0.0, 10.0));
        assert_eq!(path[0].up, DVec3::Z);
        assert_eq!((path[0].fov_y_deg, path[0].line), (80.0, 3));
        assert_eq!(path[1].eye, DVec3::new(100.0, -3.5, 7.0));
        assert_eq!((path[1].fov_y_deg, path[1].line), (45.5, 5));
        assert!(parse("").unwrap().is_empty());
        assert!(parse("// nothing\n").unwrap().is_empty());
    }

    #[test]
    fn lf_crlf_and_lone_cr_end_lines_alike() {
        let line = "1 2 3 0 0 0 0 0 1 60";
        for end in ["\n", "\r\n", "\r"] {
            let text = format!("// c{end}{line}{end}{end}{line} oops{end}");
            let e = parse(&text).expect_err("the 4th line is bad");
            assert_eq!((e.line, e.col), (4, 22), "{end:?}: {e}");
            let ok = parse(&format!("{line}{end}// c{end}{line}")).unwrap();
            assert_eq!(
                ok.iter().map(|c| c.line).collect::<Vec<_>>(),
                [1, 3],
                "{end:?}"
            );
        }
    }

    #[test]
    fn errors_name_line_column_and_field() {
        assert_eq!(
            error("1 2 3 0 0 0 0 0 1 60\n1 2 3 0 0 0 0 0 1\n"),
            "path.txt:2:18: camera 2: fov: expected 10 numbers (eye, look-at, up, fov), found 9"
        );
        assert_eq!(
            error("1 2 x 0 0 0 0 0 1 60"),
            "path.txt:1:5: camera 1: eye z: expected a number, found 'x'"
        );
        assert_eq!(
            error("1 2 3 0 nan 0 0 0 1 60"),
            "path.txt:1:9: camera 1: look-at y: expected a finite number, got 'nan'"
        );
        assert_eq!(
            error("1 2 3 0 0 0 0 0 1 180"),
            "path.txt:1:19: camera 1: fov: expected a field of view in (0, 180) degrees, got 180"
        );
        assert_eq!(
            error("1 2 3 1 2 3 0 0 1 60"),
            "path.txt:1:7: camera 1: look-at: the view direction is zero (the eye is the point looked at)"
        );
        assert_eq!(
            error("0 0 9 0 0 0 0 0 1 60"),
            "path.txt:1:13: camera 1: up: parallel to the view direction (or zero)"
        );
        assert_eq!(
            error("1 2 3 0 0 0 0 0 1 60 7"),
            "path.txt:1:22: camera 1: end of line: expected 10 numbers a line, found more: '7'"
        );
        // columns count characters, not bytes; a non-UTF-8 byte is harmless in a comment
        assert_eq!(
            error("// é\n\u{e9} 2 3 0 0 0 0 0 1 60"),
            "path.txt:2:1: camera 1: eye x: expected a number, found '\u{e9}'"
        );
        assert_eq!(
            parse("1 2 3 0 0 0 0 0 1 60 // \u{fffd}\u{fffd}")
                .unwrap()
                .len(),
            1
        );
        // a comment ends a token
        assert_eq!(parse("1 2 3 0 0 0 0 0 1 60//x").unwrap().len(), 1);
        // a byte-order mark is not part of the first number
        assert_eq!(parse("\u{feff}1 2 3 0 0 0 0 0 1 60").unwrap()[0].eye.x, 1.0);
    }

    #[test]
    fn files_are_read_and_unreadable_ones_named() {
        let dir = std::env::temp_dir().join(format!("octaray-camera-path-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("p.txt");
        std::fs::write(&file, b"1 2 3 0 0 0 0 0 1 60 // \xb0\n").unwrap();
        assert_eq!(read_camera_path(&file).unwrap().len(), 1);
        let e = read_camera_path(&dir.join("missing.txt")).unwrap_err();
        assert_eq!((e.line, e.field.as_str()), (0, "file"));
        assert!(e.to_string().contains("missing.txt"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A recorded line reads back as the camera's eye, up and fov exactly and its view
    /// direction to rounding, and renders as `--eye --look-at --up --fov` would.
    #[test]
    fn recorded_lines_read_back() {
        let camera = Camera::from_look(
            DVec3::new(0.1, -1e-7, 12345.678),
            DVec3::new(-1.0, 0.3, -0.2),
            DVec3::new(0.0, 0.1, 1.0),
            33.3,
        )
        .unwrap();
        let line = format_line(&camera);
        let back = parse(&line).unwrap()[0];
        assert_eq!(back.eye, camera.eye);
        assert_eq!(back.up, camera.up);
        assert_eq!(back.fov_y_deg, camera.fov_y_deg);
        let rebuilt = back.camera();
        assert!((rebuilt.look - camera.look).length() < 1e-12);
        assert!((rebuilt.up - camera.up).length() < 1e-12);
    }
}
