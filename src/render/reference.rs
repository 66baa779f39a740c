//! The reference path: the oracle of every faster path.
//!
//! f64 throughout, one ray at a time, every object tested against every ray (no
//! acceleration structure), each rule of `docs/scene-format.md` written out in the
//! order the spec states it. It is written to be read, not to be fast. It never calls
//! packet or BVH code and no fast path calls it, so one bug cannot pass both.
//!
//! Secondary rays (shadow and mirror) start at the hit point moved just past its
//! floating-point error bound along the normal ([`offset_ray_origin`]), so they never
//! re-hit the surface they leave, at any scale.

use glam::DVec3;

use super::frame::render_bands;
use super::{RenderSettings, RenderStats, Rendered};
use crate::geometry::{self, RefHit, SurfacePoint, floor};
use crate::math::Ray;
use crate::math::float::offset_ray_origin;
use crate::output::framebuffer::quantize;
use crate::scene::{Floor, Material, Scene};

/// What a ray hit: an object of the scene (by index in file order) or the floor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    Object(usize),
    Floor,
}

/// The nearest hit of a ray.
#[derive(Clone, Copy, Debug)]
pub struct Found {
    pub target: Target,
    pub hit: RefHit,
}

/// The reference renderer over one scene.
pub struct Reference<'a> {
    scene: &'a Scene,
}

impl<'a> Reference<'a> {
    pub fn new(scene: &'a Scene) -> Self {
        Reference { scene }
    }

    /// The nearest hit with 0 < t < t_max. Ties in t go to the object listed first;
    /// the floor comes after every object.
    pub fn nearest(&self, ray: &Ray, t_max: f64) -> Option<Found> {
        let mut best: Option<Found> = None;
        let mut t_best = t_max;
        for (i, object) in self.scene.objects.iter().enumerate() {
            if let Some(hit) = geometry::intersect_ref(&object.shape, ray, t_best) {
                t_best = hit.t;
                best = Some(Found {
                    target: Target::Object(i),
                    hit,
                });
            }
        }
        if let Some(t) = floor::intersect_ref(ray, t_best) {
            best = Some(Found {
                target: Target::Floor,
                hit: RefHit::at(t),
            });
        }
        best
    }

    /// Whether anything, the floor included, lies on the ray with 0 < t < t_max.
    pub fn occluded(&self, ray: &Ray, t_max: f64) -> bool {
        floor::intersect_ref(ray, t_max).is_some()
            || self
                .scene
                .objects
                .iter()
                .any(|o| geometry::intersect_ref(&o.shape, ray, t_max).is_some())
    }

    /// Surface record, colour and material at a hit.
    pub fn surface(&self, ray: &Ray, found: &Found) -> (SurfacePoint, DVec3, Material) {
        match found.target {
            Target::Floor => {
                let s = floor::surface_ref(ray, found.hit.t);
                (s, Floor::color_at(s.point.x, s.point.y), Floor::MATERIAL)
            }
            Target::Object(i) => {
                let o = &self.scene.objects[i];
                let s = geometry::surface_ref(&o.shape, ray, &found.hit);
                (s, o.material.color, o.material)
            }
        }
    }

    /// The colour seen along a camera ray (traced at level 1), each channel in [0, 1].
    ///
    /// Reflection is a chain (one mirror ray per hit), so it is followed with a loop,
    /// not recursion: any recursion level runs in constant stack. The per-level
    /// clamping of the spec is applied on the way back, from the deepest hit up.
    pub fn trace(&self, camera_ray: &Ray, stats: &mut RenderStats) -> DVec3 {
        let mut chain: Vec<(DVec3, f64)> = Vec::new();
        let mut ray = *camera_ray;
        let mut level = 1;
        while let Some(found) = self.nearest(&ray, f64::INFINITY) {
            let (mut surf, color, m) = self.surface(&ray, &found);
            // every normal is flipped to face the incoming ray
            if surf.normal.dot(ray.dir) > 0.0 {
                surf.normal = -surf.normal;
            }
            let local = self.phong(&surf, color, &m, -ray.dir, stats);
            chain.push((local, m.kr));
            // level N gives N − 1 bounces; kr = 0 would add exactly nothing
            if level >= self.scene.recursion_level || m.kr == 0.0 {
                break;
            }
            let n = surf.normal;
            let dir = (ray.dir - n * (2.0 * ray.dir.dot(n))).normalize();
            ray = Ray::new(offset_ray_origin(surf.point, surf.err, n, dir), dir);
            stats.reflection_rays += 1;
            level += 1;
        }
        chain
            .iter()
            .rev()
            .fold(DVec3::ZERO, |deeper, &(local, kr)| {
                (local + deeper * kr).clamp(DVec3::ZERO, DVec3::ONE)
            })
    }

    /// Ambient plus, for every point light then every spotlight, Phong diffuse and
    /// specular if the light is inside its cone, unshadowed and in front of the surface.
    /// `n` (in `surf`) faces the viewer; `v` points to the viewer.
    fn phong(
        &self,
        surf: &SurfacePoint,
        color: DVec3,
        m: &Material,
        v: DVec3,
        stats: &mut RenderStats,
    ) -> DVec3 {
        let p = surf.point;
        let n = surf.normal;
        let mut out = color * m.ka;
        let points = self
            .scene
            .point_lights
            .iter()
            .map(|l| (l.position, l.color, None));
        let spots = self
            .scene
            .spot_lights
            .iter()
            .map(|s| (s.position, s.color, Some(s)));
        for (lp, lc, spot) in points.chain(spots) {
            // spotlight only: skip it if the hit is outside the cone (hard edge)
            if let Some(s) = spot {
                let w = p - lp;
                let angle = s.direction.cross(w).length().atan2(s.direction.dot(w));
                if angle.to_degrees() > s.cutoff_deg {
                    continue;
                }
            }
            let to_light = lp - p;
            let dist = to_light.length();
            if dist == 0.0 {
                continue; // the light sits on the surface: no direction to it
            }
            let l = to_light / dist;
            let n_dot_l = n.dot(l);
            if n_dot_l <= 0.0 {
                continue;
            }
            // shadow: anything on the segment between the surface and the light
            let origin = offset_ray_origin(p, surf.err, n, l);
            let segment = lp - origin;
            let len = segment.length();
            stats.shadow_rays += 1;
            if len > 0.0 && self.occluded(&Ray::new(origin, segment / len), len) {
                continue;
            }
            let r = n * (2.0 * n_dot_l) - l;
            out += lc * m.kd * n_dot_l * color;
            out += lc * m.ks * r.dot(v).max(0.0).powf(m.shine) * color;
        }
        out
    }
}

/// Renders a frame on the reference path: one ray through each pixel centre.
pub fn render(scene: &Scene, settings: &RenderSettings) -> Rendered {
    let grid = settings.camera.pixel_grid(settings.width, settings.height);
    let tracer = Reference::new(scene);
    let width = settings.width;
    render_bands(settings, 1, |row, pixels| {
        let mut stats = RenderStats::default();
        for (i, px) in pixels.iter_mut().enumerate() {
            let ray = Ray::new(grid.eye, grid.direction(i as f64, row as f64));
            let c = tracer.trace(&ray, &mut stats);
            *px = [quantize(c.x), quantize(c.y), quantize(c.z)];
        }
        stats.primary_rays += width as u64;
        stats
    })
}
