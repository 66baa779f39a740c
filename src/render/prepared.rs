//! A profile applied to one scene: the renderer it picks, built once, then any number of
//! frames.
//!
//! The frame-level knobs of a [`Profile`] are applied here, the same on both paths:
//!
//! - `samples_per_pixel` = n²: the frame loop's n × n stratified samples per pixel
//!   ([`super::frame`]); at n = 1 one ray through each pixel centre, the spec's image.
//! - `sampler`, `threshold`: that grid everywhere (`uniform`), or only inside the pixels
//!   whose corners differ by more than the threshold (`adaptive`,
//!   [`super::frame::Sampler`]).
//! - `resolution_scale`: the frame is rendered at the scaled size, then upscaled
//!   (bilinear) to the requested one.
//! - `max_recursion`: caps the recursion level the renderer is built with.
//! - `photons`: the caustic photon count (scenes with glass only).
//!
//! The packet path works in an f32 frame whose origin is set here explicitly
//! ([`frame_origin`] for a single render: the camera's eye, or the world origin for a
//! mesh whose vertices are f32 values; [`Prepared::rebase`] moves it, as the viewer
//! does when its camera has flown far from it).

use std::time::Instant;

use glam::DVec3;

use super::caustic::CausticSettings;
use super::packet::PacketRenderer;
use super::profile::{Profile, RenderPath};
use super::reference::Reference;
use super::{FrameRenderer, PixelRect, RenderSettings, Rendered};
use crate::output::Framebuffer;
use crate::scene::{Scene, Shape};

/// How far, in multiples of the view's nearest hit distance, the eye may move from the
/// packet path's f32 frame origin before [`Prepared::follow`] re-centres the frame.
pub const REBASE_RATIO: f64 = 4.0;

/// A profile prepared for one scene.
pub struct Prepared<'a> {
    profile: Profile,
    scene: &'a Scene,
    engine: Engine<'a>,
}

/// The renderer a profile picked for a scene, once.
enum Engine<'a> {
    /// The reference, with its photon map if the scene has glass.
    Reference(Box<Reference<'a>>),
    /// The packet renderer in its f32 frame.
    Packet(Box<PacketRenderer>),
}

impl Profile {
    /// Builds what this profile needs for `scene` (the packet path's BVH in an f32 frame
    /// centred on `origin`, the photon map of a scene with glass) for any number of
    /// frames.
    pub fn prepare<'a>(&self, scene: &'a Scene, origin: DVec3) -> Prepared<'a> {
        Prepared::new(self, scene, origin)
    }

    /// Renders one frame (prepares the scene first, in the frame [`frame_origin`] picks
    /// for its eye; prefer [`Profile::prepare`] for many frames of one scene).
    pub fn render(&self, scene: &Scene, settings: &RenderSettings) -> Rendered {
        self.prepare(scene, frame_origin(scene, settings.camera.eye))
            .render(settings)
    }
}

/// The packet path's f32 frame origin for one view from `eye`.
///
/// The eye, so that what is near it keeps its detail however far the scene lies from
/// the world origin; but the world origin for a scene with a mesh whose vertices are
/// all f32 values (as OBJ files written from f32 data hold), where the eye lies within
/// [`REBASE_RATIO`] times a lower bound of the nearest hit distance (the distance to
/// the floor's plane and to every object's box) from the world origin. The mesh's
/// vertices are then exact in the frame: re-rounded about the eye they tilt small
/// triangles by up to about 1e-4 rad, which decides shadow edges and highlights
/// differently from the reference. Points in view carry at most 1 + [`REBASE_RATIO`]
/// times the rounding of a frame at the eye, the standard [`Prepared::follow`] keeps.
/// Scenes with a quadric keep the eye (their reach is not measured here).
pub fn frame_origin(scene: &Scene, eye: DVec3) -> DVec3 {
    let f32_exact = |v: &[DVec3]| {
        v.iter()
            .all(|p| p.as_vec3().as_dvec3() == *p && p.is_finite())
    };
    let exact_mesh = scene
        .objects
        .iter()
        .any(|o| matches!(&o.shape, Shape::Mesh(m) if f32_exact(m.vertices())));
    if !exact_mesh {
        return eye;
    }
    // distance from the eye to the box of `v` (0 inside it)
    let box_distance = |v: &[DVec3]| {
        let lo = v.iter().fold(DVec3::INFINITY, |a, &p| a.min(p));
        let hi = v.iter().fold(DVec3::NEG_INFINITY, |a, &p| a.max(p));
        (lo - eye).max(eye - hi).max(DVec3::ZERO).length()
    };
    let mut near = eye.z.abs();
    for o in &scene.objects {
        let d = match &o.shape {
            Shape::Sphere { center, radius } => (center.distance(eye) - radius).max(0.0),
            Shape::Triangle { v } => box_distance(v),
            Shape::Prism { v, .. } => box_distance(v),
            Shape::Mesh(m) => box_distance(m.vertices()),
            Shape::Quadric(_) => return eye,
        };
        near = near.min(d);
    }
    if eye.length() <= REBASE_RATIO * near {
        DVec3::ZERO
    } else {
        eye
    }
}

impl<'a> Prepared<'a> {
    /// Builds what `profile` needs for `scene`; the packet path's f32 frame is centred
    /// on `origin` (use the camera's eye).
    pub fn new(profile: &Profile, scene: &'a Scene, origin: DVec3) -> Prepared<'a> {
        let caustic = CausticSettings {
            photons: profile.photons,
            ..CausticSettings::default()
        };
        let cap = profile.max_recursion.unwrap_or(u32::MAX);
        let engine = match profile.path {
            RenderPath::Reference => Engine::Reference(Box::new(
                Reference::with_caustics(scene, &caustic).cap_recursion(cap),
            )),
            RenderPath::Packet => Engine::Packet(Box::new(
                PacketRenderer::with_options(scene, origin, &profile.packet, &caustic)
                    .cap_recursion(cap),
            )),
        };
        Prepared {
            profile: profile.clone(),
            scene,
            engine,
        }
    }

    /// The profile this was prepared with.
    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    /// The path that renders this scene.
    pub fn path(&self) -> RenderPath {
        match self.engine {
            Engine::Reference(_) => RenderPath::Reference,
            Engine::Packet(_) => RenderPath::Packet,
        }
    }

    /// The packet path's f32 frame origin (world); `None` on the reference.
    pub fn origin(&self) -> Option<DVec3> {
        match &self.engine {
            Engine::Packet(p) => Some(p.base()),
            Engine::Reference(_) => None,
        }
    }

    /// Moves the packet path's f32 frame to `origin`: rebuilds its BVH and tables there
    /// (the reference has no frame: nothing to do).
    pub fn rebase(&mut self, origin: DVec3) {
        if matches!(self.engine, Engine::Packet(_)) {
            *self = Prepared::new(&self.profile, self.scene, origin);
        }
    }

    /// Re-centres the packet path's f32 frame on `eye` when the eye has moved from its
    /// origin by more than [`REBASE_RATIO`] times `nearest`, the distance to the nearest
    /// thing the last frame's camera rays hit (the scale the view must resolve): points
    /// in view then carry at most 1 + [`REBASE_RATIO`] times the rounding they would
    /// in a frame centred on the eye. Returns whether it moved.
    pub fn follow(&mut self, eye: DVec3, nearest: f64) -> bool {
        match self.origin() {
            Some(origin) if origin.distance(eye) > REBASE_RATIO * nearest => {
                self.rebase(eye);
                true
            }
            _ => false,
        }
    }

    /// On the packet path: the scene's smallest object against its distance
    /// ([`super::precision`]).
    pub fn smallest_detail(&self) -> Option<super::precision::Detail> {
        match &self.engine {
            Engine::Packet(p) => p.smallest_detail(),
            Engine::Reference(_) => None,
        }
    }

    /// [`Prepared::smallest_detail`] where f32 loses it
    /// ([`super::precision::Detail::below_f32`]): the command line warns.
    pub fn detail_below_f32(&self) -> Option<super::precision::Detail> {
        self.smallest_detail().filter(|d| d.below_f32())
    }

    /// Renders one frame, or the rectangle `settings.crop` of it (the same pixels as the
    /// whole frame's). `stats.elapsed` covers the frame, not the preparation.
    pub fn render(&self, settings: &RenderSettings) -> Rendered {
        let start = Instant::now();
        let sampler = self.profile.sampler();
        let packet;
        let frames: &dyn FrameRenderer = match &self.engine {
            Engine::Reference(r) => &**r,
            Engine::Packet(p) => {
                packet = p.frames();
                &*packet
            }
        };
        let scale = self.profile.resolution_scale;
        let scaled = |v: u32| ((v as f64 * scale).round() as u32).clamp(1, v.max(1));
        let (w, h) = (scaled(settings.width), scaled(settings.height));
        let mut out = if (w, h) == (settings.width, settings.height) {
            frames.render_sampled(settings, sampler)
        } else {
            // the whole frame at the scaled size, upscaled, then the crop cut out
            let inner = RenderSettings {
                width: w,
                height: h,
                crop: None,
                ..settings.clone()
            };
            let small = frames.render_sampled(&inner, sampler);
            let full = upscale_bilinear(&small.image, settings.width, settings.height);
            let rect = settings.rect();
            Rendered {
                image: cut(&full, rect),
                rect,
                stats: small.stats,
            }
        };
        out.stats.elapsed = start.elapsed();
        out
    }
}

/// The pixels `rect` of `image`.
fn cut(image: &Framebuffer, rect: PixelRect) -> Framebuffer {
    if rect == PixelRect::full(image.width, image.height) {
        return image.clone();
    }
    let mut out = Framebuffer::new(rect.width(), rect.height());
    for (y, row) in out.pixels.chunks_mut(rect.width() as usize).enumerate() {
        let from = (rect.y0 as usize + y) * image.width as usize + rect.x0 as usize;
        row.copy_from_slice(&image.pixels[from..from + row.len()]);
    }
    out
}

/// Bilinear upscale (pixel centres aligned, edges clamped); rows in parallel.
pub fn upscale_bilinear(src: &Framebuffer, width: u32, height: u32) -> Framebuffer {
    let mut out = Framebuffer::new(width, height);
    if src.width == 0 || src.height == 0 || width == 0 {
        return out;
    }
    let (sw, sh) = (src.width as usize, src.height as usize);
    let coord = |x: u32, n: u32, sn: usize| {
        let f = ((x as f64 + 0.5) * sn as f64 / n as f64 - 0.5).clamp(0.0, (sn - 1) as f64);
        let i = (f.floor() as usize).min(sn - 1);
        (i, (i + 1).min(sn - 1), f - i as f64)
    };
    let cols: Vec<_> = (0..width).map(|x| coord(x, width, sw)).collect();
    let row = |(y, line): (usize, &mut [[u8; 3]])| {
        let (y0, y1, fy) = coord(y as u32, height, sh);
        for (px, &(x0, x1, fx)) in line.iter_mut().zip(&cols) {
            let p = |xx: usize, yy: usize| src.pixels[yy * sw + xx];
            let (a, b, c, d) = (p(x0, y0), p(x1, y0), p(x0, y1), p(x1, y1));
            for k in 0..3 {
                let top = a[k] as f64 * (1.0 - fx) + b[k] as f64 * fx;
                let bottom = c[k] as f64 * (1.0 - fx) + d[k] as f64 * fx;
                px[k] = (top * (1.0 - fy) + bottom * fy).round() as u8;
            }
        }
    };
    if crate::parallel::parallel() {
        use rayon::prelude::*;
        out.pixels
            .par_chunks_mut(width as usize)
            .enumerate()
            .for_each(row);
    } else {
        out.pixels
            .chunks_mut(width as usize)
            .enumerate()
            .for_each(row);
    }
    out
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::scene::obj::Mesh;
    use crate::scene::{Material, Object, Quadric};

    fn scene_with(shapes: Vec<Shape>) -> Scene {
        let material = Material {
            color: DVec3::ONE,
            ka: 0.2,
            kd: 0.5,
            ks: 0.3,
            kr: 0.0,
            shine: 10.0,
        };
        Scene {
            recursion_level: 1,
            pixels: 8,
            objects: shapes
                .into_iter()
                .map(|shape| Object { shape, material })
                .collect(),
            point_lights: vec![],
            spot_lights: vec![],
        }
    }

    /// A mesh of one triangle at `at`, sides `side`.
    fn mesh(at: DVec3, side: f64) -> Shape {
        let v = vec![at, at + DVec3::X * side, at + DVec3::Y * side];
        Shape::Mesh(Arc::new(Mesh::new(v, vec![[0, 1, 2]])))
    }

    const EYE: DVec3 = DVec3::new(0.0, -3.0, 2.0);

    #[test]
    fn a_mesh_of_f32_vertices_in_view_of_the_world_origin_is_framed_there() {
        let s = scene_with(vec![mesh(DVec3::new(-0.5, 0.0, 0.25), 1.0)]);
        assert_eq!(frame_origin(&s, EYE), DVec3::ZERO);
        // with other kinds beside it
        let s = scene_with(vec![
            mesh(DVec3::new(-0.5, 0.0, 0.25), 1.0),
            Shape::Sphere {
                center: DVec3::new(1.0, 1.0, 1.0),
                radius: 0.5,
            },
            Shape::Triangle {
                v: [DVec3::ZERO, DVec3::X, DVec3::Y],
            },
        ]);
        assert_eq!(frame_origin(&s, EYE), DVec3::ZERO);
    }

    #[test]
    fn every_other_view_is_framed_at_the_eye() {
        let at = DVec3::new(-0.5, 0.0, 0.25);
        // no mesh
        let triangle = Shape::Triangle {
            v: [at, at + DVec3::X, at + DVec3::Y],
        };
        assert_eq!(frame_origin(&scene_with(vec![triangle]), EYE), EYE);
        // vertices that are not f32 values (0.1 is not)
        assert_eq!(
            frame_origin(&scene_with(vec![mesh(DVec3::splat(0.1), 1.0)]), EYE),
            EYE
        );
        // a mesh far from the world origin, seen from near it
        let far = DVec3::new(4096.0, 0.0, 0.0);
        assert_eq!(
            frame_origin(&scene_with(vec![mesh(far + at, 1.0)]), far + EYE),
            far + EYE
        );
        // the eye close to the floor's plane (something may be hit within 0.125)
        let low = DVec3::new(0.0, -3.0, 0.125);
        assert_eq!(frame_origin(&scene_with(vec![mesh(at, 1.0)]), low), low);
        // the eye close to a sphere
        let sphere = Shape::Sphere {
            center: EYE + DVec3::X,
            radius: 0.875,
        };
        assert_eq!(
            frame_origin(&scene_with(vec![mesh(at, 1.0), sphere]), EYE),
            EYE
        );
        // a quadric
        let quadric = Shape::Quadric(Quadric {
            coef: [1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0],
            min: DVec3::ZERO,
            size: DVec3::ZERO,
        });
        assert_eq!(
            frame_origin(&scene_with(vec![mesh(at, 1.0), quadric]), EYE),
            EYE
        );
    }

    /// `Profile::render` prepares the packet path in that frame.
    #[test]
    fn a_single_render_is_prepared_in_that_frame() {
        let s = scene_with(vec![mesh(DVec3::new(-20.0, -20.0, 5.0), 40.0)]);
        let settings = RenderSettings::square(32);
        let origin = frame_origin(&s, settings.camera.eye);
        assert_eq!(origin, DVec3::ZERO);
        let profile = Profile::by_name(Profile::default_name()).unwrap();
        let prepared = profile.prepare(&s, origin);
        assert_eq!(prepared.origin(), Some(origin));
        let image = profile.render(&s, &settings).image;
        assert!(image.pixels.iter().any(|p| *p != [0, 0, 0]));
        assert_eq!(image, prepared.render(&settings).image);
    }
}
