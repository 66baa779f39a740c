//! The digest a piece of a frame records (`octaray-digest`): of the scene and every
//! setting that changes pixels, so that `octaray assemble` refuses pieces of another
//! frame.
//!
//! It covers, as the readable text [`FrameDigest::settings`] lists them:
//! - the build: crate version, target architecture and the SIMD features compiled in
//!   (fused multiply-add and the vector width round differently);
//! - the scene as parsed: recursion level, every object (shape, material, glass, every
//!   mesh triangle and vertex) and light, bit for bit; not the file's name, comments or
//!   layout, nor its `pixels` line (the frame size stands for it);
//! - the frame size and the camera (eye, look, right, up, field of view, bit for bit:
//!   the packet path's f32 frame is centred on the eye);
//! - the profile's knobs (not its name), the packet path's only on that path.
//!
//! Not covered, as they do not change pixels: threads, the progress bar, the output
//! name and format, the piece's rectangle (recorded beside the digest).
//!
//! FNV-1a with 128 bits (a published, fixed function: the same on every machine and
//! build): enough to tell settings apart by mistake, not against forgery.

use glam::DVec3;

use crate::render::options::PacketOptions;
use crate::render::profile::{Profile, RenderPath, SamplerKind};
use crate::scene::{Camera, Glass, Material, Object, PointLight, Scene, Shape, SpotLight};

/// FNV-1a, 128 bits.
#[derive(Clone, Copy)]
pub struct Fnv1a128(u128);

impl Default for Fnv1a128 {
    fn default() -> Self {
        Fnv1a128(0x6c62272e07bb014262b821756295c58d)
    }
}

impl Fnv1a128 {
    const PRIME: u128 = 0x0000000001000000000000000000013b;

    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u128).wrapping_mul(Self::PRIME);
        }
    }

    fn u32(&mut self, v: u32) {
        self.write(&v.to_le_bytes());
    }

    fn f64(&mut self, v: f64) {
        self.write(&v.to_bits().to_le_bytes());
    }

    fn vec(&mut self, v: DVec3) {
        self.f64(v.x);
        self.f64(v.y);
        self.f64(v.z);
    }

    pub fn finish(&self) -> u128 {
        self.0
    }

    /// `fnv1a128:` and 32 hex digits.
    pub fn text(&self) -> String {
        format!("fnv1a128:{:032x}", self.0)
    }
}

/// The digest of a frame's settings and the text it is the digest of.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameDigest {
    /// What the digest covers, one line each (recorded beside it).
    pub settings: String,
    /// `fnv1a128:` and 32 hex digits of `settings`.
    pub digest: String,
}

impl FrameDigest {
    pub fn new(
        scene: &Scene,
        camera: &Camera,
        width: u32,
        height: u32,
        profile: &Profile,
    ) -> FrameDigest {
        let v = |p: DVec3| format!("[{:?}, {:?}, {:?}]", p.x, p.y, p.z);
        let Camera {
            eye,
            look,
            right,
            up,
            fov_y_deg,
        } = camera;
        let settings = [
            "octaray frame settings v1".to_string(),
            format!("build: {}", build()),
            format!("scene: {}", scene_summary(scene)),
            format!("frame: {width}x{height}"),
            format!(
                "camera: eye {}, look {}, right {}, up {}, fov {fov_y_deg:?}",
                v(*eye),
                v(*look),
                v(*right),
                v(*up)
            ),
            format!("profile: {}", profile_knobs(profile)),
        ]
        .join("\n");
        let mut h = Fnv1a128::default();
        h.write(settings.as_bytes());
        FrameDigest {
            settings,
            digest: h.text(),
        }
    }
}

/// Crate version, architecture and the SIMD features compiled in.
fn build() -> String {
    let features: Vec<&str> = [
        ("sse4.1", cfg!(target_feature = "sse4.1")),
        ("avx", cfg!(target_feature = "avx")),
        ("avx2", cfg!(target_feature = "avx2")),
        ("fma", cfg!(target_feature = "fma")),
        ("avx512f", cfg!(target_feature = "avx512f")),
        ("neon", cfg!(target_feature = "neon")),
    ]
    .into_iter()
    .filter_map(|(name, on)| on.then_some(name))
    .collect();
    format!(
        "octaray {}, {} ({})",
        env!("CARGO_PKG_VERSION"),
        std::env::consts::ARCH,
        features.join(" ")
    )
}

/// The scene's hash and counts.
fn scene_summary(scene: &Scene) -> String {
    format!(
        "{} (recursion level {}; {} objects, {} point lights, {} spot lights)",
        scene_hash(scene).text(),
        scene.recursion_level,
        scene.objects.len(),
        scene.point_lights.len(),
        scene.spot_lights.len()
    )
}

/// Every field of the scene that changes pixels, bit for bit (each type destructured, so
/// that a new field is a compile error here until it is hashed or named as ignored).
pub fn scene_hash(scene: &Scene) -> Fnv1a128 {
    let mut h = Fnv1a128::default();
    let Scene {
        recursion_level,
        pixels: _,
        objects,
        point_lights,
        spot_lights,
    } = scene;
    h.u32(*recursion_level);
    h.u32(objects.len() as u32);
    for Object { shape, material } in objects {
        hash_shape(&mut h, shape);
        let Material {
            color,
            ka,
            kd,
            ks,
            kr,
            shine,
        } = material;
        h.vec(*color);
        for c in [ka, kd, ks, kr, shine] {
            h.f64(*c);
        }
    }
    h.u32(point_lights.len() as u32);
    for PointLight { position, color } in point_lights {
        h.vec(*position);
        h.vec(*color);
    }
    h.u32(spot_lights.len() as u32);
    for SpotLight {
        position,
        color,
        direction,
        cutoff_deg,
    } in spot_lights
    {
        h.vec(*position);
        h.vec(*color);
        h.vec(*direction);
        h.f64(*cutoff_deg);
    }
    h
}

fn hash_shape(h: &mut Fnv1a128, shape: &Shape) {
    match shape {
        Shape::Sphere { center, radius } => {
            h.write(b"sphere");
            h.vec(*center);
            h.f64(*radius);
        }
        Shape::Triangle { v } => {
            h.write(b"triangle");
            v.iter().for_each(|p| h.vec(*p));
        }
        Shape::Quadric(q) => {
            h.write(b"quadric");
            let crate::scene::Quadric { coef, min, size } = q;
            coef.iter().for_each(|c| h.f64(*c));
            h.vec(*min);
            h.vec(*size);
        }
        Shape::Prism { v, glass } => {
            h.write(b"prism");
            v.iter().for_each(|p| h.vec(*p));
            let Glass {
                kt,
                cauchy_a,
                cauchy_b,
            } = glass;
            for c in [kt, cauchy_a, cauchy_b] {
                h.f64(*c);
            }
        }
        Shape::Mesh(mesh) => {
            h.write(b"mesh");
            let (vertices, triangles) = (mesh.vertices(), mesh.triangles());
            h.u32(vertices.len() as u32);
            vertices.iter().for_each(|p| h.vec(*p));
            h.u32(triangles.len() as u32);
            for t in triangles {
                t.iter().for_each(|i| h.u32(*i));
            }
        }
    }
}

/// The profile's knobs, not its name; the packet path's options only on that path.
fn profile_knobs(profile: &Profile) -> String {
    let Profile {
        name: _,
        path,
        samples_per_pixel,
        sampler,
        threshold,
        resolution_scale,
        max_recursion,
        photons,
        packet,
    } = profile;
    let mut out = format!(
        "path {path:?}, samples_per_pixel {samples_per_pixel}, sampler {sampler:?}, \
         resolution_scale {resolution_scale:?}, max_recursion {max_recursion:?}, photons {photons}"
    );
    if *sampler == SamplerKind::Adaptive {
        out += &format!(", threshold {threshold:?}");
    }
    if *path == RenderPath::Packet {
        let PacketOptions {
            shadow_any_hit,
            ray_offset,
            single_ray_lanes,
            triangle_test,
            // not part of the image: 16-lane packets give every ray the 8-lane hit
            isa: _,
        } = packet;
        out += &format!(
            ", shadow_any_hit {shadow_any_hit}, ray_offset {ray_offset:?}, \
             single_ray_lanes {single_ray_lanes}, triangle_test {triangle_test:?}"
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::parse::parse_scene;

    fn given() -> Scene {
        parse_scene(Scene::GIVEN, "given").unwrap().scene
    }

    fn digest(scene: &Scene, camera: &Camera, w: u32, profile: &Profile) -> String {
        FrameDigest::new(scene, camera, w, 48, profile).digest
    }

    /// FNV-1a 128's published test vectors.
    #[test]
    fn fnv1a_128_matches_its_specification() {
        let hash = |s: &[u8]| {
            let mut h = Fnv1a128::default();
            h.write(s);
            h.finish()
        };
        assert_eq!(hash(b""), 0x6c62272e07bb014262b821756295c58d);
        assert_eq!(hash(b"a"), 0xd228cb696f1a8caf78912b704e4a8964);
        assert_eq!(hash(b"foobar"), 0x343e1662793c64bf6f0d3597ba446f18);
    }

    #[test]
    fn every_setting_that_changes_pixels_changes_the_digest() {
        let scene = given();
        let camera = Camera::default();
        let fast = Profile::by_name("fast").unwrap();
        let base = digest(&scene, &camera, 64, &fast);
        // the same settings give the same digest; the profile's name is not a setting
        assert_eq!(base, digest(&scene.clone(), &camera, 64, &fast));
        let mut renamed = fast.clone();
        renamed.name = "renamed".into();
        assert_eq!(base, digest(&scene, &camera, 64, &renamed));
        // the scene's own size is not, the frame size is
        let mut other = scene.clone();
        other.pixels = 5;
        assert_eq!(base, digest(&other, &camera, 64, &fast));
        assert_ne!(base, digest(&scene, &camera, 65, &fast));
        // one bit of one object, a light, the recursion level
        let mut other = scene.clone();
        other.objects[3].material.shine =
            f64::from_bits(other.objects[3].material.shine.to_bits() + 1);
        assert_ne!(base, digest(&other, &camera, 64, &fast));
        let mut other = scene.clone();
        other.point_lights[0].color.x += 0.5;
        assert_ne!(base, digest(&other, &camera, 64, &fast));
        let mut other = scene.clone();
        other.recursion_level += 1;
        assert_ne!(base, digest(&other, &camera, 64, &fast));
        // the camera
        let mut moved = camera;
        moved.eye.z += 1e-9;
        assert_ne!(base, digest(&scene, &moved, 64, &fast));
        // the knobs, the packet path's only on that path
        let knob = |text: &str| Profile::from_toml("x", text, "x.toml").unwrap();
        assert_ne!(
            base,
            digest(&scene, &camera, 64, &knob("samples_per_pixel = 4"))
        );
        assert_ne!(base, digest(&scene, &camera, 64, &knob("photons = 7")));
        let adaptive = |t: &str| {
            let p = knob(&format!(
                "samples_per_pixel = 16\nsampler = \"adaptive\"\nthreshold = {t}"
            ));
            digest(&scene, &camera, 64, &p)
        };
        let uniform16 = digest(&scene, &camera, 64, &knob("samples_per_pixel = 16"));
        assert_ne!(uniform16, adaptive("0.05"));
        assert_ne!(adaptive("0.05"), adaptive("0.1"));
        assert_ne!(
            base,
            digest(&scene, &camera, 64, &knob("shadow_any_hit = false"))
        );
        let reference = knob("path = \"reference\"");
        let reference_moller = knob("path = \"reference\"\ntriangle_test = \"moller\"");
        assert_eq!(
            digest(&scene, &camera, 64, &reference),
            digest(&scene, &camera, 64, &reference_moller)
        );
    }

    #[test]
    fn the_settings_text_says_what_was_hashed() {
        let d = FrameDigest::new(
            &given(),
            &Camera::default(),
            1920,
            1080,
            &Profile::by_name("fast").unwrap(),
        );
        let lines: Vec<&str> = d.settings.lines().collect();
        assert_eq!(lines[0], "octaray frame settings v1");
        assert!(lines[2].starts_with("scene: fnv1a128:"), "{}", lines[2]);
        assert_eq!(lines[3], "frame: 1920x1080");
        assert!(
            lines[4].starts_with("camera: eye [100.0, 100.0, 50.0], look ["),
            "{}",
            lines[4]
        );
        assert!(
            lines[5].contains("samples_per_pixel 1,")
                && lines[5].contains("triangle_test Watertight")
        );
        assert!(d.digest.starts_with("fnv1a128:") && d.digest.len() == 9 + 32);
    }
}
