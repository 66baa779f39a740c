//! The binary cache of parsed OBJ meshes: after a text parse of an OBJ file of at
//! least [`MIN_SOURCE_BYTES`], the [`Mesh`] the parser returned is stored, and the next
//! load of the same file reads it instead of the text.
//!
//! Directory: `$XDG_CACHE_HOME/octaray/mesh`, else `~/.cache/octaray/mesh`
//! ([`crate::cache::root`]); `OCTARAY_MESH_CACHE=off` turns the cache off ([`dir`]).
//! A cache file is named by a digest of the source's canonical path and holds, all
//! little-endian:
//!
//! ```text
//! 0   magic "OCTAMESH"         8 bytes
//! 8   format version           u32
//! 12  bytes of the path        u32
//! 16  source length            u64
//! 24  source modification time i128, nanoseconds from the Unix epoch
//! 40  vertices                 u64
//! 48  triangles                u64
//! 56  digest                   u64, of bytes 0..56 and 64.. (`Digest`)
//! 64  the canonical path, then x y z (f64) per vertex, then a b c (u32) per triangle
//! ```
//!
//! A file that does not match in every field (another version, another source length
//! or time, a size that does not add up, a digest, an index out of range, a coordinate
//! that is not finite) is ignored: the text is parsed and the file written anew.

use std::ffi::OsStr;
use std::fs::File;
use std::io::{self, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::UNIX_EPOCH;

use glam::DVec3;

use super::obj::{Mesh, ObjError, parse_file};

/// OBJ files from this size on are cached (a smaller one parses in a few milliseconds).
pub const MIN_SOURCE_BYTES: u64 = 1 << 20;

const MAGIC: &[u8; 8] = b"OCTAMESH";
/// Change it with the layout, or with what the parser returns for the same text.
const VERSION: u32 = 1;
/// Bytes before the path.
const HEADER: usize = 64;
/// Where the digest sits in the header.
const DIGEST_AT: usize = 56;
/// Bytes per vertex and per triangle in the file.
const VERTEX_BYTES: usize = 24;
const TRIANGLE_BYTES: usize = 12;

/// Reads an OBJ file: from the mesh cache (this module) when it holds the
/// file as it is now, else the text, parsed (and then stored in the cache, if large
/// enough). A cache that cannot be written costs one warning on stderr per process.
pub fn load_obj(path: &Path) -> Result<Mesh, ObjError> {
    let (mesh, cache) = load_obj_cached(path, dir().as_deref())?;
    if let CacheUse::NotWritten(why) = cache {
        static WARNED: AtomicBool = AtomicBool::new(false);
        if !WARNED.swap(true, Ordering::Relaxed) {
            let _ = writeln!(
                std::io::stderr(),
                "octaray: warning: mesh cache not written ({why}); OCTARAY_MESH_CACHE=off turns it off"
            );
        }
    }
    Ok(mesh)
}

/// What the mesh cache did in a load.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CacheUse {
    /// Nothing: no cache directory, or a file the cache does not take (under
    /// [`MIN_SOURCE_BYTES`], not a regular file, or changed while
    /// it was read).
    Unused,
    /// The mesh was read from this cache file.
    Read(PathBuf),
    /// The text was parsed, and the mesh stored in this cache file.
    Written(PathBuf),
    /// The text was parsed; the cache could not be written (why).
    NotWritten(String),
}

/// [`load_obj`] with the cache in `cache` (`None`: no cache), saying what the cache
/// did; nothing is printed. The cache never makes a load fail.
pub fn load_obj_cached(path: &Path, cache: Option<&Path>) -> Result<(Mesh, CacheUse), ObjError> {
    // (taken before the text is read: a file changed meanwhile is not stored as it was)
    let source = cache.and_then(|dir| Some((dir, Source::of(path)?)));
    if let Some((dir, s)) = &source
        && let Some(mesh) = read(dir, s)
    {
        return Ok((mesh, CacheUse::Read(s.cache_file(dir))));
    }
    let mesh = parse_file(path)?;
    let used = match source {
        Some((dir, s)) if Source::of(path).as_ref() == Some(&s) => match write(dir, &s, &mesh) {
            Ok(file) => CacheUse::Written(file),
            Err(e) => CacheUse::NotWritten(format!("{}: {e}", s.cache_file(dir).display())),
        },
        _ => CacheUse::Unused,
    };
    Ok((mesh, used))
}

/// The mesh cache's directory: `mesh` under [`crate::cache::root`]; `None` (no cache)
/// when the environment variable `OCTARAY_MESH_CACHE` is `off` or no root is known.
pub fn dir() -> Option<PathBuf> {
    dir_from(
        std::env::var_os("OCTARAY_MESH_CACHE").as_deref(),
        crate::cache::root(),
    )
}

/// [`dir`] from the value of `OCTARAY_MESH_CACHE` and the cache root.
fn dir_from(switch: Option<&OsStr>, root: Option<PathBuf>) -> Option<PathBuf> {
    if switch.is_some_and(|v| v.eq_ignore_ascii_case("off")) {
        return None;
    }
    root.map(|r| r.join("mesh"))
}

/// An OBJ file as the cache identifies it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Source {
    /// Canonical: every name of the file shares one cache file.
    path: PathBuf,
    len: u64,
    mtime_ns: i128,
}

impl Source {
    /// The file at `path` as it is now; `None` for a file the cache does not take (not
    /// a regular file, under [`MIN_SOURCE_BYTES`], no modification time).
    pub fn of(path: &Path) -> Option<Source> {
        let meta = std::fs::metadata(path).ok()?;
        if !meta.is_file() || meta.len() < MIN_SOURCE_BYTES {
            return None;
        }
        let mtime_ns = match meta.modified().ok()?.duration_since(UNIX_EPOCH) {
            Ok(after) => after.as_nanos() as i128,
            Err(before) => -(before.duration().as_nanos() as i128),
        };
        let path = std::fs::canonicalize(path).ok()?;
        u32::try_from(path.as_os_str().len()).ok()?;
        Some(Source {
            path,
            len: meta.len(),
            mtime_ns,
        })
    }

    /// The cache file of this source in `dir`.
    pub fn cache_file(&self, dir: &Path) -> PathBuf {
        let mut d = Digest::new(0);
        d.update(self.path_bytes());
        dir.join(format!("{:016x}.mesh", d.finish()))
    }

    fn path_bytes(&self) -> &[u8] {
        self.path.as_os_str().as_encoded_bytes()
    }
}

/// Bytes read or written at a time: whole vertices and triangles. The file is streamed
/// through a buffer of this size, not read whole: freeing a whole file's buffer (under
/// 32 MiB) raises glibc's mmap threshold, and the BVH build's later allocations then
/// stay resident, a larger peak (benches/README.md).
const BLOCK: usize = VERTEX_BYTES * 32 * 1024;

/// The mesh of `source` from its cache file in `dir`; `None` when there is none or it
/// does not match (module doc).
pub fn read(dir: &Path, source: &Source) -> Option<Mesh> {
    let mut file = File::open(source.cache_file(dir)).ok()?;
    let len = file.metadata().ok()?.len();
    decode(&mut file, len, source)
}

/// Stores `mesh`, parsed from `source`, in `dir` (made if missing), atomically;
/// returns the file written.
pub fn write(dir: &Path, source: &Source, mesh: &Mesh) -> io::Result<PathBuf> {
    std::fs::create_dir_all(dir)?;
    let file = source.cache_file(dir);
    crate::temporaries::write_renamed(&file, |f| encode(f, mesh, source))?;
    Ok(file)
}

/// Writes the cache file of `mesh`, parsed from `source`, to `w` (module doc), from
/// its start.
pub fn encode(w: &mut (impl Write + Seek), mesh: &Mesh, source: &Source) -> io::Result<()> {
    let path = source.path_bytes();
    let mut head = [0u8; HEADER];
    let mut put = |at: usize, b: &[u8]| head[at..at + b.len()].copy_from_slice(b);
    put(0, MAGIC);
    put(8, &VERSION.to_le_bytes());
    put(12, &(path.len() as u32).to_le_bytes());
    put(16, &source.len.to_le_bytes());
    put(24, &source.mtime_ns.to_le_bytes());
    put(40, &(mesh.vertices().len() as u64).to_le_bytes());
    put(48, &(mesh.triangles().len() as u64).to_le_bytes());
    let mut digest = Digest::new(1);
    digest.update(&head[..DIGEST_AT]);
    digest.update(path);
    w.seek(SeekFrom::Start(0))?;
    w.write_all(&head)?;
    w.write_all(path)?;
    let mut buf = Vec::with_capacity(BLOCK);
    let mut flush = |buf: &mut Vec<u8>, w: &mut dyn Write, at_least: usize| {
        if buf.len() < at_least {
            return Ok(());
        }
        digest.update(buf);
        let done = w.write_all(buf);
        buf.clear();
        done
    };
    for v in mesh.vertices() {
        for c in v.to_array() {
            buf.extend_from_slice(&c.to_le_bytes());
        }
        flush(&mut buf, w, BLOCK)?;
    }
    for t in mesh.triangles() {
        for i in t {
            buf.extend_from_slice(&i.to_le_bytes());
        }
        flush(&mut buf, w, BLOCK)?;
    }
    flush(&mut buf, w, 0)?;
    w.seek(SeekFrom::Start(DIGEST_AT as u64))?;
    w.write_all(&digest.finish().to_le_bytes())
}

/// The mesh in a cache file of `len` bytes read from `r`, if it is one of `source`
/// (module doc).
pub fn decode(r: &mut impl Read, len: u64, source: &Source) -> Option<Mesh> {
    let mut head = [0u8; HEADER];
    r.read_exact(&mut head).ok()?;
    let u64_at = |at: usize| u64::from_le_bytes(le(&head, at));
    if &head[..8] != MAGIC
        || u32::from_le_bytes(le(&head, 8)) != VERSION
        || u64_at(16) != source.len
        || i128::from_le_bytes(le(&head, 24)) != source.mtime_ns
    {
        return None;
    }
    let path_len = u32::from_le_bytes(le(&head, 12)) as usize;
    let nv = usize::try_from(u64_at(40)).ok()?;
    let nt = usize::try_from(u64_at(48)).ok()?;
    let vertex_bytes = nv.checked_mul(VERTEX_BYTES)?;
    let payload = vertex_bytes.checked_add(nt.checked_mul(TRIANGLE_BYTES)?)?;
    // (the sizes add up to the file's; a vertex or a triangle takes at most 6 times
    // its bytes of text)
    let most = source.len.saturating_mul(6);
    if HEADER.checked_add(path_len)?.checked_add(payload)? as u64 != len || payload as u64 > most {
        return None;
    }
    let mut path = vec![0; path_len];
    r.read_exact(&mut path).ok()?;
    if path != source.path_bytes() {
        return None;
    }
    let mut digest = Digest::new(1);
    digest.update(&head[..DIGEST_AT]);
    digest.update(&path);
    let mut vertices = Vec::with_capacity(nv);
    let mut triangles = Vec::with_capacity(nt);
    // what the parser guarantees (a digest can match a file written wrongly): finite
    // coordinates, indices in range (checked without branches, in the same pass)
    let (mut finite, mut most) = (true, 0);
    let f64_at = |c: &[u8], at: usize| f64::from_le_bytes(le(c, at));
    let u32_at = |c: &[u8], at: usize| u32::from_le_bytes(le(c, at));
    let mut buf = vec![0; BLOCK.min(payload)];
    let mut at = 0;
    while at < payload {
        let block = &mut buf[..BLOCK.min(payload - at)];
        r.read_exact(block).ok()?;
        digest.update(block);
        // (blocks start at whole vertices, and at whole triangles past the vertices)
        let split = vertex_bytes.clamp(at, at + block.len()) - at;
        vertices.extend(block[..split].chunks_exact(VERTEX_BYTES).map(|c| {
            let v = DVec3::new(f64_at(c, 0), f64_at(c, 8), f64_at(c, 16));
            finite &= v.is_finite();
            v
        }));
        triangles.extend(block[split..].chunks_exact(TRIANGLE_BYTES).map(|c| {
            let t = [u32_at(c, 0), u32_at(c, 4), u32_at(c, 8)];
            most = most.max(t[0]).max(t[1]).max(t[2]);
            t
        }));
        at += block.len();
    }
    let in_range = nt == 0 || (most as usize) < nv;
    (digest.finish() == u64_at(DIGEST_AT) && finite && in_range)
        .then_some(Mesh::new(vertices, triangles))
}

/// `N` bytes of `b` from `at`, zeros past its end (callers check lengths first).
#[inline(always)]
fn le<const N: usize>(b: &[u8], at: usize) -> [u8; N] {
    let mut out = [0; N];
    if let Some(s) = b.get(at..at + N) {
        out.copy_from_slice(s);
    }
    out
}

/// A 64-bit digest of a stream of bytes, fed in pieces of any size: four lanes over
/// little-endian words, each step (xor the word, multiply by an odd constant, rotate) a
/// bijection of the lane, so that changing any one word always changes the digest;
/// then SplitMix64's finaliser. A check against damage at memory speed, not against
/// forgery.
struct Digest {
    lanes: [u64; 4],
    len: u64,
    /// The start of a 32-byte step not yet taken.
    held: [u8; 32],
    n_held: usize,
}

impl Digest {
    const K: [u64; 4] = [
        0x9E37_79B9_7F4A_7C15,
        0xBF58_476D_1CE4_E5B9,
        0x94D0_49BB_1331_11EB,
        0xD6E8_FEB8_6659_FD93,
    ];

    fn new(seed: u64) -> Digest {
        Digest {
            lanes: Self::K.map(|k| k ^ seed),
            len: 0,
            held: [0; 32],
            n_held: 0,
        }
    }

    #[inline(always)]
    fn step(&mut self, block: &[u8]) {
        for (i, h) in self.lanes.iter_mut().enumerate() {
            let w = u64::from_le_bytes(le(block, 8 * i));
            *h = (*h ^ w).wrapping_mul(Self::K[i]).rotate_left(23);
        }
    }

    fn update(&mut self, mut bytes: &[u8]) {
        self.len += bytes.len() as u64;
        if self.n_held > 0 {
            let k = (32 - self.n_held).min(bytes.len());
            self.held[self.n_held..self.n_held + k].copy_from_slice(&bytes[..k]);
            self.n_held += k;
            bytes = &bytes[k..];
            if self.n_held < 32 {
                return;
            }
            let held = self.held;
            self.step(&held);
        }
        let mut blocks = bytes.chunks_exact(32);
        for b in &mut blocks {
            self.step(b);
        }
        let rest = blocks.remainder();
        self.held[..rest.len()].copy_from_slice(rest);
        self.n_held = rest.len();
    }

    fn finish(mut self) -> u64 {
        self.held[self.n_held..].fill(0);
        let held = self.held;
        self.step(&held);
        let mix = |mut z: u64| {
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        };
        self.lanes.iter().fold(self.len, |acc, &x| mix(acc ^ x))
    }
}

#[cfg(test)]
mod tests {
    use std::fs;
    use std::time::{Duration, SystemTime};

    use super::*;
    use crate::scene::obj::parse_obj_bytes;

    /// An empty directory of this test process.
    fn scratch(tag: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("octaray-mesh-cache-{tag}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        d
    }

    /// OBJ text of at least `bytes` bytes: a strip of quads over vertices with
    /// coordinates of every kind the cache must keep bit for bit (negative zero, a
    /// subnormal, 17 significant digits, large and small exponents), `seed` in them.
    fn obj_text(bytes: usize, seed: u64) -> Vec<u8> {
        let mut s = String::from("# strip\n");
        let mut k = 0u64;
        while s.len() < bytes {
            let x = (k.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ seed) as f64 * 1e-19;
            let y = match k % 5 {
                0 => "-0".to_string(),
                1 => "4.9e-324".to_string(),
                2 => format!("{}", 0.1 + k as f64 / 3.0),
                3 => "-1.7976931348623157e308".to_string(),
                _ => format!("{}", k as f64 * 1e-300),
            };
            s += &format!("v {x} {y} {}\nv {x} {} 1\n", seed % 97, k as f64 * 0.25);
            k += 1;
            if k >= 2 {
                let a = 2 * k - 3;
                s += &format!("f {a} {} -1 {}\nf {a}/1 {}//2 -2\n", a + 1, a + 2, a + 2);
            }
        }
        s.into_bytes()
    }

    /// The mesh as bit patterns, so that -0 and 0 differ.
    fn bits(m: &Mesh) -> (Vec<[u64; 3]>, Vec<[u32; 3]>) {
        let v = m.vertices().iter().map(|v| v.to_array().map(f64::to_bits));
        (v.collect(), m.triangles().to_vec())
    }

    fn parsed(text: &[u8]) -> Mesh {
        parse_obj_bytes(text, "t.obj").unwrap()
    }

    /// The cache file of `mesh`.
    fn encoded(mesh: &Mesh, source: &Source) -> Vec<u8> {
        let mut c = io::Cursor::new(Vec::new());
        encode(&mut c, mesh, source).unwrap();
        c.into_inner()
    }

    /// The digest of `bytes` fed whole.
    fn digest(bytes: &[u8], seed: u64) -> u64 {
        let mut d = Digest::new(seed);
        d.update(bytes);
        d.finish()
    }

    /// The digest a cache file records: of its bytes but the digest's own.
    fn file_digest(b: &[u8]) -> u64 {
        let mut d = Digest::new(1);
        d.update(&b[..DIGEST_AT]);
        d.update(&b[HEADER..]);
        d.finish()
    }

    /// Meshes of every size around the streaming block (the vertices ending inside a
    /// block, at its end, none at all) come back bit for bit, and the file's digest
    /// is the digest of its bytes.
    #[test]
    fn meshes_come_back_whole_across_blocks() {
        let source = Source {
            path: PathBuf::from("/some/where/m.obj"),
            len: 1 << 30,
            mtime_ns: -5,
        };
        let mut r = 0x1234_5678_9abc_def0u64;
        let mut next = move || {
            r ^= r << 13;
            r ^= r >> 7;
            r ^= r << 17;
            r
        };
        let block_vertices = BLOCK / VERTEX_BYTES;
        for (nv, nt) in [
            (0, 0),
            (3, 1),
            (block_vertices, 0),
            (block_vertices, 1),
            (block_vertices - 1, 3),
            (40_000, 70_001),
            (3 * block_vertices + 7, 2 * BLOCK / TRIANGLE_BYTES + 5),
        ] {
            let mesh = Mesh::new(
                (0..nv)
                    .map(|_| {
                        // finite bit patterns of every kind (-0, subnormals, the largest)
                        let f = |b: u64| {
                            let x = f64::from_bits(b);
                            if x.is_finite() {
                                x
                            } else {
                                f64::from_bits(b >> 12)
                            }
                        };
                        DVec3::new(f(next()), f(next()), f(next() & 0x800f_ffff_ffff_ffff))
                    })
                    .collect(),
                (0..nt)
                    .map(|_| [0, 1, 2].map(|_| (next() % nv.max(1) as u64) as u32))
                    .collect(),
            );
            let bytes = encoded(&mesh, &source);
            assert_eq!(
                bytes.len(),
                HEADER + 17 + VERTEX_BYTES * nv + TRIANGLE_BYTES * nt,
                "{nv} {nt}"
            );
            assert_eq!(
                u64::from_le_bytes(le(&bytes, DIGEST_AT)),
                file_digest(&bytes)
            );
            let back = decode(&mut &bytes[..], bytes.len() as u64, &source).unwrap();
            assert_eq!(bits(&back), bits(&mesh), "{nv} {nt}");
            // another source, or a length that is not the file's: nothing
            let other = Source {
                mtime_ns: 6,
                ..source.clone()
            };
            assert!(decode(&mut &bytes[..], bytes.len() as u64, &other).is_none());
            assert!(decode(&mut &bytes[..], bytes.len() as u64 + 1, &source).is_none());
        }
    }

    #[test]
    fn a_cached_load_is_the_parsed_mesh() {
        let d = scratch("same");
        let (obj, cache) = (d.join("m.obj"), d.join("cache"));
        let text = obj_text(1 << 20, 3);
        fs::write(&obj, &text).unwrap();
        let want = parsed(&text);
        assert!(want.triangles().len() > 10_000, "{want:?}");
        let (first, used) = load_obj_cached(&obj, Some(&cache)).unwrap();
        let CacheUse::Written(file) = used else {
            panic!("not written: {used:?}")
        };
        assert!(
            file.starts_with(&cache) && file.is_file(),
            "{}",
            file.display()
        );
        assert_eq!(bits(&first), bits(&want));
        let (second, used) = load_obj_cached(&obj, Some(&cache)).unwrap();
        assert_eq!(used, CacheUse::Read(file.clone()));
        assert_eq!(second.vertices().len(), want.vertices().len());
        assert_eq!(second.triangles(), want.triangles());
        assert_eq!(bits(&second), bits(&want));
        // 24 bytes a vertex, 12 a triangle, the header and the path
        let path_len = fs::canonicalize(&obj).unwrap().as_os_str().len();
        let size = HEADER + path_len + 24 * want.vertices().len() + 12 * want.triangles().len();
        assert_eq!(fs::metadata(&file).unwrap().len(), size as u64);
        // another name of the same file shares the cache file
        let other = d.join(".").join("m.obj");
        assert_eq!(
            load_obj_cached(&other, Some(&cache)).unwrap().1,
            CacheUse::Read(file)
        );
        fs::remove_dir_all(&d).unwrap();
    }

    /// Sets the modification time of `path`.
    fn set_mtime(path: &Path, t: SystemTime) {
        let f = fs::OpenOptions::new().write(true).open(path).unwrap();
        f.set_modified(t).unwrap();
    }

    #[test]
    fn a_changed_source_is_parsed_again() {
        let d = scratch("changed");
        let (obj, cache) = (d.join("m.obj"), d.join("cache"));
        let t0 = SystemTime::UNIX_EPOCH + Duration::from_nanos(1_700_000_000_123_456_789);
        let a = obj_text(1 << 20, 1);
        fs::write(&obj, &a).unwrap();
        set_mtime(&obj, t0);
        assert!(matches!(
            load_obj_cached(&obj, Some(&cache)).unwrap().1,
            CacheUse::Written(_)
        ));
        assert!(matches!(
            load_obj_cached(&obj, Some(&cache)).unwrap().1,
            CacheUse::Read(_)
        ));
        // other contents, another length, the same time
        let b = obj_text((1 << 20) + 5000, 2);
        assert_ne!(a.len(), b.len());
        fs::write(&obj, &b).unwrap();
        set_mtime(&obj, t0);
        let (m, used) = load_obj_cached(&obj, Some(&cache)).unwrap();
        assert!(matches!(used, CacheUse::Written(_)), "{used:?}");
        assert_eq!(bits(&m), bits(&parsed(&b)));
        // other contents of the same length, a nanosecond later
        let mut c = b.clone();
        let at = c.iter().position(|&x| x == b'5').unwrap();
        c[at] = b'6';
        fs::write(&obj, &c).unwrap();
        set_mtime(&obj, t0 + Duration::from_nanos(1));
        let (m, used) = load_obj_cached(&obj, Some(&cache)).unwrap();
        assert!(matches!(used, CacheUse::Written(_)), "{used:?}");
        assert_eq!(bits(&m), bits(&parsed(&c)));
        assert_ne!(bits(&m), bits(&parsed(&b)));
        // the same contents touched: parsed again, the same mesh
        set_mtime(&obj, t0 + Duration::from_secs(60));
        let (m, used) = load_obj_cached(&obj, Some(&cache)).unwrap();
        assert!(matches!(used, CacheUse::Written(_)), "{used:?}");
        assert_eq!(bits(&m), bits(&parsed(&c)));
        assert!(matches!(
            load_obj_cached(&obj, Some(&cache)).unwrap().1,
            CacheUse::Read(_)
        ));
        // one cache file for the one source throughout
        assert_eq!(fs::read_dir(&cache).unwrap().count(), 1);
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_damaged_cache_file_is_ignored_and_replaced() {
        let d = scratch("damaged");
        let (obj, cache) = (d.join("m.obj"), d.join("cache"));
        let text = obj_text(1 << 20, 5);
        fs::write(&obj, &text).unwrap();
        let want = bits(&parsed(&text));
        let CacheUse::Written(file) = load_obj_cached(&obj, Some(&cache)).unwrap().1 else {
            panic!("not written")
        };
        let good = fs::read(&file).unwrap();
        let source = Source::of(&obj).unwrap();
        let bad_index = {
            let (v, mut t) = parsed(&text).into_parts();
            t[7][1] = v.len() as u32;
            Mesh::new(v, t)
        };
        let nan = {
            let (mut v, t) = parsed(&text).into_parts();
            v[3].y = f64::NAN;
            Mesh::new(v, t)
        };
        // damage with the digest made to match again, so that each check is tested on
        // its own; the digest's own cases keep it
        let sealed = |mut b: Vec<u8>| {
            if b.len() >= HEADER {
                let d = file_digest(&b);
                b[DIGEST_AT..HEADER].copy_from_slice(&d.to_le_bytes());
            }
            b
        };
        let changed = |at: usize, with: &[u8]| {
            let mut b = good.clone();
            b[at..at + with.len()].copy_from_slice(with);
            sealed(b)
        };
        let flipped = |at: usize, bit: u8| {
            let mut b = good.clone();
            b[at] ^= bit;
            b
        };
        let damaged: Vec<(&str, Vec<u8>)> = vec![
            ("empty", Vec::new()),
            ("header only", sealed(good[..HEADER].to_vec())),
            (
                "truncated by a byte",
                sealed(good[..good.len() - 1].to_vec()),
            ),
            ("a byte more", sealed([&good[..], &[0]].concat())),
            (
                "a coordinate's bit",
                flipped(good.len() - 12 * 1000 - 5, 0x10),
            ),
            ("an index's bit", flipped(good.len() - 7, 0x01)),
            ("a header bit", flipped(60, 0x01)),
            ("another magic", changed(0, b"OCTAMESX")),
            ("another version", changed(8, &(VERSION + 1).to_le_bytes())),
            (
                "another source length",
                changed(16, &(source.len + 1).to_le_bytes()),
            ),
            (
                "another time",
                changed(24, &(source.mtime_ns - 1).to_le_bytes()),
            ),
            (
                "vertex count near 2^64",
                changed(40, &(u64::MAX / 3).to_le_bytes()),
            ),
            (
                "a vertex less",
                changed(40, &(want.0.len() as u64 - 1).to_le_bytes()),
            ),
            (
                "another path",
                changed(HEADER + 1, &[good[HEADER + 1] ^ 0x20]),
            ),
            ("a path length of 0", changed(12, &0u32.to_le_bytes())),
            // contents the parser never returns
            ("an index out of range", encoded(&bad_index, &source)),
            ("a NaN", encoded(&nan, &source)),
        ];
        for (what, bytes) in damaged {
            assert_ne!(bytes, good, "{what}");
            fs::write(&file, &bytes).unwrap();
            let (m, used) = load_obj_cached(&obj, Some(&cache)).unwrap();
            assert_eq!(used, CacheUse::Written(file.clone()), "{what}");
            assert_eq!(bits(&m), want, "{what}");
            assert_eq!(fs::read(&file).unwrap(), good, "{what}: not replaced");
            let (m, used) = load_obj_cached(&obj, Some(&cache)).unwrap();
            assert_eq!(
                (used, bits(&m)),
                (CacheUse::Read(file.clone()), want.clone()),
                "{what}"
            );
        }
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn files_under_a_mebibyte_are_not_cached() {
        let d = scratch("small");
        let cache = d.join("cache");
        let text = obj_text(1 << 20, 7);
        let n = MIN_SOURCE_BYTES as usize;
        assert!(text.len() > n, "{}", text.len());
        let (under, at) = (d.join("under.obj"), d.join("at.obj"));
        // (cut after a line: the mesh stays valid)
        let cut = text[..n].iter().rposition(|&b| b == b'\n').unwrap() + 1;
        fs::write(&under, &text[..cut]).unwrap();
        let (m, used) = load_obj_cached(&under, Some(&cache)).unwrap();
        assert_eq!(used, CacheUse::Unused);
        assert_eq!(bits(&m), bits(&parsed(&text[..cut])));
        assert!(!cache.exists());
        fs::write(&at, [&text[..cut], &vec![b'#'; n - cut]].concat()).unwrap();
        assert_eq!(fs::metadata(&at).unwrap().len(), MIN_SOURCE_BYTES);
        assert!(matches!(
            load_obj_cached(&at, Some(&cache)).unwrap().1,
            CacheUse::Written(_)
        ));
        // no cache asked for: none used
        assert_eq!(load_obj_cached(&at, None).unwrap().1, CacheUse::Unused);
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn an_unwritable_cache_still_loads_the_mesh() {
        let d = scratch("unwritable");
        let obj = d.join("m.obj");
        let text = obj_text(1 << 20, 9);
        fs::write(&obj, &text).unwrap();
        // a file where the directory should be (a permission would not stop root)
        let blocked = d.join("blocked");
        fs::write(&blocked, b"not a directory").unwrap();
        for cache in [blocked.clone(), blocked.join("mesh")] {
            let (m, used) = load_obj_cached(&obj, Some(&cache)).unwrap();
            assert!(matches!(used, CacheUse::NotWritten(_)), "{used:?}");
            assert_eq!(bits(&m), bits(&parsed(&text)));
        }
        assert_eq!(fs::read(&blocked).unwrap(), b"not a directory");
        // and a bad OBJ is still its parse error, with its line
        fs::write(&obj, [&text[..], b"f 1 2\n"].concat()).unwrap();
        let e = load_obj_cached(&obj, Some(&d.join("cache"))).unwrap_err();
        assert!(e.message.contains("a face needs at least 3"), "{e}");
        assert!(!d.join("cache").exists());
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn the_switch_turns_the_cache_off() {
        let root = Some(PathBuf::from("/c/octaray"));
        let mesh = Some(PathBuf::from("/c/octaray/mesh"));
        assert_eq!(dir_from(None, root.clone()), mesh);
        assert_eq!(dir_from(Some(OsStr::new("on")), root.clone()), mesh);
        assert_eq!(dir_from(Some(OsStr::new("off")), root.clone()), None);
        assert_eq!(dir_from(Some(OsStr::new("OFF")), root), None);
        assert_eq!(dir_from(None, None), None);
    }

    #[test]
    fn the_digest_sees_every_word() {
        let base: Vec<u8> = (0..1000u32).flat_map(|i| i.to_le_bytes()).collect();
        let d0 = digest(&base, 0);
        assert_ne!(d0, digest(&base, 1));
        assert_ne!(d0, digest(&base[..base.len() - 1], 0));
        for at in (0..base.len()).step_by(7) {
            let mut b = base.clone();
            b[at] ^= 0x80;
            assert_ne!(digest(&b, 0), d0, "byte {at}");
        }
        // fed in pieces of any size: the digest of the whole
        for piece in [1, 5, 31, 32, 33, 100, 4000] {
            let mut d = Digest::new(0);
            for p in base.chunks(piece) {
                d.update(p);
            }
            assert_eq!(d.finish(), d0, "pieces of {piece}");
        }
    }
}
