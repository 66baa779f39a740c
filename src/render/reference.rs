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
//!
//! Glass (the dispersive prism, spec §6) is the one place where a ray branches. At a
//! glass hit at level L the colour is
//!
//! ```text
//! clamp( phong + (kr + kt·F)·C_reflected + kt·(1 − F)·C_transmitted , 0, 1)
//! ```
//!
//! with F the exact dielectric Fresnel reflectance (1 under total internal reflection)
//! and both rays traced at level L + 1: refraction consumes levels like mirror rays, so
//! level N still gives N − 1 bounces of either kind, and every level still returns a
//! clamped colour. `kr` keeps its meaning (an extra mirror term, as on every object);
//! `kt` weighs the Fresnel-split glass transport. The ray is RGB until it meets glass;
//! there its transmitted part splits into the pixel's 16 wavelengths
//! ([`Wavelengths`]), each traced monochromatically (its own n(λ) at every later glass
//! surface) and summed with RGB weights that add up to (1, 1, 1); the reflected part,
//! the same ray for every wavelength, is traced once with the weighted mean of
//! kr + kt·F. Branches that could add at most [`GLASS_CUTOFF`] (1/2048, an eighth of
//! an 8-bit step) to the pixel are not traced; scenes without
//! glass never branch, never prune and render exactly as before. The light that glass
//! bends onto other surfaces (the caustic) comes from [`CausticMap`]: every non-glass
//! surface adds `kd · c ⊙ E_caustic` to its Phong sum. Shadow rays treat glass as
//! opaque; the light it transmits arrives through the caustic instead.

use glam::DVec3;

use super::caustic::{CausticMap, CausticSettings, PhotonHit, PhotonTracer, glass_of};
use super::frame::{SampleBlock, SampleColors, SampleTracer, Samples};
use super::spectral::{
    CAMERA_SAMPLES, GLASS_CUTOFF, MAX_GLASS_DEPTH, Wavelengths, glass_interface, nm_to_um,
};
use super::{FrameRenderer, RenderSettings, RenderStats, Rendered};
use crate::geometry::{self, RefHit, SurfacePoint, floor, prism};
use crate::math::Ray;
use crate::math::float::offset_ray_origin;
use crate::output::framebuffer::quantize;
use crate::scene::{Floor, Material, Scene, Shape};

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
    /// Per object: its faces and bounding sphere if it is a prism (computed once; the
    /// same hits as `geometry::intersect_ref`).
    prisms: Vec<Option<prism::Prepared>>,
    /// Light bent by glass onto other surfaces; `None` without glass.
    caustics: Option<CausticMap>,
    /// Seed of the per-pixel wavelengths.
    seed: u64,
    /// The recursion level traced (the scene's unless a profile caps it).
    recursion_level: u32,
    /// Quadric objects: each nearest-hit query tests them all (`quadric_tests`).
    quadrics: u64,
}

/// The pixel a camera ray belongs to, and its wavelengths once a ray meets glass.
struct PixelCtx {
    x: u32,
    y: u32,
    seed: u64,
    wavelengths: std::cell::OnceCell<Wavelengths>,
}

impl PixelCtx {
    fn wavelengths(&self) -> &Wavelengths {
        self.wavelengths
            .get_or_init(|| Wavelengths::for_pixel(self.x, self.y, self.seed))
    }
}

impl<'a> Reference<'a> {
    /// The reference over `scene`, with the default caustic settings (the photon pass
    /// runs here, only if the scene has glass).
    pub fn new(scene: &'a Scene) -> Self {
        Self::with_caustics(scene, &CausticSettings::default())
    }

    /// The reference over `scene`; `settings` sets the photon count, radius and seed.
    pub fn with_caustics(scene: &'a Scene, settings: &CausticSettings) -> Self {
        let prisms = scene
            .objects
            .iter()
            .map(|o| match &o.shape {
                Shape::Prism { v, .. } => Some(prism::Prepared::new(v)),
                _ => None,
            })
            .collect();
        let mut r = Reference {
            scene,
            prisms,
            caustics: None,
            seed: settings.seed,
            recursion_level: scene.recursion_level,
            quadrics: scene
                .objects
                .iter()
                .filter(|o| matches!(o.shape, Shape::Quadric(_)))
                .count() as u64,
        };
        if scene.has_prisms() {
            r.caustics = CausticMap::build(scene, settings, &r);
        }
        r
    }

    /// Traces at most `level` levels (a profile's `max_recursion`); the photon map does
    /// not depend on it.
    pub fn cap_recursion(mut self, level: u32) -> Self {
        self.recursion_level = self.recursion_level.min(level);
        self
    }

    /// The caustic photon map, if the scene has glass that a light reaches.
    pub fn caustics(&self) -> Option<&CausticMap> {
        self.caustics.as_ref()
    }

    /// The nearest hit with 0 < t < t_max. Ties in t go to the object listed first;
    /// the floor comes after every object.
    pub fn nearest(&self, ray: &Ray, t_max: f64) -> Option<Found> {
        let mut best: Option<Found> = None;
        let mut t_best = t_max;
        for (i, object) in self.scene.objects.iter().enumerate() {
            if let Some(hit) = self.intersect(i, &object.shape, ray, t_best) {
                t_best = hit.t;
                best = Some(Found {
                    target: Target::Object(i),
                    hit,
                });
            }
        }
        // the floor loses ties, also those that rounding splits: a face lying on it (a
        // prism's base) meets the ray at a t computed by the triangle formula, a few
        // ulps either side of the floor's
        let t_floor = if best.is_some() {
            t_best * floor::TIE
        } else {
            t_best
        };
        if let Some(t) = floor::intersect_ref(ray, t_floor) {
            best = Some(Found {
                target: Target::Floor,
                hit: RefHit::at(t),
            });
        }
        best
    }

    /// Whether anything, the floor included, lies on the ray with 0 < t < t_max.
    pub fn occluded(&self, ray: &Ray, t_max: f64) -> bool {
        self.occluded_counted(ray, t_max, &mut 0)
    }

    /// [`Reference::occluded`], adding the quadrics it tested to `quadric_tests`.
    fn occluded_counted(&self, ray: &Ray, t_max: f64, quadric_tests: &mut u64) -> bool {
        floor::intersect_ref(ray, t_max).is_some()
            || self.scene.objects.iter().enumerate().any(|(i, o)| {
                *quadric_tests += u64::from(matches!(o.shape, Shape::Quadric(_)));
                self.intersect(i, &o.shape, ray, t_max).is_some()
            })
    }

    /// Object `i` against `ray`: prisms through their prepared faces, every other kind
    /// through `geometry::intersect_ref`.
    fn intersect(&self, i: usize, shape: &Shape, ray: &Ray, t_max: f64) -> Option<RefHit> {
        match &self.prisms[i] {
            Some(p) => p.intersect_ref(ray, t_max),
            None => geometry::intersect_ref(shape, ray, t_max),
        }
    }

    /// Surface record, colour and material at a hit.
    pub fn surface(&self, ray: &Ray, found: &Found) -> (SurfacePoint, DVec3, Material) {
        match found.target {
            Target::Floor => {
                let s = floor::surface_ref(ray, found.hit.t);
                (s, floor::color_ref(ray, found.hit.t), Floor::MATERIAL)
            }
            Target::Object(i) => {
                let o = &self.scene.objects[i];
                let s = match &self.prisms[i] {
                    Some(p) => p.surface_ref(&found.hit),
                    None => geometry::surface_ref(&o.shape, ray, &found.hit),
                };
                (s, o.material.color, o.material)
            }
        }
    }

    /// The colour seen along a camera ray (traced at level 1), each channel in [0, 1],
    /// with the wavelengths of pixel (0, 0) should it meet glass.
    pub fn trace(&self, camera_ray: &Ray, stats: &mut RenderStats) -> DVec3 {
        self.trace_pixel(camera_ray, 0, 0, stats)
    }

    /// The colour seen along a camera ray of pixel (x, y) (its wavelengths, if it meets
    /// glass, are a hash of the pixel and the seed).
    pub fn trace_pixel(&self, camera_ray: &Ray, x: u32, y: u32, stats: &mut RenderStats) -> DVec3 {
        let px = PixelCtx {
            x,
            y,
            seed: self.seed,
            wavelengths: std::cell::OnceCell::new(),
        };
        self.radiance(*camera_ray, 1, None, 1.0, 0, &px, stats)
    }

    /// The colour along `ray` traced at `level`: RGB (`lambda` None) or one wavelength
    /// (nm). `weight` bounds what the colour of this ray can add to the pixel (the
    /// product of the branch weights from the camera, times the wavelength's largest RGB
    /// weight on monochromatic paths); `depth` is the recursion depth.
    ///
    /// Reflection is a chain (one mirror ray per hit), so it is followed with a loop,
    /// not recursion: any recursion level runs in constant stack. At glass the heavier
    /// branch continues the loop and the lighter one recurses. The per-level clamping of
    /// the spec is applied on the way back, from the deepest hit up.
    #[allow(clippy::too_many_arguments)]
    fn radiance(
        &self,
        mut ray: Ray,
        mut level: u32,
        lambda: Option<f64>,
        mut weight: f64,
        depth: u32,
        px: &PixelCtx,
        stats: &mut RenderStats,
    ) -> DVec3 {
        // per level: the local colour (with any branched-off light) and the weight of
        // the colour of the next level in the chain
        let mut chain = MirrorChain::default();
        loop {
            stats.quadric_tests += self.quadrics;
            let Some(found) = self.nearest(&ray, f64::INFINITY) else {
                break;
            };
            if level == 1 {
                stats.nearest_hit = stats.nearest_hit.min(found.hit.t);
            }
            let (mut surf, color, m) = self.surface(&ray, &found);
            let outward = surf.normal; // unflipped: prism faces are wound outwards
            // every normal is flipped to face the incoming ray
            if surf.normal.dot(ray.dir) > 0.0 {
                surf.normal = -surf.normal;
            }
            let glass = match found.target {
                Target::Object(i) => glass_of(&self.scene.objects[i].shape),
                Target::Floor => None,
            };
            let mut local = self.phong(&surf, color, &m, -ray.dir, stats);
            let Some(g) = glass else {
                if let Some(map) = &self.caustics {
                    local += map.irradiance(surf.point, surf.normal) * m.kd * color;
                }
                chain.push((local, DVec3::splat(m.kr)));
                // level N gives N − 1 bounces; kr = 0 would add exactly nothing
                if level >= self.recursion_level || m.kr == 0.0 {
                    break;
                }
                let n = surf.normal;
                let dir = (ray.dir - n * (2.0 * ray.dir.dot(n))).normalize();
                ray = Ray::new(offset_ray_origin(surf.point, surf.err, n, dir), dir);
                stats.reflection_rays += 1;
                level += 1;
                weight *= m.kr;
                continue;
            };
            // glass: reflected and transmitted rays, both at the next level
            if level >= self.recursion_level {
                chain.push((local, DVec3::ZERO));
                break;
            }
            let next = level + 1;
            let spawn =
                |dir: DVec3| Ray::new(offset_ray_origin(surf.point, surf.err, outward, dir), dir);
            let (side, main_weight, main_dir) = match lambda {
                None => {
                    // RGB meets glass: the transmitted light splits into wavelengths
                    let wl = px.wavelengths();
                    // one bound for every wavelength of the pixel, so that pruning never
                    // treats wavelengths differently where the glass does not
                    let reach_w = wl
                        .weight
                        .iter()
                        .map(|w| w.max_element())
                        .fold(0.0, f64::max);
                    let mut side = DVec3::ZERO;
                    let mut reflect_weight = DVec3::ZERO;
                    let mut reflected = ray.dir;
                    for i in 0..CAMERA_SAMPLES {
                        let n = g.index(nm_to_um(wl.lambda[i]));
                        let f = glass_interface(ray.dir, outward, n);
                        reflected = f.reflected;
                        reflect_weight += wl.weight[i] * (m.kr + g.kt * f.fresnel);
                        let wt = g.kt * (1.0 - f.fresnel);
                        // what this wavelength's path can add to the pixel, at most
                        let reach = weight * wt * reach_w;
                        if let Some(t) = f.transmitted
                            && reach > GLASS_CUTOFF
                            && depth < MAX_GLASS_DEPTH
                        {
                            stats.refraction_rays += 1;
                            let c = self.radiance(
                                spawn(t),
                                next,
                                Some(wl.lambda[i]),
                                reach,
                                depth + 1,
                                px,
                                stats,
                            );
                            side += wl.weight[i] * wt * c;
                        }
                    }
                    (side, reflect_weight, reflected)
                }
                Some(l) => {
                    let f = glass_interface(ray.dir, outward, g.index(nm_to_um(l)));
                    let wr = m.kr + g.kt * f.fresnel;
                    match f.transmitted {
                        Some(t) if g.kt * (1.0 - f.fresnel) > 0.0 => {
                            let wt = g.kt * (1.0 - f.fresnel);
                            let (main, main_w, other, other_w) = if wt >= wr {
                                (t, wt, f.reflected, wr)
                            } else {
                                (f.reflected, wr, t, wt)
                            };
                            let mut side = DVec3::ZERO;
                            if other_w * weight > GLASS_CUTOFF && depth < MAX_GLASS_DEPTH {
                                if other == t {
                                    stats.refraction_rays += 1;
                                } else {
                                    stats.reflection_rays += 1;
                                }
                                side = other_w
                                    * self.radiance(
                                        spawn(other),
                                        next,
                                        lambda,
                                        weight * other_w,
                                        depth + 1,
                                        px,
                                        stats,
                                    );
                            }
                            (side, DVec3::splat(main_w), main)
                        }
                        _ => (DVec3::ZERO, DVec3::splat(wr), f.reflected),
                    }
                }
            };
            chain.push((local + side, main_weight));
            let w = main_weight.max_element();
            if w * weight <= GLASS_CUTOFF {
                break;
            }
            // a transmitted ray goes on through the surface, a reflected one turns back
            if (main_dir.dot(outward) > 0.0) == (ray.dir.dot(outward) > 0.0) {
                stats.refraction_rays += 1;
            } else {
                stats.reflection_rays += 1;
            }
            ray = spawn(main_dir);
            level = next;
            weight *= w;
        }
        chain.fold()
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
                stats.cone_tests += 1;
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
            if len > 0.0
                && self.occluded_counted(
                    &Ray::new(origin, segment / len),
                    len,
                    &mut stats.quadric_tests,
                )
            {
                continue;
            }
            let r = n * (2.0 * n_dot_l) - l;
            out += lc * m.kd * n_dot_l * color;
            out += lc * m.ks * r.dot(v).max(0.0).powf(m.shine) * color;
        }
        out
    }
}

impl PhotonTracer for Reference<'_> {
    fn nearest(&self, ray: &Ray) -> Option<PhotonHit> {
        let found = Reference::nearest(self, ray, f64::INFINITY)?;
        let (s, _, _) = self.surface(ray, &found);
        Some(PhotonHit {
            t: found.hit.t,
            point: s.point,
            normal: s.normal,
            err: s.err,
            object: match found.target {
                Target::Object(i) => Some(i),
                Target::Floor => None,
            },
        })
    }
}

/// Renders a frame on the reference path: one ray through each pixel centre.
pub fn render(scene: &Scene, settings: &RenderSettings) -> Rendered {
    render_with(scene, settings, &CausticSettings::default())
}

/// [`render`] with explicit caustic settings (photon count, radius, seed). The photon
/// pass (only for scenes with glass) runs before the frame and is not in
/// `stats.elapsed`.
pub fn render_with(
    scene: &Scene,
    settings: &RenderSettings,
    caustic: &CausticSettings,
) -> Rendered {
    Reference::with_caustics(scene, caustic).render(settings, 1)
}

/// The levels of a mirror chain: per level the local colour and the weight of the next
/// level's colour, folded back from the deepest with the spec's per-level clamping.
/// Memory stays bounded at any recursion level: every [`CHAIN_LEVELS`] levels are
/// composed into one map x ↦ clamp(a + b·x, lo, hi) per channel (a composition of such
/// maps with b >= 0 is one), so a chain of at most that many levels folds exactly as
/// written, a longer one within f64 rounding of it.
#[derive(Default)]
struct MirrorChain {
    levels: Vec<(DVec3, DVec3)>,
    /// (a, b, lo, hi) of the levels already composed, outermost first.
    prefix: Option<[DVec3; 4]>,
}

/// Levels a [`MirrorChain`] holds before composing them.
const CHAIN_LEVELS: usize = 64;

impl MirrorChain {
    fn push(&mut self, level: (DVec3, DVec3)) {
        if self.levels.len() == CHAIN_LEVELS {
            for &(local, kr) in &self.levels {
                let inner = [local, kr, DVec3::ZERO, DVec3::ONE];
                self.prefix = Some(match self.prefix {
                    None => inner,
                    Some([a, b, lo, hi]) => {
                        let apply = |x: DVec3| (a + b * x).clamp(lo, hi);
                        // weights above 1 compound without bound; inputs lie in [0, 1]
                        let hold = |v: DVec3| v.clamp(DVec3::splat(-1e300), DVec3::splat(1e300));
                        [
                            hold(a + b * local),
                            hold(b * kr),
                            apply(inner[2]),
                            apply(inner[3]),
                        ]
                    }
                });
            }
            self.levels.clear();
        }
        self.levels.push(level);
    }

    fn fold(&self) -> DVec3 {
        let c = self
            .levels
            .iter()
            .rev()
            .fold(DVec3::ZERO, |deeper, &(local, kr)| {
                (local + deeper * kr).clamp(DVec3::ZERO, DVec3::ONE)
            });
        match self.prefix {
            Some([a, b, lo, hi]) => (a + b * c).clamp(lo, hi),
            None => c,
        }
    }
}

/// The reference's side of the frame loop: each sample of a block, one ray at a time.
impl SampleTracer for Reference<'_> {
    type Scratch = ();
    type Colors = RefColors;

    fn trace_block(
        &self,
        samples: &Samples,
        block: SampleBlock,
        _scratch: &mut (),
        stats: &mut RenderStats,
    ) -> RefColors {
        let grid = &samples.grid;
        let mut out = [DVec3::ZERO; 8];
        for (k, c) in out.iter_mut().enumerate() {
            if block.bits >> k & 1 == 1 {
                let (x, y) = (block.x + k as u32 % 4, block.y + k as u32 / 4);
                let ray = Ray::new(grid.eye, samples.direction(x, y));
                *c = self.trace_pixel(&ray, x, y, stats);
            }
        }
        RefColors(out)
    }
}

/// The reference's colours of a block of samples, in f64.
#[derive(Clone, Copy, Debug)]
pub struct RefColors(pub [DVec3; 8]);

impl SampleColors for RefColors {
    type Sum = DVec3;

    fn rgb8(&self) -> [[u8; 3]; 8] {
        self.0
            .map(|c| [quantize(c.x), quantize(c.y), quantize(c.z)])
    }

    fn lane(&self, k: usize) -> DVec3 {
        self.0[k]
    }

    fn add(sum: DVec3, c: DVec3) -> DVec3 {
        sum + c
    }

    fn resolve(sum: DVec3, count: u32) -> [u8; 3] {
        let c = sum * (1.0 / count as f64);
        [quantize(c.x), quantize(c.y), quantize(c.z)]
    }

    fn linear(sum: DVec3, count: u32) -> DVec3 {
        sum * (1.0 / count as f64)
    }
}
