//! Wavefront OBJ meshes for the `mesh PATH.obj` object kind.
//!
//! Scene syntax: `mesh PATH.obj` then the usual material (`r g b  ka kd ks kr  shine`);
//! PATH is relative to the scene file and may not contain whitespace. Of the OBJ
//! format only `v x y z` (an optional w is ignored) and `f` lines are read; `f` takes
//! three or more vertex references (`i`, `i/t`, `i//n`, `i/t/n`; 1-based, negative
//! counts back from the latest vertex) and polygons are fanned into triangles
//! (v0 v1 v2, v0 v2 v3, ...). Every other line (`vt`, `vn`, `o`, `g`, `usemtl`, `#`,
//! ...) is ignored. A line ends at LF, CRLF or a lone CR, as in scene files. Errors
//! name the file and line.
//!
//! A file is read a run of whole lines at a time (about 1 MiB; held whole only as far
//! as its longest line). A large regular file is read in runs of 4 MiB, each cut into
//! pieces of whole lines parsed on the worker threads, each piece on its own (indices
//! that count back are resolved, and every index checked, when the pieces are
//! joined); any error sends the file through one serial pass, which finds the first
//! error in file order with its line. Both passes read the same tokens the same way:
//! coordinates with `str::parse::<f64>`, words split at Unicode
//! whitespace (on an ASCII line, at its ASCII whitespace: the same words).

use std::fmt;
use std::io::{self, Read, Seek};
use std::path::Path;
use std::sync::OnceLock;

use glam::DVec3;
use rayon::prelude::*;

use super::input::Limited;

/// Triangles over a shared vertex array, f64 like the rest of the scene.
///
/// Its arrays are read through [`Mesh::vertices`] and [`Mesh::triangles`] and never
/// changed in place (to edit one, take it apart with [`Mesh::into_parts`] and build
/// anew), so what [`Mesh::zero_area`] counted once stays true.
#[derive(Clone)]
pub struct Mesh {
    vertices: Vec<DVec3>,
    /// Vertex indices (0-based) of each triangle, in file order.
    triangles: Vec<[u32; 3]>,
    /// [`Mesh::zero_area`], counted on its first call.
    zero_area: OnceLock<usize>,
}

impl PartialEq for Mesh {
    fn eq(&self, other: &Mesh) -> bool {
        self.vertices == other.vertices && self.triangles == other.triangles
    }
}

impl fmt::Debug for Mesh {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "Mesh {{ {} vertices, {} triangles }}",
            self.vertices.len(),
            self.triangles.len()
        )
    }
}

impl Mesh {
    pub fn new(vertices: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Mesh {
        Mesh {
            vertices,
            triangles,
            zero_area: OnceLock::new(),
        }
    }

    pub fn vertices(&self) -> &[DVec3] {
        &self.vertices
    }

    /// Vertex indices (0-based) of each triangle, in file order.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The vertices and the triangles, for a mesh built anew from them.
    pub fn into_parts(self) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        (self.vertices, self.triangles)
    }

    /// How many of its triangles have zero area (`is_degenerate_triangle`). Counted on
    /// the first call and kept (the scene's parse warns with it, and the packet path
    /// skips the f64 test of every triangle when it is 0).
    pub fn zero_area(&self) -> usize {
        *self.zero_area.get_or_init(|| {
            (0..self.triangles.len())
                .filter(|&k| crate::scene::parse::is_degenerate_triangle(&self.triangle(k)))
                .count()
        })
    }

    /// The vertices of triangle `k`.
    #[inline(always)]
    pub fn triangle(&self, k: usize) -> [DVec3; 3] {
        // each vertex loaded by name (an array `map` went through the stack, whose
        // 8- and 16-byte stores its readers' wider loads then waited for)
        let [a, b, c] = self.triangles[k];
        let v = &self.vertices;
        [v[a as usize], v[b as usize], v[c as usize]]
    }
}

/// A rejected OBJ file: `file:line: message`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ObjError {
    pub file: String,
    /// 1-based; 0 when the file could not be read.
    pub line: usize,
    pub message: String,
}

impl fmt::Display for ObjError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}: {}", self.file, self.line, self.message)
    }
}

impl std::error::Error for ObjError {}

/// Reads and parses an OBJ file (no cache: [`super::mesh_cache::load_obj`]), a run of
/// whole lines at a time ([`runs`]): a file is held whole only as far as its longest
/// line.
pub fn parse_file(path: &Path) -> Result<Mesh, ObjError> {
    let name = path.display().to_string();
    let cannot = |e| unreadable(&name, e);
    let file = super::input::open_input(path).map_err(cannot)?;
    let meta = file.metadata().map_err(cannot)?;
    // a pipe cannot be read twice, so only a regular file may take the pieces' pass
    // first; on any error its serial pass reads the same open file again from its start
    if meta.is_file() && meta.len() >= PARALLEL_BYTES as u64 && crate::parallel::threads() > 1 {
        let mut again = file.try_clone().map_err(cannot)?;
        if let Some(mesh) = parse_parallel(Limited::new(file), true).map_err(cannot)? {
            return Ok(mesh);
        }
        again.seek(io::SeekFrom::Start(0)).map_err(cannot)?;
        return parse_serial(Limited::new(again), true, &name);
    }
    parse_serial(Limited::new(file), true, &name)
}

/// The error of an input `file` that could not be read.
fn unreadable(file: &str, e: io::Error) -> ObjError {
    ObjError {
        file: file.to_string(),
        line: 0,
        message: format!("cannot read: {e}"),
    }
}

/// Parses OBJ text; `file` is only used in messages.
pub fn parse_obj(text: &str, file: &str) -> Result<Mesh, ObjError> {
    parse_obj_bytes(text.as_bytes(), file)
}

/// Files from this size on are parsed in pieces on the worker threads.
const PARALLEL_BYTES: usize = 1 << 20;
/// Bytes per piece, about (a few per thread, so that the threads finish together).
const PIECE_BYTES: usize = 1 << 20;
/// Bytes read at a time for the serial pass: a buffer that stays in the cache. (Read
/// whole into fresh pages first, the 51 MB torus of `benches/` took about half as long
/// to read as to parse.)
const SERIAL_RUN_BYTES: usize = 1 << 20;
/// Bytes read at a time for the pieces' pass, each run cut into pieces.
const PARALLEL_RUN_BYTES: usize = 4 << 20;

/// Parses OBJ bytes; `file` is only used in messages. Invalid UTF-8 (a cp1252 byte)
/// is harmless in a comment or a line the format ignores: a line holding any is
/// decoded lossily, so a bad byte inside a `v` or `f` line makes it fail with its line.
pub fn parse_obj_bytes(text: &[u8], file: &str) -> Result<Mesh, ObjError> {
    if text.len() >= PARALLEL_BYTES
        && crate::parallel::threads() > 1
        && let Some(mesh) = parse_parallel(text, false).map_err(|e| unreadable(file, e))?
    {
        return Ok(mesh);
    }
    parse_serial(text, false, file)
}

/// The serial pass: one [`Part`] fed the runs of `input` in file order, every index
/// checked at its line. `bom`: a leading byte-order mark is skipped.
fn parse_serial(input: impl Read, bom: bool, file: &str) -> Result<Mesh, ObjError> {
    serial_runs(input, SERIAL_RUN_BYTES, bom, file)
}

/// [`parse_serial`] in runs of about `chunk` bytes.
fn serial_runs(input: impl Read, chunk: usize, bom: bool, file: &str) -> Result<Mesh, ObjError> {
    let mut part = Part::new(true);
    runs(
        input,
        chunk,
        bom,
        |e| unreadable(file, e),
        |text| part.feed(text, file),
    )?;
    Ok(Mesh::new(part.vertices, part.triangles))
}

/// The pieces' pass: each run of `input` cut into pieces parsed on the worker
/// threads, the pieces joined at the end; `Ok(None)` on any error in the text (the
/// serial pass then names the first).
fn parse_parallel(input: impl Read, bom: bool) -> io::Result<Option<Mesh>> {
    parallel_runs(input, PARALLEL_RUN_BYTES, bom)
}

/// [`parse_parallel`] in runs of about `chunk` bytes.
fn parallel_runs(input: impl Read, chunk: usize, bom: bool) -> io::Result<Option<Mesh>> {
    let mut parts = Vec::new();
    // stopped by `Some(read error)`, or `None` for an error in some piece
    let done = runs(input, chunk, bom, Some, |text| {
        parts.extend(pieces(text).ok_or(None)?);
        Ok(())
    });
    match done {
        // joined once, into arrays of the final size
        Ok(()) => Ok(join(parts)),
        Err(None) => Ok(None),
        Err(Some(e)) => Err(e),
    }
}

/// Reads `input` about `chunk` bytes at a time and hands `f` each run of whole lines
/// (a line longer than `chunk` is read on until it ends), in order, the last one at
/// the end of the input whatever its end; a leading byte-order mark skipped when
/// `bom`. The runs' lines are the input's lines, each whole in one run. Stops at the
/// first error of `f`, or of the input (made an `E` by `read`).
fn runs<E>(
    mut input: impl Read,
    chunk: usize,
    bom: bool,
    read: impl Fn(io::Error) -> E,
    mut f: impl FnMut(&[u8]) -> Result<(), E>,
) -> Result<(), E> {
    debug_assert!(chunk >= 4, "a run holds a byte-order mark");
    // room for a run and the part line before it: no growth while lines are short
    let mut buf = Vec::with_capacity(chunk + (64 << 10));
    let mut first = true;
    loop {
        let kept = buf.len();
        let got = (&mut input)
            .take(chunk as u64)
            .read_to_end(&mut buf)
            .map_err(&read)?;
        let end = got < chunk;
        if std::mem::take(&mut first) && bom && buf.starts_with(b"\xef\xbb\xbf") {
            // it would glue itself to the first keyword (and drop a `v` line,
            // shifting every index after it)
            buf.drain(..3);
        }
        // the kept part line has no line end but perhaps a CR at its end, so only
        // from there on can a line end lie (a scan of the whole buffer at each read
        // made a line of n bytes cost n² / chunk)
        let cut = if end {
            buf.len()
        } else {
            let from = kept.saturating_sub(1);
            match whole_lines(&buf[from..]) {
                0 => 0,
                c => from + c,
            }
        };
        if cut > 0 {
            f(&buf[..cut])?;
            buf.drain(..cut);
        }
        if end {
            return Ok(());
        }
    }
}

/// The length of the longest prefix of `text` made of whole lines (see [`line_end`])
/// when more bytes may follow: up to its last line end, but a CR at the very end may
/// be the first half of a CRLF, so its line waits for the next byte.
fn whole_lines(text: &[u8]) -> usize {
    let known = text.len() - (text.last() == Some(&b'\r')) as usize;
    // a CR before `known` is followed by a byte that is no LF (the last line end
    // found), so it ends its line alone
    text[..known]
        .iter()
        .rposition(|&b| b == b'\n' || b == b'\r')
        .map_or(0, |k| k + 1)
}

/// The pieces of `text` parsed in parallel, in order; `None` on any error.
fn pieces(text: &[u8]) -> Option<Vec<Part>> {
    let pieces = (text.len() / PIECE_BYTES).clamp(2, 256);
    // each search from where the last one ended at the earliest, so that a long line
    // is scanned once, not once per cut inside it
    let mut last = 0;
    let mut cuts: Vec<usize> = (0..=pieces)
        .map(|k| {
            last = next_line_start(text, (k * text.len() / pieces).max(last));
            last
        })
        .collect();
    cuts.dedup();
    cuts.par_windows(2)
        .map(|w| Part::parse(&text[w[0]..w[1]], "", false).ok())
        .collect()
}

/// The mesh of `parts` (parsed in file order, unchecked), the indices that count back
/// resolved; `None` when an index lies out of range.
fn join(parts: Vec<Part>) -> Option<Mesh> {
    let nv = parts.iter().map(|p| p.vertices.len()).sum();
    let nt = parts.iter().map(|p| p.triangles.len()).sum();
    let mut vertices = Vec::with_capacity(nv);
    let mut triangles = Vec::with_capacity(nt);
    for p in parts {
        let before = vertices.len();
        if p.need > before as i64 {
            return None;
        }
        let t0 = triangles.len();
        triangles.extend_from_slice(&p.triangles);
        for &k in &p.back {
            let c = &mut triangles[t0 + k / 3][k % 3];
            *c = c.wrapping_add(before as u32);
        }
        vertices.extend_from_slice(&p.vertices);
    }
    Some(Mesh::new(vertices, triangles))
}

/// The pieces of `text` parsed in parallel and joined; `None` on any error (the
/// serial pass then names the first).
#[cfg(test)]
fn parse_pieces(text: &[u8]) -> Option<Mesh> {
    join(pieces(text)?)
}

/// Where the line that holds byte `at` or the next one starts: `at` itself when a
/// line starts there (see [`line_end`]), else the start of the next line (`text.len()`
/// when none).
fn next_line_start(text: &[u8], at: usize) -> usize {
    if at == 0 {
        return 0;
    }
    let mut i = at;
    while i < text.len() {
        let starts = match text[i - 1] {
            b'\n' => true,
            b'\r' => text[i] != b'\n',
            _ => false,
        };
        if starts {
            return i;
        }
        i += 1;
    }
    text.len()
}

/// The line starting at `start`: where it ends (the index of its LF or CR, or
/// `text.len()`), where the next line starts, and whether the line is ASCII. A line
/// ends at LF, CRLF or a lone CR, the rule of scene files.
#[inline]
fn line_end(text: &[u8], start: usize) -> (usize, usize, bool) {
    let (mut i, mut high) = (start, 0u64);
    // eight bytes at a time: LF and CR are below 0x0e (as are tab, vertical tab, form
    // feed and other control bytes, which do not end a line)
    let end = loop {
        let Some(chunk) = text.get(i..i + 8) else {
            let rest = &text[i..];
            let k = rest
                .iter()
                .position(|&b| b == b'\n' || b == b'\r')
                .unwrap_or(rest.len());
            high = rest[..k].iter().fold(high, |h, &b| h | b as u64);
            break i + k;
        };
        let x = u64::from_le_bytes(chunk.try_into().expect("8 bytes"));
        // the top bit of each byte below 0x0e (a borrow can only mark bytes after
        // the first such byte)
        let below = x.wrapping_sub(0x0e0e_0e0e_0e0e_0e0e) & !x & TOP;
        if below == 0 {
            high |= x;
            i += 8;
            continue;
        }
        let k = (below.trailing_zeros() / 8) as usize;
        // the bytes before it, and it
        high |= x & (u64::MAX >> (56 - 8 * k));
        if matches!(chunk[k], b'\n' | b'\r') {
            break i + k;
        }
        i += k + 1;
    };
    let crlf = text.get(end) == Some(&b'\r') && text.get(end + 1) == Some(&b'\n');
    let next = (end + 1 + crlf as usize).min(text.len());
    (end, next, high & TOP == 0)
}

/// The top bit of every byte of a `u64`.
const TOP: u64 = 0x8080_8080_8080_8080;

/// What a run of whole lines holds.
#[derive(Default)]
struct Part {
    vertices: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    /// Corners (3 · triangle + corner) whose index counts back from the latest vertex,
    /// stored relative to the part's first vertex: the vertices before the part are
    /// added when the parts are joined (unchecked parts only).
    back: Vec<usize>,
    /// The least count of vertices before the part that puts all its indices in range.
    need: i64,
    /// The corners of the face being read: index, and whether it counts back.
    face: Vec<(u32, bool)>,
    /// Whether the part starts the file: indices are checked (and resolved) at once.
    checked: bool,
    /// Lines read so far (the runs of the serial pass continue the count).
    lines: usize,
}

impl Part {
    /// An empty part; when `checked`, it starts the file and every index is checked at
    /// its line, else the checks wait for the join ([`Part::need`]).
    fn new(checked: bool) -> Part {
        Part {
            checked,
            ..Part::default()
        }
    }

    /// Parses the lines of `text` (whole lines: see [`line_end`]).
    fn parse(text: &[u8], file: &str, checked: bool) -> Result<Part, ObjError> {
        let mut part = Part::new(checked);
        part.feed(text, file)?;
        Ok(part)
    }

    /// Parses the whole lines of `text`, the next ones of the file after those read so
    /// far; errors name the line in the file.
    fn feed(&mut self, text: &[u8], file: &str) -> Result<(), ObjError> {
        let mut at = 0;
        while at < text.len() {
            self.lines += 1;
            let (end, next, is_ascii) = line_end(text, at);
            // an ASCII line split at ASCII whitespace is split as `split_whitespace`
            // splits it
            let read = if is_ascii {
                match self.ascii_face(&text[..end], at) {
                    Some(read) => read,
                    None => self.words(AsciiWords { text, at, end }),
                }
            } else {
                self.words(String::from_utf8_lossy(&text[at..end]).split_whitespace())
            };
            read.map_err(|message| ObjError {
                file: file.to_string(),
                line: self.lines,
                message,
            })?;
            at = next;
        }
        Ok(())
    }

    /// One line (without its end) split into words by `it`.
    #[inline]
    fn words<'a>(&mut self, mut it: impl Iterator<Item = &'a str>) -> Result<(), String> {
        match it.next() {
            Some("v") => {
                let mut c = [0.0; 3];
                for (k, out) in c.iter_mut().enumerate() {
                    let tok = it
                        .next()
                        .ok_or_else(|| format!("v: expected 3 coordinates, found {k}"))?;
                    *out = parse_f64(tok).filter(|v| v.is_finite()).ok_or_else(|| {
                        format!("v: '{}' is not a finite number", super::text::escaped(tok))
                    })?;
                }
                self.vertices.push(DVec3::from(c));
            }
            Some("f") => {
                self.face.clear();
                for tok in it {
                    let idx = match tok.bytes().position(|b| b == b'/') {
                        Some(k) => &tok[..k],
                        None => tok,
                    };
                    let i = parse_index(idx).ok_or_else(|| {
                        format!("f: '{}' is not a vertex index", super::text::escaped(tok))
                    })?;
                    self.corner(i)?;
                }
                self.fan()?;
            }
            _ => {}
        }
        Ok(())
    }

    /// The ASCII line `line[at..]` when it is an `f` line of plain indices (`i`,
    /// `i/...`, at most 18 digits), read as [`Part::words`] reads it, without making
    /// words; `None` (nothing read) for any other line.
    #[inline]
    fn ascii_face(&mut self, line: &[u8], at: usize) -> Option<Result<(), String>> {
        // (no LF or CR inside a line: 0x09 ..= 0x0c are tab, vertical tab, form feed)
        let space = |b: u8| b == b' ' || b.wrapping_sub(0x09) < 4;
        let mut i = at;
        while i < line.len() && space(line[i]) {
            i += 1;
        }
        if line.get(i) != Some(&b'f') || line.get(i + 1).is_some_and(|&b| !space(b)) {
            return None;
        }
        i += 1;
        self.face.clear();
        loop {
            while i < line.len() && space(line[i]) {
                i += 1;
            }
            let Some(&first) = line.get(i) else {
                break;
            };
            let neg = first == b'-';
            if neg || first == b'+' {
                i += 1;
            }
            let digits = i;
            let mut v = 0i64;
            while i < line.len() && i - digits < 18 && line[i].is_ascii_digit() {
                v = v * 10 + (line[i] - b'0') as i64;
                i += 1;
            }
            if i == digits {
                return None;
            }
            if let Some(&b) = line.get(i)
                && !space(b)
            {
                if b != b'/' {
                    return None;
                }
                while i < line.len() && !space(line[i]) {
                    i += 1;
                }
            }
            if let Err(e) = self.corner(if neg { -v } else { v }) {
                return Some(Err(e));
            }
        }
        Some(self.fan())
    }

    /// Adds vertex reference `i` (as written) to the face being read.
    #[inline]
    fn corner(&mut self, i: i64) -> Result<(), String> {
        // vertices so far in this part
        let nv = self.vertices.len() as i64;
        // the index (relative to the part's first vertex when it counts back), and
        // the vertices it needs before the part
        let (at, need) = if i > 0 {
            (i - 1, i - nv)
        } else {
            (nv + i, 0i64.saturating_sub(nv + i))
        };
        if i == 0 || (self.checked && need > 0) {
            return Err(format!(
                "f: vertex index {i} out of range ({nv} vertices so far)"
            ));
        }
        self.need = self.need.max(need);
        self.face.push((at as u32, i < 0 && !self.checked));
        Ok(())
    }

    /// Fans the face read into triangles.
    #[inline]
    fn fan(&mut self) -> Result<(), String> {
        if self.face.len() < 3 {
            return Err(format!(
                "f: a face needs at least 3 vertices, found {}",
                self.face.len()
            ));
        }
        for k in 1..self.face.len() - 1 {
            let corners = [self.face[0], self.face[k], self.face[k + 1]];
            let t = self.triangles.len();
            for (c, &(_, back)) in corners.iter().enumerate() {
                if back {
                    self.back.push(3 * t + c);
                }
            }
            self.triangles.push(corners.map(|c| c.0));
        }
        Ok(())
    }
}

/// `s.parse::<f64>()`, bit for bit. A plain decimal (`[+-]d.d`) whose digits make an
/// integer w <= 2⁵³ and whose fraction has at most 22 digits is w / 10^k, one
/// division of exact operands, so correctly rounded (Clinger's fast path, which
/// `str::parse` takes too, after a slower scan); anything else goes to `str::parse`,
/// a token of more than 17 bytes at once. (The float parse was most of the time of a
/// `v` line. The 1.5 million coordinates of `benches/`' torus1m, 17 digits each:
/// 30–32 ms by `str::parse`, 36–38 ms when this scan came first, 31–32 ms now; the
/// same values with 6 decimals: 17–18 ms here, 21 ms by `str::parse`.)
#[inline]
fn parse_f64(s: &str) -> Option<f64> {
    /// 10^k, exact in f64 for k <= 22.
    const POW10: [f64; 23] = [
        1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
        1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
    ];
    const EXACT: u64 = 1 << 53;
    // more than 16 digits (an f32 value printed as an f64 has 17): past 2⁵³ at once,
    // whose scan here would only come before `str::parse`'s own
    if s.len() > 17 {
        return s.parse().ok();
    }
    let b = s.as_bytes();
    let neg = b.first() == Some(&b'-');
    let start = (neg || b.first() == Some(&b'+')) as usize;
    let (mut i, mut w) = (start, 0u64);
    // the digits from `i` into `w`; false when w grew past 2⁵³. Eight at a time while
    // w <= 2⁵³ / 10⁸ (so w · 10⁸ + 99999999 < 2⁶⁴), then one at a time while w <= 2⁵³
    // (w · 10 + 9 < 2⁶⁴)
    let digits = |i: &mut usize, w: &mut u64| {
        while let Some(chunk) = b.get(*i..*i + 8) {
            let x = u64::from_le_bytes(chunk.try_into().expect("8 bytes"));
            if !eight_digits(x) || *w > EXACT / 100_000_000 {
                break;
            }
            *w = *w * 100_000_000 + eight_digits_value(x);
            *i += 8;
            if *w > EXACT {
                return false;
            }
        }
        while *i < b.len() && b[*i].is_ascii_digit() {
            *w = *w * 10 + (b[*i] - b'0') as u64;
            *i += 1;
            if *w > EXACT {
                return false;
            }
        }
        true
    };
    if !digits(&mut i, &mut w) {
        return s.parse().ok();
    }
    let int_digits = i - start;
    let mut frac = 0;
    if b.get(i) == Some(&b'.') {
        i += 1;
        let f0 = i;
        if !digits(&mut i, &mut w) {
            return s.parse().ok();
        }
        frac = i - f0;
        // ("5." and ".5" are numbers to `str::parse` too: left to it)
        if frac == 0 {
            return s.parse().ok();
        }
    }
    if i != b.len() || int_digits == 0 || frac >= POW10.len() {
        return s.parse().ok();
    }
    let v = w as f64 / POW10[frac];
    Some(if neg { -v } else { v })
}

/// Whether the eight bytes of `x` (little-endian) are ASCII digits.
#[inline]
fn eight_digits(x: u64) -> bool {
    let a = x.wrapping_add(0x4646_4646_4646_4646);
    let b = x.wrapping_sub(0x3030_3030_3030_3030);
    (a | b) & TOP == 0
}

/// The value of eight ASCII digits (little-endian: the first digit in the low byte).
#[inline]
fn eight_digits_value(x: u64) -> u64 {
    const MASK: u64 = 0x0000_00ff_0000_00ff;
    const MUL1: u64 = 100 + (1_000_000 << 32);
    const MUL2: u64 = 1 + (10_000 << 32);
    let v = x - 0x3030_3030_3030_3030;
    let v = v * 10 + (v >> 8);
    ((v & MASK).wrapping_mul(MUL1) + ((v >> 16) & MASK).wrapping_mul(MUL2)) >> 32
}

/// `s.parse::<i64>()`, with the common short case (a sign, up to 18 digits) done
/// without the general routine.
#[inline(always)]
fn parse_index(s: &str) -> Option<i64> {
    let b = s.as_bytes();
    let (neg, digits) = match b.first() {
        Some(b'-') => (true, &b[1..]),
        Some(b'+') => (false, &b[1..]),
        _ => (false, b),
    };
    if digits.is_empty() || digits.len() > 18 {
        return s.parse().ok();
    }
    let mut v = 0i64;
    for &d in digits {
        let x = d.wrapping_sub(b'0');
        if x > 9 {
            return None;
        }
        v = v * 10 + x as i64;
    }
    Some(if neg { -v } else { v })
}

/// The words of an ASCII line, `text[at..end]` (`text[end]`, if any, is its LF or
/// CR): runs of bytes other than the ASCII whitespace of `char::is_whitespace`
/// (space, tab, vertical tab, form feed).
struct AsciiWords<'a> {
    text: &'a [u8],
    at: usize,
    end: usize,
}

impl<'a> Iterator for AsciiWords<'a> {
    type Item = &'a str;

    #[inline(always)]
    fn next(&mut self) -> Option<&'a str> {
        // (no LF or CR inside a line: 0x09 ..= 0x0c are tab, vertical tab, form feed)
        let space = |b: u8| b == b' ' || b.wrapping_sub(0x09) < 4;
        let (t, end) = (self.text, self.end);
        let mut i = self.at;
        while i < end && space(t[i]) {
            i += 1;
        }
        if i >= end {
            return None;
        }
        let start = i;
        // eight bytes at a time (a byte at a time, this loop took more instructions
        // than the float parse): a space, and the line's end, are below 0x21, as are
        // control bytes, which belong to a word
        loop {
            let Some(chunk) = t.get(i..i + 8) else {
                while i < end && !space(t[i]) {
                    i += 1;
                }
                break;
            };
            let x = u64::from_le_bytes(chunk.try_into().expect("8 bytes"));
            let below = x.wrapping_sub(0x2121_2121_2121_2121) & !x & TOP;
            if below == 0 {
                i += 8;
                continue;
            }
            let k = i + (below.trailing_zeros() / 8) as usize;
            if k >= end || space(t[k]) {
                i = k.min(end);
                break;
            }
            i = k + 1;
        }
        self.at = i;
        let word = &t[start..i];
        debug_assert!(word.is_ascii());
        // SAFETY: the line is ASCII (`line_end`), so every slice of it is UTF-8 (the
        // check it skips was a tenth of a large mesh's parse: benches/README.md).
        Some(unsafe { std::str::from_utf8_unchecked(word) })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quads_are_fanned_and_negative_indices_count_back() {
        let text = "# a quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1/1/1 2//1 3 4\nf -4 -3 -2\n";
        let m = parse_obj(text, "q.obj").unwrap();
        assert_eq!(m.vertices().len(), 4);
        assert_eq!(m.triangles(), vec![[0, 1, 2], [0, 2, 3], [0, 1, 2]]);
        assert_eq!(m.triangle(1)[2], DVec3::new(0.0, 1.0, 0.0));
    }

    #[test]
    fn errors_name_file_and_line() {
        let e = parse_obj("v 0 0 0\nv 1 0 0\nf 1 2 3\n", "bad.obj").unwrap_err();
        assert_eq!((e.file.as_str(), e.line), ("bad.obj", 3));
        assert!(e.message.contains("out of range"), "{e}");
        let e = parse_obj("v 0 nan 0\n", "bad.obj").unwrap_err();
        assert_eq!(e.line, 1);
        let e = parse_obj("v 0 0 0\nf 1 1\n", "bad.obj").unwrap_err();
        assert!(
            e.to_string().starts_with("bad.obj:2: f: a face needs"),
            "{e}"
        );
    }

    /// Old Mac files end lines with a lone CR: every line counts (the whole file was
    /// one ignored `v` line, and a bad index went unnoticed).
    #[test]
    fn lone_cr_ends_a_line_as_in_scene_files() {
        let m = parse_obj("v 0 0 0\rv 1 0 0\r\nv 0 1 0\rf 1 2 3\r", "mac.obj").unwrap();
        assert_eq!(
            (m.vertices().len(), m.triangles().to_vec()),
            (3, vec![[0, 1, 2]])
        );
        let e = parse_obj("v 0 0 0\rv 1 0 0\r\rf 1 2 4\r", "mac.obj").unwrap_err();
        assert_eq!(
            e.to_string(),
            "mac.obj:4: f: vertex index 4 out of range (2 vertices so far)"
        );
    }

    /// SplitMix64.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }
        fn below(&mut self, n: u64) -> u64 {
            self.next() % n
        }
        fn pick<'a>(&mut self, from: &[&'a str]) -> &'a str {
            from[self.below(from.len() as u64) as usize]
        }
    }

    /// A number token of many shapes: plain decimals short and long (past 2⁵³, past 19
    /// digits), exponents, signs, leading zeros, and things `str::parse` refuses.
    fn number(r: &mut Rng) -> String {
        fn digits(r: &mut Rng, n: u64) -> String {
            (0..n).map(|_| (b'0' + r.below(10) as u8) as char).collect()
        }
        let sign = r.pick(&["", "", "-", "+"]);
        match r.below(8) {
            0 => {
                let n = 1 + r.below(25);
                format!("{sign}{}", digits(r, n))
            }
            1..=3 => {
                let (i, f) = (1 + r.below(4), r.below(26));
                format!("{sign}{}.{}", digits(r, i), digits(r, f))
            }
            4 => {
                let n = r.below(5);
                format!("{sign}.{}", digits(r, n))
            }
            5 => {
                let (i, f, e) = (1 + r.below(3), r.below(18), r.below(4));
                let m = format!("{}.{}", digits(r, i), digits(r, f));
                let x = r.pick(&["e", "E", "e-", "e+"]);
                format!("{sign}{m}{x}{}", digits(r, e))
            }
            6 => r
                .pick(&[
                    "inf", "NaN", "1e400", "0x1p3", "1..2", "--1", "1_0", "\u{661}", "", "00.000",
                ])
                .to_string(),
            _ => {
                // exact float32 values as `gen_data.py` writes them
                let v = f32::from_bits(r.next() as u32 & 0x3fff_ffff);
                format!("{sign}{}", v as f64)
            }
        }
    }

    #[test]
    fn coordinates_parse_bit_for_bit_as_str_parse() {
        let mut r = Rng(11);
        for _ in 0..200_000 {
            let s = number(&mut r);
            let want = s.parse::<f64>().ok().map(f64::to_bits);
            assert_eq!(parse_f64(&s).map(f64::to_bits), want, "{s:?}");
            let idx = s.parse::<i64>().ok();
            assert_eq!(parse_index(&s), idx, "{s:?}");
        }
    }

    /// The parser as it was written first (lines by the rule of scene files, words
    /// by `split_whitespace`, numbers by `str::parse`): the oracle of the fast one.
    fn reference(text: &[u8], file: &str) -> Result<Mesh, ObjError> {
        let text = String::from_utf8_lossy(text);
        let (mut vertices, mut triangles) = (Vec::<DVec3>::new(), Vec::new());
        let lines = text.replace("\r\n", "\n").replace('\r', "\n");
        let lines = lines.strip_suffix('\n').unwrap_or(&lines);
        for (n, line) in lines.split('\n').enumerate() {
            let err = |message: String| ObjError {
                file: file.to_string(),
                line: n + 1,
                message,
            };
            let mut it = line.split_whitespace();
            match it.next() {
                Some("v") => {
                    let mut c = [0.0; 3];
                    for (k, out) in c.iter_mut().enumerate() {
                        let tok = it
                            .next()
                            .ok_or_else(|| err(format!("v: expected 3 coordinates, found {k}")))?;
                        *out = tok
                            .parse::<f64>()
                            .ok()
                            .filter(|v| v.is_finite())
                            .ok_or_else(|| {
                                err(format!(
                                    "v: '{}' is not a finite number",
                                    crate::scene::text::escaped(tok)
                                ))
                            })?;
                    }
                    vertices.push(DVec3::from(c));
                }
                Some("f") => {
                    let mut face = Vec::new();
                    for tok in it {
                        let idx = tok.split('/').next().unwrap_or("");
                        let i: i64 = idx.parse().map_err(|_| {
                            err(format!(
                                "f: '{}' is not a vertex index",
                                crate::scene::text::escaped(tok)
                            ))
                        })?;
                        let nv = vertices.len() as i64;
                        let abs = if i > 0 { i - 1 } else { nv + i };
                        if i == 0 || abs < 0 || abs >= nv {
                            return Err(err(format!(
                                "f: vertex index {i} out of range ({nv} vertices so far)"
                            )));
                        }
                        face.push(abs as u32);
                    }
                    if face.len() < 3 {
                        return Err(err(format!(
                            "f: a face needs at least 3 vertices, found {}",
                            face.len()
                        )));
                    }
                    for k in 1..face.len() - 1 {
                        triangles.push([face[0], face[k], face[k + 1]]);
                    }
                }
                _ => {}
            }
        }
        Ok(Mesh::new(vertices, triangles))
    }

    /// Random OBJ text: mostly valid `v` and `f` lines (any index form, back
    /// references, polygons), with every line end, odd whitespace (tab, vertical tab,
    /// form feed, no-break space, U+3000), non-UTF-8 bytes, ignored lines and, when
    /// `errors`, the occasional bad token.
    fn random_obj(r: &mut Rng, lines: usize, errors: bool) -> Vec<u8> {
        let mut out = Vec::new();
        let mut nv = 0i64;
        let spaces = [
            " ", " ", " ", "  ", "\t", "\x0b", "\x0c", "\u{a0}", "\u{3000}",
        ];
        let ends = ["\n", "\n", "\n", "\r\n", "\r"];
        for _ in 0..lines {
            let sp = |r: &mut Rng| -> &str {
                if r.below(20) == 0 {
                    r.pick(&spaces)
                } else {
                    " "
                }
            };
            let mut line = String::new();
            match r.below(10) {
                0..=3 => {
                    line += "v";
                    let k = if errors && r.below(50) == 0 {
                        2
                    } else {
                        3 + r.below(2)
                    };
                    for _ in 0..k {
                        line += sp(r);
                        let x = if errors && r.below(40) == 0 {
                            number(r)
                        } else {
                            format!("{}", (r.next() as i64 as f64) * 1e-19)
                        };
                        line += &x;
                    }
                    nv += 1;
                }
                4..=7 if nv > 0 => {
                    line += "f";
                    for _ in 0..3 + r.below(3) {
                        line += sp(r);
                        let i = if r.below(4) == 0 {
                            -(1 + r.below(nv as u64) as i64)
                        } else {
                            1 + r.below(nv as u64) as i64
                        };
                        let i = if errors && r.below(200) == 0 {
                            i + nv
                        } else {
                            i
                        };
                        line += &match r.below(6) {
                            0 => format!("{i}/{}", r.below(9)),
                            1 => format!("{i}//{}", r.below(9)),
                            2 => format!("{i}/1/2"),
                            3 if errors && r.below(30) == 0 => number(r),
                            _ => format!("{i}"),
                        };
                    }
                }
                8 => line += r.pick(&["# comment", "vn 0 0 1", "vt 0.5 0.5", "g x", "", "  "]),
                _ => line += r.pick(&["o caf\u{e9}", "#\u{a0}v 1 2 3", "vt\u{a0}1"]),
            }
            out.extend_from_slice(line.as_bytes());
            if r.below(100) == 0 && !line.starts_with('f') {
                out.extend_from_slice(b" \xe9\xff");
            }
            out.extend_from_slice(r.pick(&ends).as_bytes());
        }
        out
    }

    #[test]
    fn random_obj_text_parses_as_the_reference_parses_it() {
        let mut r = Rng(5);
        for case in 0..400 {
            let lines = 1 + r.below(60) as usize;
            let text = random_obj(&mut r, lines, case % 2 == 1);
            let got = parse_obj_bytes(&text, "r.obj");
            let want = reference(&text, "r.obj");
            match (&got, &want) {
                (Ok(a), Ok(b)) => {
                    assert_eq!(a.triangles(), b.triangles(), "case {case}");
                    let bits = |m: &Mesh| -> Vec<[u64; 3]> {
                        m.vertices
                            .iter()
                            .map(|v| v.to_array().map(f64::to_bits))
                            .collect()
                    };
                    assert_eq!(bits(a), bits(b), "case {case}");
                }
                _ => assert_eq!(got, want, "case {case}: {}", String::from_utf8_lossy(&text)),
            }
        }
    }

    /// A pool of two worker threads, for the pieces' pass.
    fn two_threads() -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap()
    }

    /// Read in runs of any size (a few bytes: lines longer than a run, a CR at a run's
    /// end before its LF or not, a byte-order mark in the first run), both passes give
    /// the mesh or the first error of the whole text at once.
    #[test]
    fn runs_of_any_size_parse_as_the_whole_text() {
        let two = two_threads();
        let mut r = Rng(13);
        for case in 0..300 {
            let lines = 1 + r.below(40) as usize;
            let mut text = random_obj(&mut r, lines, case % 3 == 2);
            let bom = case % 5 == 0;
            if bom {
                text.splice(0..0, *b"\xef\xbb\xbf");
            }
            let whole = Part::parse(
                text.strip_prefix(b"\xef\xbb\xbf")
                    .filter(|_| bom)
                    .unwrap_or(&text),
                "r.obj",
                true,
            )
            .map(|p| Mesh::new(p.vertices, p.triangles));
            for chunk in [4, 5, 7, 16, 61, 1000] {
                let serial = serial_runs(&text[..], chunk, bom, "r.obj");
                assert_eq!(serial, whole, "case {case}, runs of {chunk}");
                let pieces = two.install(|| parallel_runs(&text[..], chunk, bom).unwrap());
                match &whole {
                    Ok(mesh) => {
                        assert_eq!(pieces.as_ref(), Some(mesh), "case {case}, runs of {chunk}")
                    }
                    Err(_) => assert_eq!(pieces, None, "case {case}, runs of {chunk}"),
                }
            }
        }
    }

    #[test]
    fn a_run_ends_after_its_last_whole_line() {
        assert_eq!(whole_lines(b""), 0);
        assert_eq!(whole_lines(b"v 1 2"), 0);
        assert_eq!(whole_lines(b"v 1\nv 2"), 4);
        assert_eq!(whole_lines(b"v 1\r\nv 2\r\n"), 10);
        // a lone CR ends its line; one at the very end may be half a CRLF
        assert_eq!(whole_lines(b"v 1\rv 2"), 4);
        assert_eq!(whole_lines(b"v 1\nv 2\r"), 4);
        assert_eq!(whole_lines(b"\r"), 0);
        assert_eq!(whole_lines(b"\r\r"), 1);
    }

    /// A file read in pieces on two threads, with an error in the middle: the serial
    /// pass reads the same open file again from its start and names the error's line;
    /// without the error, the pieces' mesh is the whole text's.
    #[test]
    fn a_large_file_with_an_error_is_read_again_by_the_serial_pass() {
        let two = two_threads();
        let dir = std::env::temp_dir().join(format!("octaray-obj-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("big.obj");
        let mut r = Rng(21);
        let mut text = random_obj(&mut r, 150_000, false);
        assert!(
            text.len() >= PARALLEL_RUN_BYTES + PARALLEL_BYTES,
            "{}",
            text.len()
        );
        std::fs::write(&path, &text).unwrap();
        let whole = Part::parse(&text, "big.obj", true).map(|p| Mesh::new(p.vertices, p.triangles));
        assert!(whole.is_ok());
        assert_eq!(two.install(|| parse_file(&path)).ok(), whole.ok());
        // an index out of range in the second run
        let cut = next_line_start(&text, PARALLEL_RUN_BYTES + 1000);
        text.splice(cut..cut, b"f 1 2 999999999\n".iter().copied());
        std::fs::write(&path, &text).unwrap();
        let got = two.install(|| parse_file(&path));
        let want = Part::parse(&text, &path.display().to_string(), true).map(|_| ());
        let _ = std::fs::remove_dir_all(&dir);
        let err = got.expect_err("an index out of range");
        assert_eq!(Err(err.clone()), want);
        assert!(err.message.contains("999999999"), "{err}");
    }

    /// A file large enough to be parsed in pieces gives the serial pass's mesh, and
    /// its errors (first in file order, with the line) are the serial pass's too.
    #[test]
    fn pieces_on_two_threads_join_to_the_serial_result() {
        let two = two_threads();
        let mut r = Rng(9);
        for case in 0..6 {
            let mut text = random_obj(&mut r, 120_000, false);
            if case >= 3 {
                // an error in the middle, then one early: the early one is named
                let mid = text.len() / 2 + r.below(1000) as usize;
                let cut = next_line_start(&text, mid);
                text.splice(cut..cut, b"f 1 2 999999999\n".iter().copied());
                if case == 5 {
                    let cut = next_line_start(&text, 3000);
                    text.splice(cut..cut, b"v 1 2\n".iter().copied());
                }
            }
            assert!(text.len() >= PARALLEL_BYTES, "{}", text.len());
            let serial =
                Part::parse(&text, "p.obj", true).map(|p| Mesh::new(p.vertices, p.triangles));
            if case < 3 {
                assert!(parse_pieces(&text).is_some(), "case {case}: pieces failed");
            }
            assert_eq!(
                two.install(|| parse_obj_bytes(&text, "p.obj")),
                serial,
                "case {case}"
            );
            assert_eq!(serial, reference(&text, "p.obj"), "case {case}");
        }
    }
}
