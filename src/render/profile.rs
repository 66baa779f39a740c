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
use crate::scene::parse::MAX_RECURSION_LEVEL;
use crate::scene::text::escaped;

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

/// Why a profile could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    /// Bad TOML, an unknown key or a bad value, at `file:line:column`.
    #[error("{file}:{line}:{column}: {}{message}", key_prefix(key.as_deref()))]
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
        let table = toml::de::DeTable::parse(text).map_err(|e| syntax_error(text, file, &e))?;
        let mut p = Profile {
            name: name.to_string(),
            path: RenderPath::Packet,
            samples_per_pixel: 1,
            sampler: SamplerKind::Uniform,
            threshold: DEFAULT_THRESHOLD,
            resolution_scale: 1.0,
            max_recursion: None,
            photons: super::caustic::CausticSettings::default().photons,
            packet: PacketOptions::default(),
        };
        // where `sampler` and `threshold` were set, for the checks that need every key
        let mut sampler_at = None;
        let mut threshold_at = None;
        for (key, value) in table.get_ref().iter() {
            let key_span = key.span();
            let key: &str = key.get_ref();
            let at = |span: std::ops::Range<usize>, message: String| {
                let (line, column) = line_column(text, span.start);
                ProfileError::Syntax {
                    file: file.to_string(),
                    line,
                    column,
                    key: Some(key.to_string()),
                    message,
                }
            };
            let span = value.span();
            // the value as written, for "found ..."
            let found = || escaped(text.get(span.clone()).unwrap_or("")).to_string();
            let value = value.get_ref();
            let bad = |expected: &str| {
                at(
                    span.clone(),
                    format!("expected {expected}, found {}", found()),
                )
            };
            match key {
                "path" => {
                    p.path = match string(value) {
                        Some("reference") => RenderPath::Reference,
                        Some("packet") => RenderPath::Packet,
                        _ => return Err(bad("\"reference\" or \"packet\"")),
                    }
                }
                "samples_per_pixel" => {
                    p.samples_per_pixel = integer(value, 1, 64)
                        .filter(|n| (1..=8).any(|r| r * r == *n))
                        .ok_or_else(|| {
                            bad("a square number of samples from 1 to 64 (1, 4, 9, 16, 25, 36, 49 or 64)")
                        })? as u32
                }
                "sampler" => {
                    p.sampler = match string(value) {
                        Some("uniform") => SamplerKind::Uniform,
                        Some("adaptive") => SamplerKind::Adaptive,
                        _ => return Err(bad("\"uniform\" or \"adaptive\"")),
                    };
                    sampler_at = Some(span.start);
                }
                "threshold" => {
                    p.threshold = number(value)
                        .filter(|t| (0.0..=1.0).contains(t))
                        .ok_or_else(|| {
                            bad("a threshold from 0 to 1 (a fraction of full scale, e.g. 0.02)")
                        })? as f32;
                    threshold_at = Some(span.start);
                }
                "resolution_scale" => {
                    p.resolution_scale = number(value)
                        .filter(|s| (1.0 / 16.0..=1.0).contains(s))
                        .ok_or_else(|| bad("a number from 0.0625 to 1"))?
                }
                "max_recursion" => {
                    let cap = integer(value, 0, MAX_RECURSION_LEVEL).ok_or_else(|| {
                        bad(&format!(
                            "an integer from 0 (the scene's own level) to {MAX_RECURSION_LEVEL}"
                        ))
                    })?;
                    p.max_recursion = (cap > 0).then_some(cap as u32);
                }
                "photons" => {
                    let max = super::caustic::MAX_PHOTONS;
                    p.photons = integer(value, 0, max.into())
                        .ok_or_else(|| bad(&format!("an integer from 0 to {max}")))?
                        as u32
                }
                "single_ray_lanes" => {
                    p.packet.single_ray_lanes = integer(value, 0, 8)
                        .ok_or_else(|| bad("an integer from 0 to 8"))? as u32
                }
                "triangle_test" => {
                    p.packet.triangle_test = match string(value) {
                        Some("watertight") => TriangleTest::Watertight,
                        Some("moller") => TriangleTest::Moller,
                        _ => return Err(bad("\"watertight\" or \"moller\"")),
                    }
                }
                "ray_offset" => {
                    p.packet.ray_offset = string(value)
                        .and_then(|s| RayOffset::try_from(s.to_string()).ok())
                        .ok_or_else(|| {
                            bad("\"error_bound\" or \"epsilon:<value>\" with a finite value > 0")
                        })?
                }
                "shadow_any_hit" => {
                    p.packet.shadow_any_hit = match value {
                        toml::de::DeValue::Boolean(b) => *b,
                        _ => return Err(bad("true or false")),
                    }
                }
                _ => {
                    let message = format!("unknown key; the keys are {}", KEYS.join(", "));
                    return Err(at(key_span, message));
                }
            }
        }
        let contradiction = |offset: usize, key: &str, message: &str| {
            let (line, column) = line_column(text, offset);
            ProfileError::Syntax {
                file: file.to_string(),
                line,
                column,
                key: Some(key.to_string()),
                message: message.to_string(),
            }
        };
        if let (SamplerKind::Uniform, Some(at)) = (p.sampler, threshold_at) {
            return Err(contradiction(
                at,
                "threshold",
                "only the adaptive sampler has a threshold (add sampler = \"adaptive\")",
            ));
        }
        if let (SamplerKind::Adaptive, Some(at)) = (p.sampler, sampler_at)
            && p.samples_per_pixel < 4
        {
            return Err(contradiction(
                at,
                "sampler",
                "the adaptive sampler refines a pixel to its samples_per_pixel grid: \
                 set samples_per_pixel to 4 or more",
            ));
        }
        Ok(p)
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

/// `key `photons`: ` before a message (the key escaped; an empty key said so).
fn key_prefix(key: Option<&str>) -> String {
    match key {
        None => String::new(),
        Some("") => "an empty key: ".to_string(),
        Some(k) => format!("key `{}`: ", escaped(k)),
    }
}

/// The keys of a profile file, in the order of `profiles/*.toml`.
const KEYS: [&str; 11] = [
    "path",
    "samples_per_pixel",
    "sampler",
    "threshold",
    "resolution_scale",
    "max_recursion",
    "photons",
    "single_ray_lanes",
    "triangle_test",
    "ray_offset",
    "shadow_any_hit",
];

/// A string value.
fn string<'a>(v: &'a toml::de::DeValue<'_>) -> Option<&'a str> {
    match v {
        toml::de::DeValue::String(s) => Some(s),
        _ => None,
    }
}

/// An integer value in `lo..=hi` (any base TOML allows).
fn integer(v: &toml::de::DeValue<'_>, lo: i64, hi: i64) -> Option<i64> {
    match v {
        toml::de::DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix())
            .ok()
            .filter(|n| (lo..=hi).contains(n)),
        _ => None,
    }
}

/// A number value, integer or float.
fn number(v: &toml::de::DeValue<'_>) -> Option<f64> {
    match v {
        toml::de::DeValue::Float(f) => f.as_str().parse().ok(),
        toml::de::DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix())
            .ok()
            .map(|n| n as f64),
        _ => None,
    }
}

/// 1-based line and column (in characters) of byte `at` of `text`.
fn line_column(text: &str, at: usize) -> (usize, usize) {
    let before = text.get(..at.min(text.len())).unwrap_or(text);
    let line_start = before.rfind(['\n', '\r']).map_or(0, |i| i + 1);
    let line = crate::scene::text::lines(before).count().max(1)
        + usize::from(before.ends_with(['\n', '\r']));
    (line, before[line_start..].chars().count() + 1)
}

/// A TOML syntax error as `file:line:column`, with the key on that line; a key set
/// twice is said so.
fn syntax_error(text: &str, file: &str, e: &toml::de::Error) -> ProfileError {
    let start = e.span().map_or(0, |s| s.start).min(text.len());
    let (line, column) = line_column(text, start);
    let line_start = text[..start].rfind(['\n', '\r']).map_or(0, |i| i + 1);
    let line_text = crate::scene::text::lines(&text[line_start..])
        .next()
        .unwrap_or("");
    let key = line_text
        .split_once('=')
        .map(|(k, _)| k.trim().trim_matches(['"', '\'']).to_string())
        .filter(|k| !k.is_empty() && !k.starts_with('#') && !k.starts_with('['));
    let message = match e.message().trim() {
        "duplicate key" => "set twice".to_string(),
        m => m.to_string(),
    };
    ProfileError::Syntax {
        file: file.to_string(),
        line,
        column,
        key,
        message,
    }
}
