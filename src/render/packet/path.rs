//! A packet's path from the camera: one closest-hit query per level, the mirror chain
//! folded back with per-level clamping.

use wide::f32x8;

use super::chain::Chain;
use super::{Offset, Settings, Tracer};
use crate::bvh::Steps;
use crate::math::packet::{Cmp8, HitPacket8, Mask8, RayPacket8, Vec3x8};
use crate::render::RenderStats;
use crate::render::frame::Samples;

/// Where a packet sits in its path from the camera (only glass scenes read it).
#[derive(Clone, Copy, Debug)]
pub(super) struct PathState {
    /// Recursion level the packet is traced at (1 for camera rays).
    pub level: u32,
    /// `None`: RGB rays; else each lane's wavelength (nm): monochromatic rays.
    pub lambda: Option<[f32; 8]>,
    /// Per lane, the most this ray's colour can add to its pixel (see
    /// [`crate::render::spectral::GLASS_CUTOFF`]).
    pub weight: f32x8,
    /// Nested glass branchings so far.
    pub depth: u32,
    /// Pixel of lane 0 (lane k is pixel (x + k % 4, y + k / 4)), for the wavelengths;
    /// read for RGB packets only (a monochromatic packet's lanes are wavelengths).
    pub pixel: [u32; 2],
    /// The frame's pixel grid in f64, for camera packets whose lanes are `pixel`'s:
    /// their floor hits near a tile line are recomputed from it
    /// (`gather::camera_tiles`).
    pub grid: Option<Samples>,
}

impl PathState {
    pub fn camera(pixel: [u32; 2], grid: Option<Samples>) -> PathState {
        PathState {
            level: 1,
            lambda: None,
            weight: f32x8::splat(1.0),
            depth: 0,
            pixel,
            grid,
        }
    }

    /// A branch spawned at glass: one level and one nesting deeper, at wavelengths
    /// `lambda` (`None`: RGB) with path weights `weight`.
    pub fn branch(&self, lambda: Option<[f32; 8]>, weight: f32x8) -> PathState {
        PathState {
            level: self.level + 1,
            lambda,
            weight,
            depth: self.depth + 1,
            pixel: self.pixel,
            grid: None,
        }
    }
}

impl<S: Settings> Tracer<'_, S> {
    /// Closest hit of the active lanes (packet or, for few lanes, single-ray traversal).
    pub(super) fn closest(&self, r: &RayPacket8, active: Mask8, steps: &mut Steps) -> HitPacket8 {
        let mut hit = HitPacket8::new(f32x8::splat(f32::INFINITY));
        if active.count() <= self.options.single_ray_lanes {
            self.bvh
                .intersect_x8_lanes::<S::Tri>(r, active, &mut hit, steps);
        } else {
            self.bvh.intersect_x8::<S::Tri>(r, active, &mut hit, steps);
        }
        hit
    }

    /// Lanes of `active` blocked before `t_max`.
    pub(super) fn occluded(
        &self,
        r: &RayPacket8,
        active: Mask8,
        t_max: f32x8,
        steps: &mut Steps,
    ) -> Mask8 {
        if active.count() <= self.options.single_ray_lanes {
            self.bvh
                .occluded_x8_lanes::<S::Tri>(r, active, t_max, steps)
        } else {
            self.bvh.occluded_x8::<S::Tri>(r, active, t_max, steps)
        }
    }

    /// Lanes of `active` whose nearest hit lies before `t_max` (the shadow query with
    /// `shadow_any_hit = false`).
    pub(super) fn occluded_closest(
        &self,
        r: &RayPacket8,
        active: Mask8,
        t_max: f32x8,
        steps: &mut Steps,
    ) -> Mask8 {
        let hit = self.closest(r, active, steps);
        active & hit.hit_mask() & hit.t.lt(t_max)
    }

    /// The colours along a packet traced from `path.level` on: the mirror chain in a
    /// loop, per-level clamping folded back from the deepest level. In glass scenes a
    /// glass lane's heavier branch goes on in the loop (an RGB lane's reflection,
    /// weighted per channel; a monochromatic lane's heavier ray) and [`glass`] traces the
    /// others one level deeper, nested.
    /// `first`: the packet's closest hits when they were found already (camera packets
    /// traced two at a time).
    ///
    /// [`glass`]: super::glass
    #[allow(clippy::too_many_arguments)]
    pub(super) fn trace_path(
        &self,
        camera: &RayPacket8,
        active: Mask8,
        mut first: Option<HitPacket8>,
        path: &PathState,
        chain: &mut Chain,
        stats: &mut RenderStats,
        steps: &mut Steps,
    ) -> Vec3x8 {
        chain.clear();
        // the camera packet by reference (a copy was a memcpy of 480 bytes per packet),
        // the mirror packets in `bounced`
        let mut bounced: RayPacket8;
        let mut ray = camera;
        let mut active = active;
        let mut level = path.level;
        let mut weight = path.weight;
        loop {
            let hit = match first.take() {
                Some(hit) => hit,
                None => self.closest(ray, active, steps),
            };
            let lanes = active & hit.hit_mask();
            if lanes.none() {
                break;
            }
            let mut g = self.gather(ray, &hit, lanes);
            if level == 1
                && path.lambda.is_none()
                && let Some(grid) = &path.grid
            {
                self.camera_tiles(ray, &hit, lanes, grid, path.pixel, &mut g);
                let t = lanes.select(hit.t, f32x8::splat(f32::INFINITY)).to_array();
                let nearest = t.into_iter().fold(f32::INFINITY, f32::min);
                stats.nearest_hit = stats.nearest_hit.min(nearest as f64);
            }
            let mut local = self.phong(&g, -ray.dir, lanes, stats, steps);
            let mut kr = g.kr;
            // glass lanes' per-channel weight of the next level (RGB lanes)
            let mut tint: Option<Vec3x8> = None;
            // glass lanes that go on in this loop: their direction and whether they
            // were refracted (monochromatic lanes follow their heavier branch here)
            let mut turn: Option<(Mask8, Vec3x8, Mask8)> = None;
            if S::GLASS {
                let gh = self.glass_hits(&hit, lanes);
                let glass = gh.mask;
                local = self.add_caustic(&g, lanes.and_not(glass), local);
                if glass.any() {
                    // (at the last level a glass lane keeps only its Phong colour)
                    kr = glass.select(f32x8::ZERO, kr);
                    if level < self.recursion_level {
                        let here = PathState {
                            level,
                            weight,
                            ..*path
                        };
                        if path.lambda.is_none() {
                            // RGB: the reflection goes on here, weighted per channel
                            let (side, w) = self.split_rgb(ray, &g, &gh, &here, stats, steps);
                            local = local + side;
                            kr = glass.select(w.x.max(w.y).max(w.z), kr);
                            tint = Some(Vec3x8::select(glass, w, Vec3x8::new(kr, kr, kr)));
                        } else {
                            let m = self.split_mono(ray, &g, &gh, &here, stats, steps);
                            local = local + m.side;
                            kr = glass.select(m.main_weight, kr);
                            turn = Some((glass, m.main_dir, m.refracted));
                        }
                    }
                }
            }
            chain.push((local, tint.unwrap_or(Vec3x8::new(kr, kr, kr)), lanes));
            // level N gives N − 1 bounces; kr = 0 would add exactly nothing
            if level >= self.recursion_level {
                break;
            }
            let next = lanes.and_not(kr.eq8(f32x8::ZERO));
            if next.none() {
                break;
            }
            let n = g.normal;
            let d = ray.dir - n * (f32x8::splat(2.0) * ray.dir.dot(n));
            let mut d = d * (f32x8::splat(1.0) / d.length());
            let mut refracted = Mask8::NONE;
            if let Some((glass, main_dir, t)) = turn {
                d = Vec3x8::select(glass, main_dir, d);
                refracted = next & t;
            }
            let o = self.offset.origin(g.point, g.err, n, d);
            bounced = RayPacket8::new(o, d, next);
            ray = &bounced;
            active = next;
            stats.reflection_rays += next.and_not(refracted).count() as u64;
            stats.refraction_rays += refracted.count() as u64;
            level += 1;
            if S::GLASS {
                weight *= kr;
            }
        }
        chain.fold()
    }
}
