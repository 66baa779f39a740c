//! Scene text → [`Scene`], with errors that name the file, line, column and field.
//!
//! The format (see `docs/scene-format.md`): whitespace-separated tokens read by counts,
//! line breaks carry no meaning, `//` comments run to the end of the line, keywords are
//! case-insensitive. Every number must be finite; every count an integer in range.
//! The spotlight block is optional; everything after it is ignored (read, not kept).
//! Lines end as [`super::text`] rules; tokens quoted in messages are escaped there.

use std::fmt;
use std::io::Read;
use std::path::Path;

use glam::DVec3;

use super::input::Limited;
use super::text::{Position, escaped};
use super::{Glass, Material, Object, PointLight, Quadric, Scene, Shape, SpotLight};

/// Largest accepted `recursion_level` (level N gives N − 1 bounces; deeper is pointless).
pub const MAX_RECURSION_LEVEL: i64 = 1_000_000;
/// Largest image side octaray renders (16384² RGB is 805 MB). A scene file may ask for
/// more (the format allows any `pixels` >= 1): it loads, and rendering it at its own
/// size is refused with [`Parsed::too_large`], while `--size` may render it smaller.
pub const MAX_PIXELS: i64 = 16_384;
/// Largest accepted object or light count.
pub const MAX_COUNT: i64 = 50_000_000;
/// Most triangles a scene may hold, triangle objects, prism faces (8 a prism) and mesh
/// triangles together: the packet path numbers its triangles in
/// 28 bits (the fast path's primitive codes), and a 4 GiB OBJ file of fan
/// polygons can describe two billion.
pub const MAX_TRIANGLES: u64 = (1 << 28) - 1;

/// A rejected scene file: `file:line:col: field: message`, or `file: field: message`
/// where there is no position (a file that cannot be read).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParseError {
    pub file: String,
    /// 1-based; 0: no position.
    pub line: usize,
    /// 1-based, in characters.
    pub col: usize,
    /// What was being read, e.g. `sphere 2: radius`.
    pub field: String,
    pub message: String,
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            return write!(f, "{}: {}: {}", self.file, self.field, self.message);
        }
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

/// Reads and parses a scene file (see [`parse_scene_reader`]).
pub fn parse_scene_file(path: &Path) -> Result<Parsed, ParseError> {
    let name = path.display().to_string();
    let file = super::input::open_input(path).map_err(|e| unreadable(&name, &e))?;
    parse_scene_reader(file, &name)
}

/// The error of an input that cannot be read: no position, the file is the field.
fn unreadable(file: &str, e: &std::io::Error) -> ParseError {
    ParseError {
        file: file.into(),
        line: 0,
        col: 0,
        field: "file".into(),
        message: format!("cannot read: {e}"),
    }
}

/// Parses scene bytes (see [`parse_scene_reader`]).
pub fn parse_scene_bytes(bytes: &[u8], file: &str) -> Result<Parsed, ParseError> {
    parse_scene_reader(bytes, file)
}

/// Parses scene text (see [`parse_scene_reader`]).
pub fn parse_scene(text: &str, file: &str) -> Result<Parsed, ParseError> {
    parse_scene_reader(text.as_bytes(), file)
}

/// Parses a scene from a stream (a file, a pipe, standard input), read to its end, at
/// most [`MAX_INPUT`](super::input::MAX_INPUT) bytes; `file` names it in messages and
/// mesh paths are relative to its directory.
///
/// The stream is read a token at a time: memory holds the scene and one token (at
/// most [`MAX_TOKEN`] bytes), never the file, so the ignored rest of a file costs
/// only the time to read it. Bytes that are not UTF-8 text (a cp1252 degree sign, a
/// NUL) may sit in a comment or in the ignored rest of the file: they are read as
/// U+FFFD and only matter if the scene needs the token they are in. A file that fails
/// before its first such byte fails as usual; one that fails at or after it (a binary
/// file fails at once) is reported as not a text scene file, at that byte.
pub fn parse_scene_reader(input: impl Read, file: &str) -> Result<Parsed, ParseError> {
    read_scene(input, file, MAX_TRIANGLES)
}

/// [`parse_scene_reader`] with a triangle limit of its own (tests).
fn read_scene(input: impl Read, file: &str, max_triangles: u64) -> Result<Parsed, ParseError> {
    let mut r = Reader {
        file,
        tokens: Tokens::new(Limited::new(input)),
        ahead: None,
        ahead_text: String::new(),
        text: String::new(),
        warnings: Vec::new(),
        too_large: None,
        max_triangles,
    };
    let scene = match r.scene() {
        Ok(scene) => scene,
        Err(e) => return Err(r.tokens.binary_at_or_before(e, file)),
    };
    // the ignored rest, read (and counted against the size limit) without being kept
    r.tokens.drain().map_err(|e| unreadable(file, &e))?;
    Ok(Parsed {
        scene,
        warnings: r.warnings,
        too_large: r.too_large,
    })
}

/// Longest token the scene reader holds: 4 KiB (a path of the longest Linux allows; no
/// number needs more). A longer token is refused where it is read.
pub const MAX_TOKEN: usize = 4096;

/// Where a whitespace-separated word of the scene starts, and its length; its text
/// is in a buffer of the reader (read into the same two buffers, without allocating).
#[derive(Clone, Copy, Debug)]
struct Token {
    /// Its whole length in bytes (the buffer keeps at most [`MAX_TOKEN`]).
    bytes: usize,
    line: usize,
    col: usize,
}

/// The tokens of a stream, decoded as `String::from_utf8_lossy` would decode it, with
/// lines counted by [`Position`] and `//` comments skipped.
struct Tokens<R> {
    input: R,
    buf: Box<[u8]>,
    /// Unread bytes are `buf[start..end]`.
    start: usize,
    end: usize,
    eof: bool,
    /// Stream offset of `buf[start]`.
    offset: u64,
    /// Position of the next character.
    at: Position,
    /// Offset, line and column of the first byte that is not text (invalid UTF-8, a NUL
    /// or another control character that is not whitespace).
    first_bad: Option<(u64, usize, usize)>,
}

impl<R: Read> Tokens<R> {
    fn new(input: R) -> Self {
        Tokens {
            input,
            buf: vec![0; 64 << 10].into_boxed_slice(),
            start: 0,
            end: 0,
            eof: false,
            offset: 0,
            at: Position::default(),
            first_bad: None,
        }
    }

    /// Makes at least `n` bytes available unless the stream ends first.
    #[inline]
    fn fill(&mut self, n: usize) -> std::io::Result<()> {
        if self.end - self.start >= n || self.eof {
            return Ok(());
        }
        self.refill(n)
    }

    #[inline(never)]
    fn refill(&mut self, n: usize) -> std::io::Result<()> {
        while self.end - self.start < n && !self.eof {
            if self.start > 0 {
                self.buf.copy_within(self.start..self.end, 0);
                self.end -= self.start;
                self.start = 0;
            }
            match self.input.read(&mut self.buf[self.end..]) {
                Ok(0) => self.eof = true,
                Ok(k) => self.end += k,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }

    /// The next character, its length in bytes and whether it is not text, unread;
    /// `None` at the end of the stream.
    fn peek(&mut self) -> std::io::Result<Option<(char, usize, bool)>> {
        self.fill(4)?;
        let bytes = &self.buf[self.start..self.end];
        let Some(&b) = bytes.first() else {
            return Ok(None);
        };
        let control = |c: char| c == '\0' || (c.is_control() && !c.is_whitespace());
        if b < 0x80 {
            let c = char::from(b);
            return Ok(Some((c, 1, control(c))));
        }
        let width = match b {
            0xC2..=0xDF => 2,
            0xE0..=0xEF => 3,
            0xF0..=0xF4 => 4,
            _ => 1,
        };
        let seq = &bytes[..width.min(bytes.len())];
        Ok(Some(match std::str::from_utf8(seq) {
            Ok(s) => {
                let c = s.chars().next().expect("one character");
                (c, width, control(c))
            }
            // a maximal invalid sequence, or an incomplete one at the end of the
            // stream, is one U+FFFD (as from_utf8_lossy has it)
            Err(e) => (
                char::REPLACEMENT_CHARACTER,
                e.error_len().unwrap_or(seq.len()),
                true,
            ),
        }))
    }

    /// Moves past a character [`Tokens::peek`] returned.
    fn bump(&mut self, (c, len, bad): (char, usize, bool)) {
        if bad && self.first_bad.is_none() {
            self.first_bad = Some((self.offset, self.at.line, self.at.col));
        }
        self.start += len;
        self.offset += len as u64;
        self.at.advance(c);
    }

    /// Whether a `//` comment starts here.
    fn at_comment(&mut self) -> std::io::Result<bool> {
        self.fill(2)?;
        Ok(self.buf[self.start..self.end].starts_with(b"//"))
    }

    /// The next token, its text into `text`; `None` at the end of the stream.
    fn next_token(&mut self, text: &mut String) -> std::io::Result<Option<Token>> {
        text.clear();
        if self.offset == 0 {
            // a byte-order mark, as some editors write, is not part of the first number
            self.fill(3)?;
            if self.buf[self.start..self.end].starts_with("\u{feff}".as_bytes()) {
                self.start += 3;
                self.offset += 3;
            }
        }
        // whitespace and comments
        loop {
            self.fill(2)?;
            let rest = &self.buf[self.start..self.end];
            match rest.first() {
                None => return Ok(None),
                Some(b'/') if rest.get(1) == Some(&b'/') => {
                    while let Some(ch) = self.peek()? {
                        if Position::is_line_end(ch.0) {
                            break;
                        }
                        self.bump(ch);
                    }
                }
                Some(&b) if b < 0x80 && !char::from(b).is_whitespace() => break,
                // a run of ASCII whitespace at once
                Some(&b) if b < 0x80 => {
                    let run = rest
                        .iter()
                        .position(|&b| b >= 0x80 || !char::from(b).is_whitespace())
                        .unwrap_or(rest.len());
                    for &b in &rest[..run] {
                        self.at.advance(char::from(b));
                    }
                    self.start += run;
                    self.offset += run as u64;
                }
                Some(_) => match self.peek()? {
                    Some(ch) if ch.0.is_whitespace() => self.bump(ch),
                    _ => break,
                },
            }
        }
        let mut t = Token {
            bytes: 0,
            line: self.at.line,
            col: self.at.col,
        };
        loop {
            self.fill(2)?;
            // a run of printable ASCII but '/' at once (the bytes of nearly every token)
            let rest = &self.buf[self.start..self.end];
            let run = rest
                .iter()
                .position(|&b| !(b'!'..=b'~').contains(&b) || b == b'/')
                .unwrap_or(rest.len());
            if run > 0 {
                let keep = run.min(MAX_TOKEN.saturating_sub(t.bytes));
                text.extend(rest[..keep].iter().map(|&b| char::from(b)));
                t.bytes += run;
                for _ in 0..run {
                    self.at.advance('x');
                }
                self.start += run;
                self.offset += run as u64;
                continue;
            }
            let Some(ch) = self.peek()? else { break };
            if ch.0.is_whitespace() || self.at_comment()? {
                break;
            }
            if t.bytes + ch.0.len_utf8() <= MAX_TOKEN {
                text.push(ch.0);
            }
            t.bytes += ch.0.len_utf8();
            self.bump(ch);
        }
        Ok(Some(t))
    }

    /// Reads the rest of the stream without keeping it.
    fn drain(&mut self) -> std::io::Result<u64> {
        self.start = self.end;
        std::io::copy(&mut self.input, &mut std::io::sink())
    }

    /// `e` as the error of a file that is not text, should it lie at or after the
    /// first byte that is not text.
    fn binary_at_or_before(&self, e: ParseError, file: &str) -> ParseError {
        match self.first_bad {
            Some((offset, line, col)) if e.line > 0 && (e.line, e.col) >= (line, col) => {
                ParseError {
                    file: file.into(),
                    line,
                    col,
                    field: "file".into(),
                    message: format!(
                        "not a text scene file (binary or non-UTF-8 byte at offset {offset})"
                    ),
                }
            }
            _ => e,
        }
    }
}

struct Reader<'f, R> {
    file: &'f str,
    tokens: Tokens<Limited<R>>,
    /// A token read ahead by [`Reader::peek`], and its text.
    ahead: Option<Token>,
    ahead_text: String,
    /// The text of the token [`Reader::next`] returned last.
    text: String,
    warnings: Vec<String>,
    too_large: Option<ParseError>,
    /// [`MAX_TRIANGLES`] (lower in tests).
    max_triangles: u64,
}

impl<R: Read> Reader<'_, R> {
    /// At `at`, or at the end of the file.
    fn error_at(&self, at: Option<&Token>, field: &str, message: String) -> ParseError {
        let (line, col) = at.map_or((self.tokens.at.line, self.tokens.at.col), |t| {
            (t.line, t.col)
        });
        ParseError {
            file: self.file.into(),
            line,
            col,
            field: field.into(),
            message,
        }
    }

    fn warn_at(&mut self, at: &Token, what: String) {
        let msg = format!("{}:{}:{}: {}", self.file, at.line, at.col, what);
        self.warnings.push(msg);
    }

    /// Reads the next token into `ahead`, unless it holds one.
    fn look_ahead(&mut self) -> Result<(), ParseError> {
        if self.ahead.is_none() {
            self.ahead = self
                .tokens
                .next_token(&mut self.ahead_text)
                .map_err(|e| unreadable(self.file, &e))?;
        }
        Ok(())
    }

    /// The next token, left unread (its text: `ahead_text`).
    fn peek(&mut self) -> Result<Option<Token>, ParseError> {
        self.look_ahead()?;
        Ok(self.ahead)
    }

    fn next(&mut self, field: &str, expected: &str) -> Result<Token, ParseError> {
        self.look_ahead()?;
        std::mem::swap(&mut self.text, &mut self.ahead_text);
        match self.ahead.take() {
            Some(t) if t.bytes > MAX_TOKEN => {
                let start: String = self.text.chars().take(32).collect();
                let message = format!(
                    "expected {expected}, found a token of {} bytes (more than the {MAX_TOKEN} \
                     a token may have) starting '{}'",
                    t.bytes,
                    escaped(&start)
                );
                Err(self.error_at(Some(&t), field, message))
            }
            Some(t) => Ok(t),
            None => Err(self.error_at(
                None,
                field,
                format!("expected {expected}, found end of file"),
            )),
        }
    }

    /// A finite real number.
    fn number(&mut self, field: &str) -> Result<(f64, Token), ParseError> {
        let t = self.next(field, "a number")?;
        match self.text.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok((v, t)),
            Ok(_) => Err(self.error_at(
                Some(&t),
                field,
                format!("expected a finite number, got '{}'", escaped(&self.text)),
            )),
            Err(_) => Err(self.error_at(
                Some(&t),
                field,
                format!("expected a number, found '{}'", escaped(&self.text)),
            )),
        }
    }

    fn number_ge0(&mut self, field: &str) -> Result<f64, ParseError> {
        let (v, t) = self.number(field)?;
        if v < 0.0 {
            return Err(self.error_at(Some(&t), field, format!("must be >= 0, got {}", self.text)));
        }
        Ok(v)
    }

    fn integer(&mut self, field: &str, min: i64, max: i64) -> Result<i64, ParseError> {
        let t = self.next(field, "an integer")?;
        let v: i64 = match self.text.parse::<i64>() {
            Ok(v) => v,
            Err(_) if self.text.parse::<f64>().is_ok() || looks_integral(&self.text) => {
                return Err(self.error_at(
                    Some(&t),
                    field,
                    format!("expected an integer in {min}..={max}, got {}", self.text),
                ));
            }
            Err(_) => {
                return Err(self.error_at(
                    Some(&t),
                    field,
                    format!("expected an integer, found '{}'", escaped(&self.text)),
                ));
            }
        };
        if v < min || v > max {
            return Err(self.error_at(
                Some(&t),
                field,
                format!("expected an integer in {min}..={max}, got {v}"),
            ));
        }
        Ok(v)
    }
    fn vec3(&mut self, field: &str) -> Result<(DVec3, Token), ParseError> {
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
        let at = self.peek()?;
        let pixels = self.integer("pixels", 1, u32::MAX.into())? as u32;
        if i64::from(pixels) > MAX_PIXELS {
            self.too_large = Some(self.error_at(
                at.as_ref(),
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
        let mut triangles = 0u64;
        for k in 1..=n_objects {
            let field = format!("object {k}: kind");
            let t = self.next(&field, "an object kind")?;
            let kind = self.text.to_ascii_lowercase();
            let idx = match kind.as_str() {
                "sphere" => 0,
                "triangle" => 1,
                "general" => 2,
                "prism" => 3,
                "mesh" => 4,
                _ => {
                    return Err(self.error_at(
                        Some(&t),
                        &field,
                        format!(
                            "unknown object kind '{}' (expected sphere, triangle, general, prism or mesh)",
                            escaped(&self.text)
                        ),
                    ));
                }
            };
            per_kind[idx] += 1;
            let who = format!("{kind} {}", per_kind[idx]);
            let shape = self.shape(&kind, &who, &t)?;
            let material = self.material(&who)?;
            let shape = match shape {
                Shape::Prism { v, .. } => Shape::Prism {
                    v,
                    glass: self.glass(&who)?,
                },
                s => s,
            };
            triangles += match &shape {
                Shape::Triangle { .. } => 1,
                Shape::Prism { .. } => 8,
                Shape::Mesh(m) => m.triangles().len() as u64,
                _ => 0,
            };
            if triangles > self.max_triangles {
                return Err(self.error_at(
                    Some(&t),
                    &who,
                    format!(
                        "the scene's triangles (triangle objects, 8 per prism, mesh triangles) \
                         pass octaray's limit of {}",
                        self.max_triangles
                    ),
                ));
            }
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
        match self.peek()? {
            None => {
                let msg = "note: the file ends after the point lights: no spotlights".to_string();
                let end = self.tokens.at;
                self.warnings
                    .push(format!("{}:{}:{}: {msg}", self.file, end.line, end.col));
            }
            // (a word such as "Infinity" or "NaN" opening prose is not a count)
            Some(t)
                if self.ahead_text.parse::<f64>().is_err()
                    || !self.ahead_text.bytes().any(|b| b.is_ascii_digit()) =>
            {
                let msg = format!(
                    "note: '{}' is not a spotlight count: no spotlights; the rest of the file is ignored",
                    escaped(&self.ahead_text)
                );
                self.warn_at(&t, msg);
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
                            Some(&dt),
                            &format!("{who}: direction"),
                            "must be a non-zero vector".into(),
                        ));
                    };
                    let field = format!("{who}: cutoff angle");
                    let (cutoff_deg, ct) = self.number(&field)?;
                    if !(0.0..=180.0).contains(&cutoff_deg) {
                        return Err(self.error_at(
                            Some(&ct),
                            &field,
                            format!("must be in 0..=180 degrees, got {}", self.text),
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

    fn shape(&mut self, kind: &str, who: &str, at: &Token) -> Result<Shape, ParseError> {
        match kind {
            "sphere" => {
                let (center, _) = self.vec3(&format!("{who}: center"))?;
                let field = format!("{who}: radius");
                let (radius, rt) = self.number(&field)?;
                if radius <= 0.0 {
                    return Err(self.error_at(
                        Some(&rt),
                        &field,
                        format!("must be > 0, got {}", self.text),
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
                let mesh = super::mesh_cache::load_obj(&base.join(&self.text)).map_err(|e| {
                    // (the OBJ file's name comes from this file: escaped too)
                    let at = if e.line > 0 {
                        format!(":{}", e.line)
                    } else {
                        String::new()
                    };
                    let message = format!("{}{at}: {}", escaped(&e.file), e.message);
                    self.error_at(Some(&t), &field, message)
                })?;
                let degenerate = mesh.zero_area();
                if mesh.triangles().is_empty() {
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
            return Err(self.error_at(Some(&t), &field, format!("must be > 0, got {}", self.text)));
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
///
/// Compared in squares (no square root: every mesh triangle is checked three times on
/// its way in) where the squared edge lengths lie in [2⁻⁴⁵⁰, 2⁴⁵⁰]: there no product
/// overflows and the limit 1e-24·|e1|²·|e2|² stays a normal number (a cross product
/// that underflows is far below it, degenerate either way). Outside it (a zero, NaN or
/// infinite edge, an edge longer than 2²²⁵ or shorter than 2⁻²²⁵) in lengths, as
/// `is_degenerate_triangle_by_lengths`. The reference's triangle test uses it too.
/// Inlined, and its rare case given the edges by value: a call of either with the
/// vertices' address put them on the stack, where loads that straddled the caller's
/// stores stalled (about 10 ns a triangle).
#[inline(always)]
pub fn is_degenerate_triangle(v: &[DVec3; 3]) -> bool {
    const SAFE: std::ops::RangeInclusive<f64> =
        f64::from_bits((1023 - 450) << 52)..=f64::from_bits((1023 + 450) << 52);
    let e1 = v[1] - v[0];
    let e2 = v[2] - v[0];
    let (a2, b2) = (e1.length_squared(), e2.length_squared());
    if SAFE.contains(&a2) && SAFE.contains(&b2) {
        // |e1 × e2| <= |e1|·|e2| <= 2⁴⁵⁰: finite, no component overflows
        return e1.cross(e2).length_squared() <= 1e-24 * a2 * b2;
    }
    degenerate_by_lengths(e1.to_array(), e2.to_array())
}

/// [`is_degenerate_triangle`] in lengths, at every scale.
#[cfg(test)]
fn is_degenerate_triangle_by_lengths(v: &[DVec3; 3]) -> bool {
    degenerate_by_lengths((v[1] - v[0]).to_array(), (v[2] - v[0]).to_array())
}

/// [`is_degenerate_triangle`] in lengths, of the edges from the first vertex.
#[inline(never)]
#[cold]
fn degenerate_by_lengths(e1: [f64; 3], e2: [f64; 3]) -> bool {
    let (e1, e2) = (DVec3::from_array(e1), DVec3::from_array(e2));
    let n = e1.cross(e2).length();
    let limit = 1e-12 * e1.length() * e2.length();
    // NaN (coordinates so large that the cross product overflows) is degenerate too.
    n.partial_cmp(&limit) != Some(std::cmp::Ordering::Greater)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::test_rng::Xorshift;

    /// The squared form of the degenerate test gives the lengths' answer at every scale
    /// (edges from 2⁻⁶⁰⁰ to 2⁶⁰⁰, and at the guard's edges, 2^±225), on ordinary
    /// triangles, slivers near the 1e-12 limit, zero and NaN edges.
    #[test]
    fn degenerate_triangles_in_squares_agree_with_lengths() {
        let mut rng = Xorshift(0x2545_f491_4f6c_dd1d);
        let mut unit = move || rng.f64() - 0.5;
        let (mut checked, mut degenerate) = (0, 0);
        for k in (-600..=600)
            .step_by(25)
            .chain([-226, -225, -224, 224, 225, 226])
        {
            let scale = 2f64.powi(k);
            for _ in 0..20 {
                let p = DVec3::new(unit(), unit(), unit());
                let (a, b) = (
                    DVec3::new(unit(), unit(), unit()),
                    DVec3::new(unit(), unit(), unit()),
                );
                // a sliver: b bent off a by a sine of about 1e-12 (the vertices' rounding
                // moves it by up to ~1e-3 of itself: either side of the limit)
                let off = a.cross(b).cross(a).normalize() * a.length();
                let mut cases = vec![[p, p + a, p + b], [p, p + a, p], [p, p + a, p + a * 2.0]];
                for f in [1.0 - 1e-6, 1.0 + 1e-6] {
                    cases.push([p, p + a, p + a + off * (1e-12 * f)]);
                }
                cases.push([p, p + a, DVec3::new(f64::NAN, 0.0, 0.0)]);
                for c in cases {
                    let v = c.map(|q| q * scale);
                    assert_eq!(
                        is_degenerate_triangle(&v),
                        is_degenerate_triangle_by_lengths(&v),
                        "{v:?}"
                    );
                    checked += 1;
                    degenerate += is_degenerate_triangle(&v) as usize;
                }
            }
        }
        assert!(
            degenerate > checked / 3 && degenerate < checked,
            "{degenerate} of {checked}"
        );
    }

    /// Triangles are counted over the whole scene (triangle objects, 8 per prism, mesh
    /// triangles) and refused past the limit at the object that passes it (the packet
    /// path's 28-bit triangle numbers wrapped silently).
    #[test]
    fn triangles_past_the_limit_are_refused_at_the_object_that_passes_it() {
        let prism = "prism 0 0 0 1 0 0 0 1 0 0 0 1 1 0 1 0 1 1 1 1 1 0 0 0 0 1 1 1.5 0";
        let triangle = "triangle 0 0 0 1 0 0 0 1 0 1 1 1 0 0 0 0 1";
        let text = format!("1 8 4\n{prism}\n{prism}\n{triangle}\n{triangle}\n0 0\n");
        // 8 + 8 + 1 + 1 = 18 triangles
        assert!(read_scene(text.as_bytes(), "t.txt", 18).is_ok());
        let e = read_scene(text.as_bytes(), "t.txt", 17).unwrap_err();
        assert_eq!(
            (e.line, e.col, e.field.as_str()),
            (5, 1, "triangle 2"),
            "{e}"
        );
        assert!(e.message.contains("octaray's limit of 17"), "{e}");
        let e = read_scene(text.as_bytes(), "t.txt", 10).unwrap_err();
        assert_eq!((e.line, e.field.as_str()), (3, "prism 2"), "{e}");
        assert_eq!(MAX_TRIANGLES, (1 << 28) - 1);
    }
}
