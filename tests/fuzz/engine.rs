//! The fuzz engine of `tests/fuzz.rs` (a short seeded run inside `cargo test`) and
//! `examples/fuzz.rs` (the long run): a structure-aware mutator over scene, OBJ and
//! profile text, and the checks every case must pass, through the public entry points
//! only (`octaray::scene::parse`, `Profile`, `Profile::render`).
//!
//! Case `i` of seed `s` is a pure function of (s, i): any case can be made again from
//! its number. A case starts from a corpus file (`scenes/`, `profiles/`) or a generated
//! valid input and takes up to 8 mutations that know the formats: numbers swapped for
//! edge values (0, -0, 1e308, 5e-324, 2e19, nan, inf, 1e400, counts at and past their
//! limits), keywords for other keywords, tokens deleted, repeated or moved, blocks
//! inserted, bytes that are not text (NUL, ESC, a byte-order mark, U+200B, invalid
//! UTF-8), line ends of every kind, long tokens and ignored tails; OBJ faces with
//! indices out of range and lone-CR lines; profile keys with values of the wrong type,
//! set twice, unknown or empty keys, tables.
//!
//! The checks: no panic; every message names its file (and a line from 1, or no
//! position only for a file that cannot be read) and shows no control or invisible
//! character raw; profile messages carry none of the deserializer's words; a render
//! gives the image size asked for. The budget of a case (time, memory) is kept by the
//! callers; renders are tiny (at most 6 × 6 pixels) and capped through the profile's
//! own knobs (`max_recursion`, `photons`), as the command line's `--profile` would.

#![allow(dead_code)]

use std::path::Path;

use glam::DVec3;
use octaray::render::RenderSettings;
use octaray::render::profile::Profile;
use octaray::scene::Camera;
use octaray::scene::parse::parse_scene_bytes;

/// SplitMix64: small, fast, and good enough to pick mutations.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in 0..n (n > 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    pub fn chance(&mut self, p: f64) -> bool {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64 <= p
    }

    pub fn pick<'a, T>(&mut self, s: &'a [T]) -> &'a T {
        &s[self.below(s.len())]
    }

    /// A float in [-1, 1) times 10^(-3..=3), sometimes exactly an integer.
    pub fn number(&mut self) -> String {
        let u = (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
        let scale = 10f64.powi(self.below(7) as i32 - 3);
        if self.chance(0.3) {
            format!("{}", (u * 100.0).round())
        } else {
            format!("{:.4}", u * 100.0 * scale)
        }
    }
}

/// One fuzz case: the three texts and the frame to render.
#[derive(Clone, Debug)]
pub struct Case {
    pub scene: Vec<u8>,
    /// Written as `m.obj` beside the scene (generated scenes name it).
    pub obj: Vec<u8>,
    /// `None`: the default profile.
    pub profile: Option<Vec<u8>>,
    pub width: u32,
    pub height: u32,
    /// Eye and target, or the default camera.
    pub camera: Option<(DVec3, DVec3)>,
}

const SCENES: [&str; 14] = [
    include_str!("../../scenes/given.txt"),
    include_str!("../../scenes/camera_inside_sphere.txt"),
    include_str!("../../scenes/mirrors.txt"),
    include_str!("../../scenes/no_spotlight_block.txt"),
    include_str!("../../scenes/one_sphere.txt"),
    include_str!("../../scenes/prism.txt"),
    include_str!("../../scenes/prism_povray.txt"),
    include_str!("../../scenes/prism_view.txt"),
    include_str!("../../scenes/quadric_cone.txt"),
    include_str!("../../scenes/quadric_cylinder.txt"),
    include_str!("../../scenes/quadric_hyperboloid.txt"),
    include_str!("../../scenes/quadric_paraboloid.txt"),
    include_str!("../../scenes/quadric_plane.txt"),
    include_str!("../../scenes/spotlights.txt"),
];

const PROFILES: [&str; 4] = [
    include_str!("../../profiles/reference.toml"),
    include_str!("../../profiles/accurate.toml"),
    include_str!("../../profiles/fast.toml"),
    include_str!("../../profiles/preview.toml"),
];

/// Numbers at the edges of what the formats and the renderers hold.
const EDGE_NUMBERS: [&str; 40] = [
    "0",
    "-0",
    "1",
    "-1",
    "2",
    "0.5",
    "1e308",
    "-1e308",
    "1.7976931348623157e308",
    "1e-308",
    "5e-324",
    "1e-30",
    "1e19",
    "2e19",
    "-2e19",
    "1e15",
    "8e12",
    "1e400",
    "-1e400",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "Infinity",
    "180",
    "180.0001",
    "1000000",
    "1000001",
    "16384",
    "16385",
    "4294967295",
    "4294967296",
    "50000000",
    "50000001",
    "9223372036854775808",
    "0x10",
    "1_0",
    "+5",
    ".5",
    "1e",
];

const KEYWORDS: [&str; 9] = [
    "sphere", "triangle", "general", "prism", "mesh", "SPHERE", "Prism", "cube", "m.obj",
];

/// Byte sequences that are not plain text, or are easy to get wrong.
const ODD_BYTES: [&[u8]; 16] = [
    b"\0",
    b"\x1b[2J",
    b"\xef\xbb\xbf",
    b"\xe2\x80\x8b",
    b"\xe2\x80\xae",
    b"\xff",
    b"\xc3",
    b"\xb0",
    b"\r",
    b"\r\n",
    b"\n",
    b"\t",
    b"//",
    b" // note\r",
    b"\x0b",
    b"\xc2\xa0",
];

/// A valid scene of a few random objects and lights; meshes name `m.obj`.
fn generated_scene(r: &mut Rng) -> String {
    let mut s = format!("{}\n{}\n", r.below(7), 1 + r.below(64));
    let n = r.below(7);
    s += &format!("{n}\n");
    let v = |r: &mut Rng| format!("{} {} {}", r.number(), r.number(), r.number());
    for _ in 0..n {
        let kind = r.below(5);
        match kind {
            0 => s += &format!("sphere\n{}\n{}\n", v(r), r.number().trim_start_matches('-')),
            1 => s += &format!("triangle\n{}\n{}\n{}\n", v(r), v(r), v(r)),
            2 => {
                let coef: Vec<String> = (0..10).map(|_| r.number()).collect();
                let size: Vec<String> = (0..3)
                    .map(|_| match r.chance(0.3) {
                        true => "0".into(),
                        false => r.number().trim_start_matches('-').to_string(),
                    })
                    .collect();
                s += &format!("general\n{}\n{} {}\n", coef.join(" "), v(r), size.join(" "));
            }
            3 => {
                // a triangle and the same triangle `h` higher
                let base: Vec<[f64; 3]> = (0..3)
                    .map(|_| std::array::from_fn(|_| r.number().parse().unwrap_or(0.0)))
                    .collect();
                let h: f64 = r.number().parse().unwrap_or(1.0);
                s += "prism\n";
                for dz in [0.0, h] {
                    for p in &base {
                        s += &format!("{} {} {}  ", p[0], p[1], p[2] + dz);
                    }
                }
                s += "\n";
            }
            _ => s += "mesh m.obj\n",
        }
        s += &format!("{} {} {}\n", r.below(2), r.below(2), r.below(2));
        let kr = if r.chance(0.3) { "0.8" } else { "0.1" };
        s += &format!("0.4 0.2 0.2 {kr}\n{}\n", r.below(30));
        if kind == 3 {
            s += "1 1.5 0.01\n";
        }
    }
    let lights = r.below(3);
    s += &format!("{lights}\n");
    for _ in 0..lights {
        s += &format!("{} 1 1 1\n", v(r));
    }
    if r.chance(0.8) {
        let spots = r.below(3);
        s += &format!("{spots}\n");
        for _ in 0..spots {
            s += &format!("{} 1 1 1 {} {}\n", v(r), v(r), r.below(181));
        }
    }
    if r.chance(0.3) {
        s += "\nprose after the scene, which the format ignores 1 2 3\n";
    }
    s
}

/// A small valid OBJ mesh.
fn generated_obj(r: &mut Rng) -> String {
    let n = 3 + r.below(8);
    let mut s = String::from("# mesh\n");
    for _ in 0..n {
        s += &format!("v {} {} {}\n", r.number(), r.number(), r.number());
    }
    for _ in 0..1 + r.below(6) {
        let k = 3 + r.below(2);
        let idx: Vec<String> = (0..k).map(|_| format!("{}", 1 + r.below(n))).collect();
        s += &format!("f {}\n", idx.join(" "));
    }
    s
}

/// Profile keys and values, right and wrong.
fn generated_profile(r: &mut Rng) -> String {
    const KEYS: [&str; 12] = [
        "path",
        "samples_per_pixel",
        "resolution_scale",
        "max_recursion",
        "photons",
        "single_ray_lanes",
        "triangle_test",
        "ray_offset",
        "shadow_any_hit",
        "photns",
        "\"\"",
        "'photons'",
    ];
    const VALUES: [&str; 24] = [
        "\"packet\"",
        "\"reference\"",
        "\"fast\"",
        "1",
        "4",
        "5",
        "64",
        "0",
        "-1",
        "0.5",
        "0.0625",
        "2.0",
        "nan",
        "18446744073709551616",
        "10000000",
        "10000001",
        "\"watertight\"",
        "\"moller\"",
        "\"error_bound\"",
        "\"epsilon:1e-3\"",
        "\"epsilon:-1\"",
        "true",
        "[1]",
        "{a=1}",
    ];
    // a value each key takes, in the order of KEYS
    const VALID: [&[&str]; 9] = [
        &["\"packet\"", "\"reference\""],
        &["1", "4", "9", "64"],
        &["0.0625", "0.5", "1.0", "1"],
        &["0", "1", "2", "1000000"],
        &["0", "1", "1000", "10000000"],
        &["0", "1", "8"],
        &["\"watertight\"", "\"moller\""],
        &["\"error_bound\"", "\"epsilon:1e-3\"", "\"epsilon:1e30\""],
        &["true", "false"],
    ];
    let mut s = String::new();
    // distinct keys mostly (a key set twice is one refusal among many)
    let mut keys: Vec<usize> = (0..VALID.len()).collect();
    for k in (1..keys.len()).rev() {
        keys.swap(k, r.below(k + 1));
    }
    keys.truncate(r.below(6));
    if r.chance(0.15) {
        keys.push(r.below(KEYS.len()));
    }
    for k in keys {
        let value = match VALID.get(k) {
            Some(values) if r.chance(0.8) => r.pick(values),
            _ => r.pick(&VALUES),
        };
        s += &format!("{} = {value}\n", KEYS[k]);
    }
    if r.chance(0.1) {
        s += "[table]\nx = 1\n";
    }
    s
}

/// Splits `text` into tokens and the separators before each (the last separator
/// trails).
fn tokens(text: &[u8]) -> (Vec<Vec<u8>>, Vec<Vec<u8>>) {
    let (mut toks, mut seps) = (Vec::new(), Vec::new());
    let mut i = 0;
    while i < text.len() {
        let s = i;
        while i < text.len() && text[i].is_ascii_whitespace() {
            i += 1;
        }
        seps.push(text[s..i].to_vec());
        let t = i;
        while i < text.len() && !text[i].is_ascii_whitespace() {
            i += 1;
        }
        if i > t {
            toks.push(text[t..i].to_vec());
        }
    }
    if seps.len() == toks.len() {
        seps.push(Vec::new());
    }
    (toks, seps)
}

fn join(toks: &[Vec<u8>], seps: &[Vec<u8>]) -> Vec<u8> {
    let mut out = Vec::new();
    for (k, t) in toks.iter().enumerate() {
        out.extend_from_slice(seps.get(k).map_or(&b" "[..], |s| s));
        if seps.get(k).is_some_and(|s| s.is_empty()) && k > 0 {
            out.push(b' ');
        }
        out.extend_from_slice(t);
    }
    out.extend_from_slice(seps.get(toks.len()).map_or(&b"\n"[..], |s| s));
    out
}

/// One structure-aware mutation of whitespace-separated text (scene, OBJ, profile).
fn mutate(r: &mut Rng, text: &mut Vec<u8>) {
    let (mut toks, mut seps) = tokens(text);
    let n = toks.len();
    match r.below(13) {
        // a number for an edge value
        0..=2 if n > 0 => toks[r.below(n)] = r.pick(&EDGE_NUMBERS).as_bytes().to_vec(),
        // a number for a random one
        3 if n > 0 => toks[r.below(n)] = r.number().into_bytes(),
        // a keyword for another
        4 if n > 0 => toks[r.below(n)] = r.pick(&KEYWORDS).as_bytes().to_vec(),
        // delete, repeat, swap tokens
        5 if n > 0 => {
            let k = r.below(n);
            toks.remove(k);
            if k < seps.len() - 1 {
                seps.remove(k);
            }
        }
        6 if n > 0 => {
            let k = r.below(n);
            let count = 1 + r.below(12);
            let run: Vec<Vec<u8>> = toks[k..(k + count).min(n)].to_vec();
            for (j, t) in run.into_iter().enumerate() {
                toks.insert(k + j, t);
                seps.insert(k + j, b" ".to_vec());
            }
        }
        7 if n > 1 => {
            let (a, b) = (r.below(n), r.below(n));
            toks.swap(a, b);
        }
        // odd bytes inside a token or a separator
        8 if n > 0 => {
            let k = r.below(n);
            let at = r.below(toks[k].len() + 1);
            let odd = r.pick(&ODD_BYTES);
            toks[k].splice(at..at, odd.iter().copied());
        }
        // line ends of another kind throughout
        9 => {
            let ends: [&[u8]; 5] = [b"\r", b"\r\n", b"\n", b"\n\r", b" "];
            let end = *r.pick(&ends);
            for s in &mut seps {
                if s.contains(&b'\n') || s.contains(&b'\r') {
                    *s = end.to_vec();
                }
            }
        }
        // a long token
        10 if n > 0 => {
            let len = *r.pick(&[100, 4096, 4097, 70_000]);
            let digit = *r.pick(b"10x");
            toks[r.below(n)] = vec![digit; len];
        }
        // truncate
        11 => {
            let keep = r.below(toks.len() + 1);
            toks.truncate(keep);
            seps.truncate(keep + 1);
        }
        // an ignored tail, or junk
        _ => {
            let odd = r.pick(&ODD_BYTES);
            let mut tail = b"\nwords 1 2 3 ".to_vec();
            tail.extend_from_slice(odd);
            toks.push(tail);
            seps.push(b"\n".to_vec());
        }
    }
    *text = join(&toks, &seps);
}

/// Case `index` of `seed`.
pub fn case(seed: u64, index: u64) -> Case {
    let mut r = Rng::new(seed ^ index.wrapping_mul(0xA24B_AED4_963E_E407));
    r.next_u64();
    let mut scene = if r.chance(0.4) {
        r.pick(&SCENES).as_bytes().to_vec()
    } else {
        generated_scene(&mut r).into_bytes()
    };
    // a third of the scenes unmutated or nearly (they render), the rest up to 8 times
    let rounds = if r.chance(0.35) {
        r.below(2)
    } else {
        1 + r.below(8)
    };
    for _ in 0..rounds {
        mutate(&mut r, &mut scene);
    }
    let mut obj = generated_obj(&mut r).into_bytes();
    for _ in 0..r.below(4) {
        mutate(&mut r, &mut obj);
    }
    let profile = if r.chance(0.3) {
        None
    } else {
        let mut p = if r.chance(0.5) {
            r.pick(&PROFILES).as_bytes().to_vec()
        } else {
            generated_profile(&mut r).into_bytes()
        };
        if r.chance(0.3) {
            mutate(&mut r, &mut p);
        }
        Some(p)
    };
    let camera = r.chance(0.3).then(|| {
        let p = |r: &mut Rng| {
            let n = |r: &mut Rng| r.number().parse::<f64>().unwrap_or(0.0);
            DVec3::new(n(r), n(r), n(r))
        };
        (p(&mut r), p(&mut r))
    });
    Case {
        scene,
        obj,
        profile,
        width: 1 + r.below(6) as u32,
        height: 1 + r.below(6) as u32,
        camera,
    }
}

/// The most a case may ask of the renderer: recursion levels and photons.
#[derive(Clone, Copy, Debug)]
pub struct Budget {
    pub recursion: u32,
    pub photons: u32,
}

impl Default for Budget {
    fn default() -> Self {
        Budget {
            recursion: 8,
            photons: 3000,
        }
    }
}

/// How a case ended when it passed its checks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Rendered.
    Rendered,
    /// The profile or the scene was refused with a message.
    Refused,
}

/// A message shown to a user: no control or invisible character raw (quotes and
/// backslashes are what an escape leaves).
fn check_shown(what: &str, msg: &str) -> Result<(), String> {
    match msg
        .chars()
        .find(|&c| c.escape_debug().count() > 1 && !matches!(c, '\\' | '\'' | '"'))
    {
        Some(c) => Err(format!("{what}: raw {c:?} in message: {msg:?}")),
        None => Ok(()),
    }
}

/// Runs one case in `dir` (its own scratch directory): parses, checks messages,
/// renders within `budget`. `Err` is a finding.
pub fn run(case: &Case, dir: &Path, budget: Budget) -> Result<Outcome, String> {
    let mut profile = match &case.profile {
        None => Profile::by_name(Profile::default_name()).expect("built in"),
        Some(bytes) => {
            let text = String::from_utf8_lossy(bytes);
            match Profile::from_toml("fuzz", &text, "fuzz.toml") {
                Ok(p) => p,
                Err(e) => {
                    let shown = e.to_string();
                    check_shown("profile", &shown)?;
                    if !shown.starts_with("fuzz.toml:") || shown.starts_with("fuzz.toml:0:") {
                        return Err(format!("profile message without a position: {shown:?}"));
                    }
                    for internal in [
                        "invalid type",
                        "i128",
                        "expected u32",
                        "unknown field",
                        "duplicate key",
                    ] {
                        if shown.contains(internal) {
                            return Err(format!("profile message with {internal:?}: {shown:?}"));
                        }
                    }
                    return Ok(Outcome::Refused);
                }
            }
        }
    };
    std::fs::write(dir.join("m.obj"), &case.obj).map_err(|e| format!("scratch: {e}"))?;
    let name = dir.join("scene.txt").display().to_string();
    let parsed = match parse_scene_bytes(&case.scene, &name) {
        Ok(p) => p,
        Err(e) => {
            let shown = e.to_string();
            check_shown("scene", &shown)?;
            if !shown.starts_with(&name) {
                return Err(format!("scene message without its file: {shown:?}"));
            }
            // (no position only where the file could not be read)
            if (e.line == 0 && e.field != "file") || (e.line > 0 && e.col == 0) {
                return Err(format!("scene message at {}:{}: {shown:?}", e.line, e.col));
            }
            return Ok(Outcome::Refused);
        }
    };
    for w in &parsed.warnings {
        check_shown("warning", w)?;
        if !w.starts_with(&name) {
            return Err(format!("warning without its file: {w:?}"));
        }
    }
    // the budget, through the profile's own caps
    let cap = profile.max_recursion.unwrap_or(u32::MAX);
    profile.max_recursion = Some(cap.min(budget.recursion));
    profile.photons = profile.photons.min(budget.photons);
    let mut settings = RenderSettings {
        width: case.width,
        height: case.height,
        threads: Some(1),
        ..RenderSettings::square(1)
    };
    if let Some((eye, target)) = case.camera
        && let Some(c) = Camera::look_at(eye, target, DVec3::Z, 60.0)
    {
        settings.camera = c;
    }
    let image = profile.render(&parsed.scene, &settings).image;
    if (image.width, image.height) != (case.width, case.height)
        || image.pixels.len() != (case.width * case.height) as usize
    {
        return Err(format!(
            "asked {}x{}, rendered {}x{} ({} pixels)",
            case.width,
            case.height,
            image.width,
            image.height,
            image.pixels.len()
        ));
    }
    Ok(Outcome::Rendered)
}

/// The text of a panic's payload.
pub fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic".into())
}

/// Writes `case` to `dir` as files a user can run: `scene.txt`, `m.obj`, `profile.toml`
/// and `render.sh` (the command line of the case).
pub fn save(case: &Case, dir: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    std::fs::write(dir.join("scene.txt"), &case.scene)?;
    std::fs::write(dir.join("m.obj"), &case.obj)?;
    let mut cmd = format!(
        "octaray render scene.txt --size {}x{} --threads 1 -o out.bmp",
        case.width, case.height
    );
    if let Some(p) = &case.profile {
        std::fs::write(dir.join("profile.toml"), p)?;
        cmd += " --profile ./profile.toml";
    }
    if let Some((eye, target)) = case.camera {
        cmd += &format!(
            " --eye {},{},{} --look-at {},{},{} --fov 60",
            eye.x, eye.y, eye.z, target.x, target.y, target.z
        );
    }
    std::fs::write(dir.join("render.sh"), cmd + "\n")
}

// ---------------------------------------------------------------- the budget of a case

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering::Relaxed};
use std::time::{Duration, Instant};

/// The system allocator, counting the bytes live and their peak, refusing (null, so
/// the process aborts with "memory allocation of N bytes failed") what would pass
/// [`MEMORY_LIMIT`].
pub struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
/// Bytes a process of the fuzzer may hold at once.
pub static MEMORY_LIMIT: AtomicUsize = AtomicUsize::new(usize::MAX);

impl Counting {
    fn grow(by: usize) -> bool {
        let now = LIVE.fetch_add(by, Relaxed) + by;
        if now > MEMORY_LIMIT.load(Relaxed) {
            LIVE.fetch_sub(by, Relaxed);
            return false;
        }
        PEAK.fetch_max(now, Relaxed);
        true
    }
}

// SAFETY: every call is passed to `System` with the caller's layout and pointer
// unchanged; the counters only decide whether to call it at all (null is a valid
// answer of `alloc` and `realloc`).
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if !Counting::grow(layout.size()) {
            return std::ptr::null_mut();
        }
        // SAFETY: the caller's layout, as `GlobalAlloc::alloc` requires
        let p = unsafe { System.alloc(layout) };
        if p.is_null() {
            LIVE.fetch_sub(layout.size(), Relaxed);
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if !Counting::grow(layout.size()) {
            return std::ptr::null_mut();
        }
        // SAFETY: as in `alloc`
        let p = unsafe { System.alloc_zeroed(layout) };
        if p.is_null() {
            LIVE.fetch_sub(layout.size(), Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Relaxed);
        // SAFETY: `ptr` was allocated by `System` with `layout` (every allocation here is)
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let old = layout.size();
        if new_size > old && !Counting::grow(new_size - old) {
            return std::ptr::null_mut();
        }
        // SAFETY: `ptr` was allocated by `System` with `layout`; `new_size` is the
        // caller's, as `GlobalAlloc::realloc` requires
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        match (p.is_null(), new_size > old) {
            (true, true) => {
                LIVE.fetch_sub(new_size - old, Relaxed);
            }
            (false, false) => {
                LIVE.fetch_sub(old - new_size, Relaxed);
            }
            _ => {}
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// The case now running (its number + 1; 0: none) and when it started.
static RUNNING: AtomicU64 = AtomicU64::new(0);
static STARTED: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
static STARTED_MS: AtomicU64 = AtomicU64::new(0);
static WATCHING: AtomicBool = AtomicBool::new(false);

fn now_ms() -> u64 {
    STARTED.get_or_init(Instant::now).elapsed().as_millis() as u64
}

/// Starts the thread that ends the process (exit code 3, the case named on stderr)
/// when a case runs longer than `limit`.
pub fn watch(limit: Duration) {
    if WATCHING.swap(true, Relaxed) {
        return;
    }
    now_ms();
    std::thread::spawn(move || {
        loop {
            std::thread::sleep(Duration::from_millis(50));
            let case = RUNNING.load(Relaxed);
            if case > 0 && now_ms() - STARTED_MS.load(Relaxed) > limit.as_millis() as u64 {
                eprintln!("FINDING {} time: over {limit:?}", case - 1);
                std::process::exit(3);
            }
        }
    });
}

/// Marks case `index` as running, its peak memory counted from here.
pub fn begin(index: u64) {
    STARTED_MS.store(now_ms(), Relaxed);
    RUNNING.store(index + 1, Relaxed);
    PEAK.store(LIVE.load(Relaxed), Relaxed);
}

/// Ends the running case; returns the bytes it held at its peak above what was live
/// when it began.
pub fn end(live_before: usize) -> usize {
    RUNNING.store(0, Relaxed);
    PEAK.load(Relaxed).saturating_sub(live_before)
}

/// Bytes live now.
pub fn live() -> usize {
    LIVE.load(Relaxed)
}

// ---------------------------------------------------------------- running cases

/// What a run of cases did.
#[derive(Debug, Default)]
pub struct Stats {
    pub rendered: u64,
    pub refused: u64,
    /// (case, what went wrong)
    pub findings: Vec<(u64, String)>,
    /// The largest peak of a case, bytes.
    pub peak: usize,
}

/// What [`run_cases`] tells as it goes.
pub enum Event<'a> {
    /// A case begins.
    Begin(u64),
    /// A case failed a check (also in [`Stats::findings`]).
    Finding(u64, &'a str),
}

/// Runs cases `indices` of `seed` one after another on this thread (renders on a
/// one-thread pool), each in the scratch directory `dir`, each under the watch of
/// [`watch`] (time) and held to `memory` bytes at its peak; `tell` hears of each case
/// as it begins and of each finding at once (the long run reports through it).
pub fn run_cases(
    seed: u64,
    indices: impl Iterator<Item = u64>,
    dir: &Path,
    budget: Budget,
    memory: usize,
    mut tell: impl FnMut(Event<'_>),
) -> Stats {
    std::fs::create_dir_all(dir).expect("scratch directory");
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a one-thread pool");
    let mut stats = Stats::default();
    for i in indices {
        tell(Event::Begin(i));
        let found = stats.findings.len();
        let live = live();
        begin(i);
        let c = case(seed, i);
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            pool.install(|| run(&c, dir, budget))
        }));
        let peak = end(live);
        stats.peak = stats.peak.max(peak);
        match result {
            Ok(Ok(Outcome::Rendered)) => stats.rendered += 1,
            Ok(Ok(Outcome::Refused)) => stats.refused += 1,
            Ok(Err(finding)) => stats.findings.push((i, finding)),
            Err(p) => stats
                .findings
                .push((i, format!("panic: {}", panic_text(&*p)))),
        }
        if peak > memory {
            stats
                .findings
                .push((i, format!("memory: {} MiB at its peak", peak >> 20)));
        }
        for (i, f) in &stats.findings[found..] {
            tell(Event::Finding(*i, f));
        }
    }
    stats
}
