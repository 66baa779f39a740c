//! Render profiles: named sets of knobs, each a code-path choice made once per frame,
//! never tested per ray.
//!
//! A profile is a TOML file (`profiles/*.toml`: `reference`, the oracle, and the ladder
//! `preview`, `fast` — the default —, `quality` and `accurate`); every knob and its
//! default is documented in those files.
//! [`Profile::load`] takes a name (looked up in `./profiles/`, else the copies compiled
//! into the binary) or a path. Unknown keys and bad values are errors naming
//! file:line:column and the key.
//!
//! [`super::prepared::Prepared`] applies a profile to a scene.

use std::path::Path;

use serde::Deserialize;

pub use super::frame::Sampler;
pub use super::options::{PacketOptions, RayOffset, TriangleTest};

/// Which renderer traces the frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RenderPath {
    /// f64, one ray at a time, every object tested: the oracle.
    Reference,
    /// f32, 8-ray packets through a binned-SAH BVH: the fast path.
    Packet,
}

/// How a profile samples pixels (`sampler`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SamplerKind {
    /// The `samples_per_pixel` grid in every pixel.
    Uniform,
    /// The pixels' corners, then the grid where they differ by more than `threshold`.
    Adaptive,
}

/// The adaptive sampler's threshold when a profile names none.
pub const DEFAULT_THRESHOLD: f32 = 0.05;

impl TryFrom<String> for RayOffset {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        if s == "error_bound" {
            return Ok(RayOffset::ErrorBound);
        }
        if let Some(v) = s.strip_prefix("epsilon:") {
            return match v.trim().parse::<f32>() {
                Ok(e) if e.is_finite() && e > 0.0 => Ok(RayOffset::Epsilon(e)),
                _ => Err(format!(
                    "`{s}`: the epsilon must be a finite number > 0, e.g. \"epsilon:1e-3\""
                )),
            };
        }
        Err(format!(
            "`{s}`: expected \"error_bound\" or \"epsilon:<value>\""
        ))
    }
}

/// A named profile: every knob of `profiles/*.toml`, validated.
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    pub name: String,
    pub path: RenderPath,
    /// Samples per pixel, a square n² (n × n stratified sub-pixel grid); 1 = pixel centre.
    pub samples_per_pixel: u32,
    /// The grid in every pixel, or adaptively.
    pub sampler: SamplerKind,
    /// The adaptive sampler's threshold: the largest channel difference between a
    /// pixel's corners (linear, [0, 1]) that leaves the pixel unrefined.
    pub threshold: f32,
    /// Render at this fraction of the requested size, then upscale (bilinear); 1 = off.
    pub resolution_scale: f64,
    /// Cap on the scene's recursion level; `None` = the scene's own.
    pub max_recursion: Option<u32>,
    /// Caustic photons emitted for scenes with glass (0 = no caustic).
    pub photons: u32,
    /// The packet path's options (`single_ray_lanes`, `triangle_test`, `ray_offset`,
    /// `shadow_any_hit`).
    pub packet: PacketOptions,
}

/// `samples_per_pixel`: a square from 1 to 64.
#[derive(Deserialize)]
#[serde(try_from = "u32")]
struct Spp(u32);

impl TryFrom<u32> for Spp {
    type Error = String;
    fn try_from(n: u32) -> Result<Self, String> {
        let root = (1..=8).find(|r| r * r == n);
        root.map(|_| Spp(n)).ok_or_else(|| {
            format!("{n}: expected a square number of samples from 1 to 64 (1, 4, 9, 16, ...)")
        })
    }
}

/// `resolution_scale`: in [1/16, 1].
#[derive(Deserialize)]
#[serde(try_from = "f64")]
struct Scale(f64);

impl TryFrom<f64> for Scale {
    type Error = String;
    fn try_from(s: f64) -> Result<Self, String> {
        if (1.0 / 16.0..=1.0).contains(&s) {
            Ok(Scale(s))
        } else {
            Err(format!("{s}: expected a scale from 0.0625 to 1"))
        }
    }
}

/// `threshold`: in [0, 1].
#[derive(Deserialize)]
#[serde(try_from = "f64")]
struct Threshold(f32);

impl TryFrom<f64> for Threshold {
    type Error = String;
    fn try_from(t: f64) -> Result<Self, String> {
        if (0.0..=1.0).contains(&t) {
            Ok(Threshold(t as f32))
        } else {
            Err(format!(
                "{t}: expected a threshold from 0 to 1 (a fraction of full scale, e.g. 0.02)"
            ))
        }
    }
}

/// `single_ray_lanes`: 0 to 8.
#[derive(Deserialize)]
#[serde(try_from = "u32")]
struct Lanes(u32);

impl TryFrom<u32> for Lanes {
    type Error = String;
    fn try_from(n: u32) -> Result<Self, String> {
        if n <= 8 {
            Ok(Lanes(n))
        } else {
            Err(format!("{n}: expected 0 to 8 lanes"))
        }
    }
}

/// `photons`: 0 to 10 million.
#[derive(Deserialize)]
#[serde(try_from = "u32")]
struct Photons(u32);

impl TryFrom<u32> for Photons {
    type Error = String;
    fn try_from(n: u32) -> Result<Self, String> {
        if n <= 10_000_000 {
            Ok(Photons(n))
        } else {
            Err(format!("{n}: expected at most 10000000 photons"))
        }
    }
}

/// The file format: every key optional, defaults as documented in `profiles/*.toml`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ProfileFile {
    path: Option<RenderPath>,
    samples_per_pixel: Option<Spp>,
    sampler: Option<toml::Spanned<SamplerKind>>,
    threshold: Option<toml::Spanned<Threshold>>,
    resolution_scale: Option<Scale>,
    max_recursion: Option<u32>,
    photons: Option<Photons>,
    single_ray_lanes: Option<Lanes>,
    triangle_test: Option<TriangleTest>,
    ray_offset: Option<RayOffset>,
    shadow_any_hit: Option<bool>,
}

/// Why a profile could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    /// Bad TOML, an unknown key or a bad value, at `file:line:column`.
    #[error("{file}:{line}:{column}: {}{message}", key.as_ref().map_or(String::new(), |k| format!("key `{k}`: ")))]
    Syntax {
        file: String,
        line: usize,
        column: usize,
        key: Option<String>,
        message: String,
    },
    #[error("{path}: {error}")]
    Io { path: String, error: std::io::Error },
    #[error("unknown profile `{0}` (built in: {names}; or give a path to a .toml file)", names = Profile::NAMES.join(", "))]
    Unknown(String),
}

/// The profiles compiled into the binary, so it runs from any directory.
const BUILTIN: &[(&str, &str)] = &[
    ("reference", include_str!("../../profiles/reference.toml")),
    ("accurate", include_str!("../../profiles/accurate.toml")),
    ("quality", include_str!("../../profiles/quality.toml")),
    ("fast", include_str!("../../profiles/fast.toml")),
    ("preview", include_str!("../../profiles/preview.toml")),
];

impl Profile {
    /// Names of the built-in profiles (`profiles/*.toml`).
    pub const NAMES: &'static [&'static str] =
        &["reference", "accurate", "quality", "fast", "preview"];

    /// The profile used when none is named.
    pub fn default_name() -> &'static str {
        "fast"
    }

    /// A built-in profile by name (the copy compiled into the binary).
    pub fn by_name(name: &str) -> Option<Profile> {
        let (_, text) = BUILTIN.iter().find(|(n, _)| *n == name)?;
        let file = format!("profiles/{name}.toml");
        Some(Profile::from_toml(name, text, &file).expect("built-in profiles are valid"))
    }

    /// `spec` is a path (it ends in `.toml` or contains a `/`) or a name: `profiles/NAME.toml`
    /// under the current directory if it exists, else the built-in copy.
    pub fn load(spec: &str) -> Result<Profile, ProfileError> {
        let looks_like_path = spec.ends_with(".toml") || spec.contains('/') || spec.contains('\\');
        if looks_like_path {
            return Profile::from_file(Path::new(spec));
        }
        let local = Path::new("profiles").join(format!("{spec}.toml"));
        if local.is_file() {
            return Profile::from_file(&local);
        }
        Profile::by_name(spec).ok_or_else(|| ProfileError::Unknown(spec.to_string()))
    }

    /// Loads a profile file; its name is the file stem.
    pub fn from_file(path: &Path) -> Result<Profile, ProfileError> {
        let io = |error| ProfileError::Io {
            path: path.display().to_string(),
            error,
        };
        let bytes = crate::scene::read_input(path).map_err(io)?;
        let text = String::from_utf8(bytes).map_err(|e| {
            let at = e.utf8_error().valid_up_to();
            let bytes = e.as_bytes();
            let line = 1 + bytes[..at].iter().filter(|&&b| b == b'\n').count();
            io(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("line {line}: not UTF-8 text (byte {at})"),
            ))
        })?;
        let name = path
            .file_stem()
            .map_or_else(|| "profile".into(), |s| s.to_string_lossy().into_owned());
        Profile::from_toml(&name, &text, &path.display().to_string())
    }

    /// Parses profile `name` from TOML `text`; `file` names it in errors.
    pub fn from_toml(name: &str, text: &str, file: &str) -> Result<Profile, ProfileError> {
        let f: ProfileFile = toml::from_str(text).map_err(|e| syntax_error(text, file, &e))?;
        let samples_per_pixel = f.samples_per_pixel.map_or(1, |s| s.0);
        let sampler = f
            .sampler
            .as_ref()
            .map_or(SamplerKind::Uniform, |s| *s.get_ref());
        if let (SamplerKind::Uniform, Some(t)) = (sampler, &f.threshold) {
            return Err(knob_error(
                text,
                file,
                t.span().start,
                "threshold",
                "only the adaptive sampler has a threshold (add sampler = \"adaptive\")",
            ));
        }
        if let Some(s) = &f.sampler
            && sampler == SamplerKind::Adaptive
            && samples_per_pixel < 4
        {
            return Err(knob_error(
                text,
                file,
                s.span().start,
                "sampler",
                "the adaptive sampler refines a pixel to its samples_per_pixel grid: \
                 set samples_per_pixel to 4 or more",
            ));
        }
        Ok(Profile {
            name: name.to_string(),
            path: f.path.unwrap_or(RenderPath::Packet),
            samples_per_pixel,
            sampler,
            threshold: f.threshold.map_or(DEFAULT_THRESHOLD, |t| t.into_inner().0),
            resolution_scale: f.resolution_scale.map_or(1.0, |s| s.0),
            max_recursion: f.max_recursion.filter(|&m| m > 0),
            photons: f
                .photons
                .map_or(super::caustic::CausticSettings::default().photons, |p| p.0),
            packet: {
                let d = PacketOptions::default();
                PacketOptions {
                    single_ray_lanes: f.single_ray_lanes.map_or(d.single_ray_lanes, |l| l.0),
                    triangle_test: f.triangle_test.unwrap_or(d.triangle_test),
                    ray_offset: f.ray_offset.unwrap_or(d.ray_offset),
                    shadow_any_hit: f.shadow_any_hit.unwrap_or(d.shadow_any_hit),
                }
            },
        })
    }

    /// Sub-pixel grid side: `samples_per_pixel` = n².
    pub fn samples_per_axis(&self) -> u32 {
        (1..=8)
            .find(|n| n * n == self.samples_per_pixel)
            .unwrap_or(1)
    }

    /// The frame loop's sampler of this profile.
    pub fn sampler(&self) -> Sampler {
        let n = self.samples_per_axis();
        match self.sampler {
            SamplerKind::Uniform => Sampler::Uniform { n },
            SamplerKind::Adaptive => Sampler::Adaptive {
                n,
                threshold: self.threshold,
            },
        }
    }
}

/// A knob that contradicts another, at byte `offset` of `text`, as `file:line:column`.
fn knob_error(text: &str, file: &str, offset: usize, key: &str, message: &str) -> ProfileError {
    let before = &text[..offset.min(text.len())];
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    ProfileError::Syntax {
        file: file.to_string(),
        line: before.matches('\n').count() + 1,
        column: before[line_start..].chars().count() + 1,
        key: Some(key.to_string()),
        message: message.to_string(),
    }
}

/// A TOML error as `file:line:column`, with the key on that line.
fn syntax_error(text: &str, file: &str, e: &toml::de::Error) -> ProfileError {
    let start = e.span().map_or(0, |s| s.start).min(text.len());
    let before = &text[..start];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = before[line_start..].chars().count() + 1;
    let line_text = text[line_start..].lines().next().unwrap_or("");
    let key = line_text
        .split_once('=')
        .map(|(k, _)| k.trim().trim_matches('"').to_string())
        .filter(|k| !k.is_empty() && !k.starts_with('#') && !k.starts_with('['));
    ProfileError::Syntax {
        file: file.to_string(),
        line,
        column,
        key,
        message: e.message().trim().to_string(),
    }
}
