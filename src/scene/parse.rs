//! Scene text → [`Scene`], with errors that name the file, line, column and field.
//!
//! The format (see `docs/scene-format.md`): whitespace-separated tokens read by counts,
//! line breaks carry no meaning, `//` comments run to the end of the line, keywords are
//! case-insensitive. Every number must be finite; every count an integer in range.
//! The spotlight block is optional; everything after it is ignored.

use std::fmt;
use std::path::Path;

use glam::DVec3;

use super::{Glass, Material, Object, PointLight, Quadric, Scene, Shape, SpotLight};

/// Largest accepted `recursion_level` (level N gives N − 1 bounces; deeper is pointless).
pub const MAX_RECURSION_LEVEL: i64 = 1_000_000;
/// Largest image side octaray renders (16384² RGB is 805 MB). A scene file may ask for
/// more (the format allows any `pixels` >= 1): it loads, and rendering it at its own
/// size is refused with [`Parsed::too_large`], while `--size` may render it smaller.
pub const MAX_PIXELS: i64 = 16_384;
/// Largest accepted object or light count.
pub const MAX_COUNT: i64 = 50_000_000;

/// A rejected scene file: `file:line:col: field: message`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParseError {
    pub file: String,
    /// 1-based.
    pub line: usize,
    /// 1-based, in characters.
    pub col: usize,
    /// What was being read, e.g. `sphere 2: radius`.
    pub field: String,
    pub message: String,
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:{}: {}: {}",
            self.file, self.line, self.col, self.field, self.message
        )
    }
}

impl std::error::Error for ParseError {}

/// A parsed scene and the notes and warnings met on the way (each already prefixed
/// with `file:line:col:`), for the caller to print.
#[derive(Clone, Debug)]
pub struct Parsed {
    pub scene: Scene,
    pub warnings: Vec<String>,
    /// Set when `pixels` exceeds [`MAX_PIXELS`]: the error (at the `pixels` token) to
    /// report should the scene be rendered at its own size.
    pub too_large: Option<ParseError>,
}

/// Reads and parses a scene file.
pub fn parse_scene_file(path: &Path) -> Result<Parsed, ParseError> {
    let name = path.display().to_string();
    let bytes = super::read_input(path).map_err(|e| ParseError {
        file: name.clone(),
        line: 0,
        col: 0,
        field: "file".into(),
        message: format!("cannot read: {e}"),
    })?;
    parse_scene_bytes(&bytes, &name)
}

/// Parses scene bytes; rejects binary data and invalid UTF-8 with their position.
pub fn parse_scene_bytes(bytes: &[u8], file: &str) -> Result<Parsed, ParseError> {
    // Bytes that are not UTF-8 text (a cp1252 degree sign, a NUL) may sit in a comment
    // or in the ignored rest of the file: they are read as U+FFFD and only matter if the
    // scene needs the token they are in. A file that fails before its first such byte
    // fails as usual; one that fails at or after it (a binary file fails at once) is
    // reported as not a text scene file, at that byte.
    let text = String::from_utf8_lossy(bytes);
    let (valid, invalid_at) = match std::str::from_utf8(bytes) {
        Ok(t) => (t, None),
        Err(e) => {
            let n = e.valid_up_to();
            // (the first n bytes are valid UTF-8, as from_utf8 reports)
            (std::str::from_utf8(&bytes[..n]).unwrap_or(""), Some(n))
        }
    };
    let control = valid.find(|c: char| c == '\0' || (c.is_control() && !c.is_whitespace()));
    let first_bad = control.or(invalid_at);
    let parsed = parse_scene(&text, file);
    let (Err(e), Some(bad)) = (&parsed, first_bad) else {
        return parsed;
    };
    // (lines counted as the tokenizer counts them: LF, CRLF or a lone CR)
    let prefix = String::from_utf8_lossy(&bytes[..bad])
        .replace("\r\n", "\n")
        .replace('\r', "\n");
    let line = prefix.matches('\n').count() + 1;
    let col = prefix.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    if (e.line, e.col) < (line, col) {
        return parsed;
    }
    Err(ParseError {
        file: file.into(),
        line,
        col,
        field: "file".into(),
        message: format!("not a text scene file (binary or non-UTF-8 byte at offset {bad})"),
    })
}

/// Parses scene text. `file` is only used in messages.
pub fn parse_scene(text: &str, file: &str) -> Result<Parsed, ParseError> {
    // a byte-order mark, as some editors write, is not part of the first number
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut r = Reader::new(text, file);
    let scene = r.scene()?;
    Ok(Parsed {
        scene,
        warnings: r.warnings,
        too_large: r.too_large,
    })
}

#[derive(Clone, Copy, Debug)]
struct Token<'a> {
    text: &'a str,
    line: usize,
    col: usize,
}

fn tokenize(text: &str) -> (Vec<Token<'_>>, (usize, usize)) {
    let mut tokens = Vec::new();
    let (mut line, mut col) = (1, 1);
    let mut start: Option<(usize, usize, usize)> = None;
    let mut chars = text.char_indices().peekable();
    while let Some((i, c)) = chars.next() {
        let comment = c == '/' && matches!(chars.peek(), Some((_, '/')));
        if c.is_whitespace() || comment {
            if let Some((s, l, cl)) = start.take() {
                tokens.push(Token {
                    text: &text[s..i],
                    line: l,
                    col: cl,
                });
            }
            if comment {
                // Skip to the end of the line; the newline itself is handled below.
                while let Some(&(_, n)) = chars.peek() {
                    if n == '\n' || n == '\r' {
                        break;
                    }
                    chars.next();
                }
                continue;
            }
            // a line ends at LF, CRLF or a lone CR (old Mac files)
            let lone_cr = c == '\r' && !matches!(chars.peek(), Some((_, '\n')));
            if c == '\n' || lone_cr {
                line += 1;
                col = 1;
            } else {
                col += 1;
            }
            continue;
        }
        if start.is_none() {
            start = Some((i, line, col));
        }
        col += 1;
    }
    if let Some((s, l, cl)) = start {
        tokens.push(Token {
            text: &text[s..],
            line: l,
            col: cl,
        });
    }
    (tokens, (line, col))
}

struct Reader<'a> {
    file: &'a str,
    tokens: Vec<Token<'a>>,
    pos: usize,
    /// Position just past the last character, for "end of file" errors.
    end: (usize, usize),
    warnings: Vec<String>,
    too_large: Option<ParseError>,
}

impl<'a> Reader<'a> {
    fn new(text: &'a str, file: &'a str) -> Self {
        let (tokens, end) = tokenize(text);
        Reader {
            file,
            tokens,
            pos: 0,
            end,
            warnings: Vec::new(),
            too_large: None,
        }
    }

    fn error_at(&self, at: Option<Token<'_>>, field: &str, message: String) -> ParseError {
        let (line, col) = at.map_or(self.end, |t| (t.line, t.col));
        ParseError {
            file: self.file.into(),
            line,
            col,
            field: field.into(),
            message,
        }
    }

    fn warn_at(&mut self, at: Token<'_>, what: String) {
        let msg = format!("{}:{}:{}: {}", self.file, at.line, at.col, what);
        self.warnings.push(msg);
    }

    fn peek(&self) -> Option<Token<'a>> {
        self.tokens.get(self.pos).copied()
    }

    fn next(&mut self, field: &str, expected: &str) -> Result<Token<'a>, ParseError> {
        match self.peek() {
            Some(t) => {
                self.pos += 1;
                Ok(t)
            }
            None => Err(self.error_at(
                None,
                field,
                format!("expected {expected}, found end of file"),
            )),
        }
    }

    /// A finite real number.
    fn number(&mut self, field: &str) -> Result<(f64, Token<'a>), ParseError> {
        let t = self.next(field, "a number")?;
        match t.text.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok((v, t)),
            Ok(_) => Err(self.error_at(
                Some(t),
                field,
                format!("expected a finite number, got '{}'", t.text),
            )),
            Err(_) => Err(self.error_at(
                Some(t),
                field,
                format!("expected a number, found '{}'", t.text),
            )),
        }
    }

    fn number_ge0(&mut self, field: &str) -> Result<f64, ParseError> {
        let (v, t) = self.number(field)?;
        if v < 0.0 {
            return Err(self.error_at(Some(t), field, format!("must be >= 0, got {}", t.text)));
        }
        Ok(v)
    }

    fn integer(&mut self, field: &str, min: i64, max: i64) -> Result<i64, ParseError> {
        let t = self.next(field, "an integer")?;
        let v: i64 = match t.text.parse::<i64>() {
            Ok(v) => v,
            Err(_) if t.text.parse::<f64>().is_ok() || looks_integral(t.text) => {
                return Err(self.error_at(
                    Some(t),
                    field,
                    format!("expected an integer in {min}..={max}, got {}", t.text),
                ));
            }
            Err(_) => {
                return Err(self.error_at(
                    Some(t),
                    field,
                    format!("expected an integer, found '{}'", t.text),
                ));
            }
        };
        if v < min || v > max {
            return Err(self.error_at(
                Some(t),
                field,
                format!("expected an integer in {min}..={max}, got {v}"),
            ));
        }
        Ok(v)
    }

    fn vec3(&mut self, field: &str) -> Result<(DVec3, Token<'a>), ParseError> {
        let (x, t) = self.number(&format!("{field}.x"))?;
        let (y, _) = self.number(&format!("{field}.y"))?;
        let (z, _) = self.number(&format!("{field}.z"))?;
        Ok((DVec3::new(x, y, z), t))
    }

    /// A light's colour: any finite r g b (the spec sets no range for lights).
    fn color(&mut self, field: &str) -> Result<DVec3, ParseError> {
        let (r, _) = self.number(&format!("{field}.r"))?;
        let (g, _) = self.number(&format!("{field}.g"))?;
        let (b, _) = self.number(&format!("{field}.b"))?;
        Ok(DVec3::new(r, g, b))
    }

    fn color_ge0(&mut self, field: &str) -> Result<DVec3, ParseError> {
        let r = self.number_ge0(&format!("{field}.r"))?;
        let g = self.number_ge0(&format!("{field}.g"))?;
        let b = self.number_ge0(&format!("{field}.b"))?;
        Ok(DVec3::new(r, g, b))
    }

    fn material(&mut self, who: &str) -> Result<Material, ParseError> {
        Ok(Material {
            color: self.color_ge0(&format!("{who}: color"))?,
            ka: self.number_ge0(&format!("{who}: ambient coefficient"))?,
            kd: self.number_ge0(&format!("{who}: diffuse coefficient"))?,
            ks: self.number_ge0(&format!("{who}: specular coefficient"))?,
            kr: self.number_ge0(&format!("{who}: reflection coefficient"))?,
            shine: self.number_ge0(&format!("{who}: shine"))?,
        })
    }

    fn scene(&mut self) -> Result<Scene, ParseError> {
        let recursion_level = self.integer("recursion_level", 0, MAX_RECURSION_LEVEL)? as u32;
        let at = self.peek();
        let pixels = self.integer("pixels", 1, u32::MAX.into())? as u32;
        if i64::from(pixels) > MAX_PIXELS {
            self.too_large = Some(self.error_at(
                at,
                "pixels",
                format!(
                    "{pixels} is above octaray's limit of {MAX_PIXELS} pixels per side; \
                     render it smaller with --size"
                ),
            ));
        }
        let n_objects = self.integer("n_objects", 0, MAX_COUNT)?;
        let mut objects = Vec::new();
        let mut per_kind = [0usize; 5];
        for k in 1..=n_objects {
            let field = format!("object {k}: kind");
            let t = self.next(&field, "an object kind")?;
            let kind = t.text.to_ascii_lowercase();
            let idx = match kind.as_str() {
                "sphere" => 0,
                "triangle" => 1,
                "general" => 2,
                "prism" => 3,
                "mesh" => 4,
                _ => {
                    return Err(self.error_at(
                        Some(t),
                        &field,
                        format!(
                            "unknown object kind '{}' (expected sphere, triangle, general, prism or mesh)",
                            t.text
                        ),
                    ));
                }
            };
            per_kind[idx] += 1;
            let who = format!("{kind} {}", per_kind[idx]);
            let shape = self.shape(&kind, &who, t)?;
            let material = self.material(&who)?;
            let shape = match shape {
                Shape::Prism { v, .. } => Shape::Prism {
                    v,
                    glass: self.glass(&who)?,
                },
                s => s,
            };
            objects.push(Object { shape, material });
        }

        let n_point = self.integer("n_point_lights", 0, MAX_COUNT)?;
        let mut point_lights = Vec::new();
        for k in 1..=n_point {
            let who = format!("point light {k}");
            let (position, _) = self.vec3(&format!("{who}: position"))?;
            let color = self.color(&format!("{who}: color"))?;
            point_lights.push(PointLight { position, color });
        }

        let mut spot_lights = Vec::new();
        match self.peek() {
            None => {
                let msg = "note: the file ends after the point lights: no spotlights".to_string();
                self.warnings.push(format!(
                    "{}:{}:{}: {msg}",
                    self.file, self.end.0, self.end.1
                ));
            }
            // (a word such as "Infinity" or "NaN" opening prose is not a count)
            Some(t)
                if t.text.parse::<f64>().is_err()
                    || !t.text.bytes().any(|b| b.is_ascii_digit()) =>
            {
                let msg = format!(
                    "note: '{}' is not a spotlight count: no spotlights; the rest of the file is ignored",
                    t.text
                );
                self.warn_at(t, msg);
            }
            Some(_) => {
                let n_spot = self.integer("n_spot_lights", 0, MAX_COUNT)?;
                for k in 1..=n_spot {
                    let who = format!("spot light {k}");
                    let (position, _) = self.vec3(&format!("{who}: position"))?;
                    let color = self.color(&format!("{who}: color"))?;
                    let (direction, dt) = self.vec3(&format!("{who}: direction"))?;
                    let Some(unit) = crate::math::float::unit(direction) else {
                        return Err(self.error_at(
                            Some(dt),
                            &format!("{who}: direction"),
                            "must be a non-zero vector".into(),
                        ));
                    };
                    let field = format!("{who}: cutoff angle");
                    let (cutoff_deg, ct) = self.number(&field)?;
                    if !(0.0..=180.0).contains(&cutoff_deg) {
                        return Err(self.error_at(
                            Some(ct),
                            &field,
                            format!("must be in 0..=180 degrees, got {}", ct.text),
                        ));
                    }
                    spot_lights.push(SpotLight {
                        position,
                        color,
                        direction: unit,
                        cutoff_deg,
                    });
                }
            }
        }

        Ok(Scene {
            recursion_level,
            pixels,
            objects,
            point_lights,
            spot_lights,
        })
    }

    fn shape(&mut self, kind: &str, who: &str, at: Token<'_>) -> Result<Shape, ParseError> {
        match kind {
            "sphere" => {
                let (center, _) = self.vec3(&format!("{who}: center"))?;
                let field = format!("{who}: radius");
                let (radius, rt) = self.number(&field)?;
                if radius <= 0.0 {
                    return Err(self.error_at(
                        Some(rt),
                        &field,
                        format!("must be > 0, got {}", rt.text),
                    ));
                }
                Ok(Shape::Sphere { center, radius })
            }
            "triangle" => {
                let mut v = [DVec3::ZERO; 3];
                for (i, p) in v.iter_mut().enumerate() {
                    *p = self.vec3(&format!("{who}: vertex {}", i + 1))?.0;
                }
                if is_degenerate_triangle(&v) {
                    self.warn_at(
                        at,
                        format!("warning: {who} has zero area; it will never be hit"),
                    );
                }
                Ok(Shape::Triangle { v })
            }
            "general" => {
                const NAMES: [&str; 10] = ["A", "B", "C", "D", "E", "F", "G", "H", "I", "J"];
                let mut coef = [0.0; 10];
                for (c, name) in coef.iter_mut().zip(NAMES) {
                    *c = self.number(&format!("{who}: coefficient {name}"))?.0;
                }
                let (min, _) = self.vec3(&format!("{who}: box corner"))?;
                let size = DVec3::new(
                    self.number_ge0(&format!("{who}: box length"))?,
                    self.number_ge0(&format!("{who}: box width"))?,
                    self.number_ge0(&format!("{who}: box height"))?,
                );
                let scale = coef.iter().fold(0.0f64, |m, c| m.max(c.abs()));
                if scale == 0.0 {
                    self.warn_at(
                        at,
                        format!("warning: {who} has all-zero coefficients; it will never be hit"),
                    );
                } else {
                    coef.iter_mut().for_each(|c| *c /= scale);
                }
                Ok(Shape::Quadric(Quadric { coef, min, size }))
            }
            "prism" => {
                let mut v = [DVec3::ZERO; 6];
                for (i, p) in v.iter_mut().enumerate() {
                    *p = self.vec3(&format!("{who}: vertex {}", i + 1))?.0;
                }
                // Glass parameters follow the material; filled in by the caller.
                Ok(Shape::Prism {
                    v,
                    glass: Glass {
                        kt: 0.0,
                        cauchy_a: 1.0,
                        cauchy_b: 0.0,
                    },
                })
            }
            "mesh" => {
                // the OBJ path is relative to the scene file
                let field = format!("{who}: path");
                let t = self.next(&field, "an OBJ file path")?;
                let base = Path::new(self.file).parent().unwrap_or(Path::new(""));
                let mesh = super::obj::load_obj(&base.join(t.text))
                    .map_err(|e| self.error_at(Some(t), &field, e.to_string()))?;
                let degenerate = (0..mesh.triangles.len())
                    .filter(|&k| is_degenerate_triangle(&mesh.triangle(k)))
                    .count();
                if mesh.triangles.is_empty() {
                    // (lower-case `v` and `f` lines only; anything else is ignored)
                    self.warn_at(
                        at,
                        format!("warning: {who} has no triangles (no `f` lines); it is empty"),
                    );
                } else if degenerate > 0 {
                    self.warn_at(
                        at,
                        format!(
                            "warning: {who} has {degenerate} zero-area triangles; they will never be hit"
                        ),
                    );
                }
                Ok(Shape::Mesh(std::sync::Arc::new(mesh)))
            }
            _ => unreachable!("kind checked by the caller"),
        }
    }

    fn glass(&mut self, who: &str) -> Result<Glass, ParseError> {
        let kt = self.number_ge0(&format!("{who}: kt"))?;
        let field = format!("{who}: cauchy_a");
        let (cauchy_a, t) = self.number(&field)?;
        if cauchy_a <= 0.0 {
            return Err(self.error_at(Some(t), &field, format!("must be > 0, got {}", t.text)));
        }
        let cauchy_b = self.number_ge0(&format!("{who}: cauchy_b"))?;
        Ok(Glass {
            kt,
            cauchy_a,
            cauchy_b,
        })
    }
}

fn looks_integral(s: &str) -> bool {
    let digits = s.strip_prefix(['-', '+']).unwrap_or(s);
    !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())
}

/// A triangle is degenerate when its edge vectors are (nearly) parallel: |e1 × e2| is
/// below 1e-12 · |e1| · |e2| (the sine of its sharpest angle under 1e-12), or an edge
/// has length zero. Such a triangle has no well-defined normal and is never hit.
pub fn is_degenerate_triangle(v: &[DVec3; 3]) -> bool {
    let e1 = v[1] - v[0];
    let e2 = v[2] - v[0];
    let n = e1.cross(e2).length();
    let limit = 1e-12 * e1.length() * e2.length();
    // NaN (coordinates so large that the cross product overflows) is degenerate too.
    n.partial_cmp(&limit) != Some(std::cmp::Ordering::Greater)
}
