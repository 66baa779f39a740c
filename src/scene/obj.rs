//! Wavefront OBJ meshes for the `mesh PATH.obj` object kind.
//!
//! Scene syntax: `mesh PATH.obj` then the usual material (`r g b  ka kd ks kr  shine`);
//! PATH is relative to the scene file and may not contain whitespace. Of the OBJ
//! format only `v x y z` (an optional w is ignored) and `f` lines are read; `f` takes
//! three or more vertex references (`i`, `i/t`, `i//n`, `i/t/n`; 1-based, negative
//! counts back from the latest vertex) and polygons are fanned into triangles
//! (v0 v1 v2, v0 v2 v3, ...). Every other line (`vt`, `vn`, `o`, `g`, `usemtl`, `#`,
//! ...) is ignored. Errors name the file and line.

use std::fmt;
use std::path::Path;

use glam::DVec3;

/// Triangles over a shared vertex array, f64 like the rest of the scene.
#[derive(Clone, PartialEq)]
pub struct Mesh {
    pub vertices: Vec<DVec3>,
    /// Vertex indices (0-based) of each triangle, in file order.
    pub triangles: Vec<[u32; 3]>,
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
    /// The vertices of triangle `k`.
    pub fn triangle(&self, k: usize) -> [DVec3; 3] {
        self.triangles[k].map(|i| self.vertices[i as usize])
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

/// Reads and parses an OBJ file.
pub fn load_obj(path: &Path) -> Result<Mesh, ObjError> {
    let name = path.display().to_string();
    let bytes = super::read_input(path).map_err(|e| ObjError {
        file: name.clone(),
        line: 0,
        message: format!("cannot read: {e}"),
    })?;
    // invalid UTF-8 (a cp1252 byte) is harmless in a comment or a line the format
    // ignores; the lines that are read are ASCII, so a lossy decoding changes nothing
    // they say, and a bad byte inside one makes it fail with its line
    let text = String::from_utf8_lossy(&bytes);
    // a byte-order mark would glue itself to the first keyword (and drop a `v` line,
    // shifting every index after it)
    parse_obj(text.strip_prefix('\u{feff}').unwrap_or(&text), &name)
}

/// Parses OBJ text; `file` is only used in messages.
pub fn parse_obj(text: &str, file: &str) -> Result<Mesh, ObjError> {
    let mut vertices: Vec<DVec3> = Vec::new();
    let mut triangles = Vec::new();
    let mut face: Vec<u32> = Vec::new();
    for (n, line) in text.lines().enumerate() {
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
                                super::text::escaped(tok)
                            ))
                        })?;
                }
                vertices.push(DVec3::from(c));
            }
            Some("f") => {
                face.clear();
                for tok in it {
                    let idx = tok.split('/').next().unwrap_or("");
                    let i: i64 = idx.parse().map_err(|_| {
                        err(format!(
                            "f: '{}' is not a vertex index",
                            super::text::escaped(tok)
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
    Ok(Mesh {
        vertices,
        triangles,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quads_are_fanned_and_negative_indices_count_back() {
        let text = "# a quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1/1/1 2//1 3 4\nf -4 -3 -2\n";
        let m = parse_obj(text, "q.obj").unwrap();
        assert_eq!(m.vertices.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 2]]);
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
}
