//! The packet path: the fast, default renderer.
//!
//! f32, eight rays at a time (`wide::f32x8`), through a binned-SAH [`Bvh`]; it computes
//! the picture of `docs/scene-format.md` exactly as the reference states it, and the
//! equivalence tests hold it to the reference per lane and per image. It never calls
//! reference code.
//!
//! - Frame: bands of [`BAND_ROWS`] rows over rayon; each band walks 4 × 2 pixel packets.
//! - Geometry lives in one f32 frame centred on the camera (built once per frame, f64
//!   subtraction then rounding), so scenes far from the world origin keep their detail.
//! - Per level: one closest-hit packet query; surfaces gathered per lane for the
//!   winners only; Phong shading in SIMD across the packet; one any-hit shadow packet
//!   per light from the lanes it can light (cone test only for spotlights); a mirror
//!   packet from the lanes that continue. Per-level clamping is folded back along the
//!   chain as in the reference.
//! - Secondary rays start off their surface by the hit's f32 error bound along the
//!   normal ([`offset_origin_x8`]).
//! - Packets with few active lanes (incoherent secondary rays) fall back to the
//!   single-ray traversal of the same tree, lane by lane, below [`FALLBACK_LANES`].
//! - Glass (prisms), only in scenes that have it ([`glass`]): at a glass hit the
//!   heavier branch goes on in the mirror-chain loop (an RGB lane's reflection, weighted
//!   per channel; a monochromatic lane's heavier ray), the rest is traced nested: an RGB
//!   lane's transmitted light as its pixel's 16 wavelengths in two packets of 8. The
//!   caustic photon map adds the light glass bends onto the surfaces it lands on.

mod glass;

use glam::{DVec3, Vec3};
use wide::{f32x8, f64x4, i32x8};

use super::caustic::{CausticMap, CausticSettings};
use super::frame::render_bands;
use super::{RenderSettings, RenderStats, Rendered};
use crate::bvh::{Bvh, Steps};
use crate::geometry::floor::{self, Floor32};
use crate::geometry::{PrimKind, PrimSet, Surface8, prim_code, split_code};
use crate::math::Ray;
use crate::math::packet::{
    Cmp8, HitPacket8, Mask8, Ray1, RayPacket8, Vec3x8, gamma32, offset_origin_x8,
};
use crate::scene::camera::PixelGrid;
use crate::scene::{Floor, Glass, Material, Scene, SpotLight};

/// Calls `$r.$method::<ANY_HIT, EPS, GLASS>(args)` with the renderer's knobs and the
/// scene's glass as constants: the one place a frame picks its compiled instance.
#[macro_export]
#[doc(hidden)]
macro_rules! with_packet_knobs {
    ($r:expr, $method:ident($($arg:expr),* $(,)?)) => {{
        let r = $r;
        match (r.shadow_any_hit, r.offset_epsilon.is_some(), r.has_glass()) {
            (true, false, false) => r.$method::<true, false, false>($($arg),*),
            (true, true, false) => r.$method::<true, true, false>($($arg),*),
            (false, false, false) => r.$method::<false, false, false>($($arg),*),
            (false, true, false) => r.$method::<false, true, false>($($arg),*),
            (true, false, true) => r.$method::<true, false, true>($($arg),*),
            (true, true, true) => r.$method::<true, true, true>($($arg),*),
            (false, false, true) => r.$method::<false, false, true>($($arg),*),
            (false, true, true) => r.$method::<false, true, true>($($arg),*),
        }
    }};
}

/// Rows per rayon work item (two packet rows).
pub const BAND_ROWS: u32 = 4;

/// Packets with at most this many active lanes are traced lane by lane with the
/// single-ray traversal (0 disables the fallback).
// criterion frame/given256/fast_prebuilt_fallback{0,1,2,4}: 12.0 / 13.2 / 12.8 / 9.5 ms,
// measured under heavy load from other jobs (±15 %): not yet conclusive, see
// benches/README.md.
pub const FALLBACK_LANES: u32 = 1;

/// The mirror chain of a packet: per level the local colour, the weight of the next
/// level's colour (kr; per channel for glass, whose reflection weight depends on the
/// wavelength) and the lanes that hit.
pub type Chain = Vec<(Vec3x8, Vec3x8, Mask8)>;

/// Shading parameters of one object, in f32.
#[derive(Clone, Copy, Debug)]
struct Mat32 {
    color: Vec3,
    ka: f32,
    kd: f32,
    ks: f32,
    kr: f32,
    shine: f32,
}

impl Mat32 {
    fn new(m: &Material) -> Mat32 {
        Mat32 {
            color: m.color.as_vec3(),
            ka: m.ka as f32,
            kd: m.kd as f32,
            ks: m.ks as f32,
            kr: m.kr as f32,
            // a positive shine stays positive (1e-300 would round to 0, whose rule,
            // x^0 = 1, lights every point with the full specular term)
            shine: if m.shine > 0.0 {
                (m.shine as f32).max(f32::from_bits(1))
            } else {
                0.0
            },
        }
    }
}

/// A light in the renderer's frame; spotlights carry their cone.
#[derive(Clone, Copy, Debug)]
struct Light32 {
    position: Vec3,
    color: Vec3,
    /// The cone of a spotlight with cutoff < 180°.
    cone: Option<Cone32>,
}

/// A spotlight's cone: a point P is inside when the angle θ between the axis and
/// w = P − Lp is at most the cutoff φ, tested as sin(φ − θ) >= 0, i.e.
/// |axis × w|·cos φ <= (axis · w)·sin φ, and axis · w >= 0 unless φ >= 90°.
/// Sines of small angles keep their relative precision where cosines do not: the
/// test `axis · w >= cos φ·|w|` in f32 resolved angles only to ~0.02° near the axis
/// (cos φ within an ulp of 1), so a 0.05° spotlight lit a disc twice too wide on
/// 2 % of a 256² view. In f32 the limit is then the rounded axis and light position,
/// ~1e-7 rad: still a fifth of a 1e-5° cone, which shifted its disc (3.8 % of the
/// pixels of a view framed on it). Cones within [`NARROW_CONE_DEG`] of 0° or 180°
/// are therefore tested in f64 (both found by an independent renderer of the spec).
#[derive(Clone, Copy, Debug)]
struct Cone32 {
    axis: Vec3,
    cos: f32,
    sin: f32,
    /// φ >= 90°: points behind the light's plane can be inside.
    wide: bool,
    /// A narrow cone (or the narrow dark cone behind a nearly full one): the axis and
    /// the light's position relative to the frame's origin, unrounded, and cos φ, sin φ.
    exact: Option<(DVec3, DVec3, f64, f64)>,
}

/// Spotlights whose cutoff lies within this of 0° or 180° test their cone in f64,
/// where f32's ~1e-7 rad of rounding would be a visible part of it.
const NARROW_CONE_DEG: f64 = 0.1;

impl Cone32 {
    /// The cone of spotlight `s` in the frame centred on `base`.
    fn new(s: &SpotLight, base: DVec3) -> Cone32 {
        let phi = s.cutoff_deg;
        // exactly 90°: cos φ = 0, so that points in the light's plane (axis · w = 0)
        // are inside, as the reference's atan2 finds them (cos(π/2) rounds to 6e-17)
        let (sin, cos) = if phi == 90.0 {
            (1.0, 0.0)
        } else {
            phi.to_radians().sin_cos()
        };
        let narrow = phi.min(180.0 - phi) < NARROW_CONE_DEG;
        Cone32 {
            axis: s.direction.as_vec3(),
            cos: cos as f32,
            sin: sin as f32,
            wide: phi >= 90.0,
            exact: narrow.then(|| (s.direction, s.position - base, cos, sin)),
        }
    }

    /// Lanes whose point `p` (frame coordinates) is inside the cone; `lp` is the
    /// light's position in the frame.
    #[inline(always)]
    fn contains(&self, p: Vec3x8, lp: Vec3x8) -> Mask8 {
        if let Some((axis, apex, cos, sin)) = self.exact {
            let mut bits = 0;
            for i in 0..8 {
                let w = p.lane(i).as_dvec3() - apex;
                let c = axis.dot(w);
                if axis.cross(w).length() * cos <= c * sin && (self.wide || c >= 0.0) {
                    bits |= 1 << i;
                }
            }
            return Mask8::from_bits(bits);
        }
        let axis = Vec3x8::splat(self.axis);
        let w = p - lp;
        let c = axis.dot(w);
        let s = axis.cross(w).length();
        let inside = (s * f32x8::splat(self.cos)).le(c * f32x8::splat(self.sin));
        if self.wide {
            inside
        } else {
            inside & c.ge(f32x8::ZERO)
        }
    }
}

/// A scene prepared for the packet path: BVH, materials and lights in one f32 frame
/// centred on `base`.
pub struct PacketRenderer {
    pub bvh: Bvh,
    base: DVec3,
    materials: Vec<Mat32>,
    floor: Mat32,
    lights: Vec<Light32>,
    recursion_level: u32,
    /// Packets with at most this many active lanes use the single-ray traversal.
    pub fallback_lanes: u32,
    /// Shadow rays stop at their first blocker (any-hit); `false` runs a closest-hit
    /// query instead (profile knob `shadow_any_hit`, chosen once per frame).
    pub shadow_any_hit: bool,
    /// Secondary rays leave surfaces by this fixed distance along the normal instead
    /// of the hit's error bound (profile knob `ray_offset = "epsilon:<value>"`,
    /// chosen once per frame).
    pub offset_epsilon: Option<f32>,
    /// Per object, its glass if it is a prism; empty when the scene has none.
    glass: Vec<Option<Glass>>,
    /// Light bent by glass onto other surfaces; `None` without glass.
    caustics: Option<CausticMap>,
    /// Seed of the per-pixel wavelengths (the caustic settings' seed).
    seed: u64,
    /// `Some(bits)` when every shininess (the floor's too) is a whole number below
    /// 2^bits ≤ 256: the specular power is then taken by squaring ([`pow_whole`]).
    whole_shine: Option<u32>,
}

/// Where a packet sits in its path from the camera (only glass scenes read it).
#[derive(Clone, Copy, Debug)]
struct PathState {
    /// Recursion level the packet is traced at (1 for camera rays).
    level: u32,
    /// `None`: RGB rays; else each lane's wavelength (nm): monochromatic rays.
    lambda: Option<[f32; 8]>,
    /// Per lane, the most this ray's colour can add to its pixel (see
    /// [`crate::render::spectral::GLASS_CUTOFF`]).
    weight: f32x8,
    /// Nested glass branchings so far.
    depth: u32,
    /// Pixel of lane 0 (lane k is pixel (x + k % 4, y + k / 4)), for the wavelengths;
    /// read for RGB packets only (a monochromatic packet's lanes are wavelengths).
    pixel: [u32; 2],
    /// The frame's pixel grid in f64, for camera packets whose lanes are `pixel`'s:
    /// their floor hits near a tile line are recomputed from it
    /// ([`PacketRenderer::camera_tiles`]).
    grid: Option<PixelGrid>,
}

impl PathState {
    fn camera(pixel: [u32; 2], grid: Option<PixelGrid>) -> PathState {
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
    fn branch(&self, lambda: Option<[f32; 8]>, weight: f32x8) -> PathState {
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

/// [`PacketRenderer::camera_tiles`] recomputes a camera ray's floor hit in f64 when
/// the f32 point lies within this many f32 ulps of |o| + t of a tile line.
const TILE_TRIGGER: f32 = 16.0;

/// Lights whose shadow packets [`PacketRenderer::phong`] sets up together.
const SHADOW_BATCH: usize = 4;

/// One light's shadow packet and what shading needs of it.
#[derive(Clone, Copy, Debug)]
struct ShadowRay {
    /// Lanes the light can reach (cone, front side).
    m: Mask8,
    /// Unit direction to the light and its cosine with the normal.
    l: Vec3x8,
    n_dot_l: f32x8,
    /// From the surface (offset) to the light, `len` long, over lanes `m_ray`.
    ray: RayPacket8,
    len: f32x8,
    m_ray: Mask8,
}

/// The per-lane surface data a level's shading needs, gathered for the winners.
struct Gathered {
    point: Vec3x8,
    /// Facing the incoming ray.
    normal: Vec3x8,
    /// Lanes whose geometric normal was turned round to face the ray (glass needs
    /// the outward one).
    flipped: Mask8,
    err: Vec3x8,
    color: Vec3x8,
    ka: f32x8,
    kd: f32x8,
    ks: f32x8,
    kr: f32x8,
    shine: f32x8,
}

impl PacketRenderer {
    /// Builds the BVH and tables of `scene` in a frame centred on `base` (use the
    /// camera's eye), with the default caustic settings should the scene have glass.
    pub fn new(scene: &Scene, base: DVec3) -> PacketRenderer {
        Self::with_caustics(scene, base, &CausticSettings::default())
    }

    /// [`PacketRenderer::new`]; `caustic` sets the photon count, radius and seed of the
    /// photon pass, which runs here (through this BVH) only if the scene has glass.
    pub fn with_caustics(scene: &Scene, base: DVec3, caustic: &CausticSettings) -> PacketRenderer {
        Self::with_options(scene, base, caustic, false)
    }

    /// [`PacketRenderer::with_caustics`]; `moller` picks the plain Möller–Trumbore
    /// triangle test for every triangle (profile knob `triangle_test = "moller"`),
    /// instead of the watertight one.
    pub fn with_options(
        scene: &Scene,
        base: DVec3,
        caustic: &CausticSettings,
        moller: bool,
    ) -> PacketRenderer {
        let mut prims = PrimSet::from_scene(scene, base);
        prims.moller = moller;
        let bvh = Bvh::build(prims);
        let rel = |p: DVec3| (p - base).as_vec3();
        // A light keeps its side of the floor plane (z = 0) in the f32 frame: rounded
        // there, one within half an ulp of the plane (1e-6 above it, seen from 50 units
        // away) would land on it, light nothing on the floor and shine through it.
        let floor_z = Floor32::new(base).z;
        let light_rel = |p: DVec3| {
            let mut q = rel(p);
            if p.z > 0.0 && q.z <= floor_z {
                q.z = floor_z.next_up();
            } else if p.z < 0.0 && q.z >= floor_z {
                q.z = floor_z.next_down();
            }
            q
        };
        let points = scene.point_lights.iter().map(|l| Light32 {
            position: light_rel(l.position),
            color: l.color.as_vec3(),
            cone: None,
        });
        let spots = scene.spot_lights.iter().map(|s| Light32 {
            position: light_rel(s.position),
            color: s.color.as_vec3(),
            cone: (s.cutoff_deg < 180.0).then(|| Cone32::new(s, base)),
        });
        let materials: Vec<Mat32> = scene
            .objects
            .iter()
            .map(|o| Mat32::new(&o.material))
            .collect();
        let floor = Mat32::new(&Floor::MATERIAL);
        let whole_shine = materials.iter().chain([&floor]).try_fold(0, |bits, m| {
            let s = m.shine;
            ((0.0..256.0).contains(&s) && s.fract() == 0.0)
                .then(|| bits.max(u32::BITS - (s as u32).leading_zeros()))
        });
        let mut r = PacketRenderer {
            bvh,
            base,
            materials,
            floor,
            lights: points.chain(spots).collect(),
            recursion_level: scene.recursion_level,
            fallback_lanes: FALLBACK_LANES,
            shadow_any_hit: true,
            offset_epsilon: None,
            glass: Vec::new(),
            caustics: None,
            seed: caustic.seed,
            whole_shine,
        };
        if scene.has_prisms() {
            r.glass = scene
                .objects
                .iter()
                .map(|o| super::caustic::glass_of(&o.shape))
                .collect();
            r.caustics = CausticMap::build(scene, caustic, &r);
        }
        r
    }

    /// Whether the scene has glass (then every frame runs the glass instance).
    pub fn has_glass(&self) -> bool {
        !self.glass.is_empty()
    }

    /// The caustic photon map, if the scene has glass that a light reaches.
    pub fn caustics(&self) -> Option<&CausticMap> {
        self.caustics.as_ref()
    }

    /// The frame's origin in world space.
    pub fn base(&self) -> DVec3 {
        self.base
    }

    /// Closest hit of the active lanes (packet or, for few lanes, single-ray traversal).
    fn closest(&self, r: &RayPacket8, active: Mask8, steps: &mut Steps) -> HitPacket8 {
        let mut hit = HitPacket8::new(f32x8::splat(f32::INFINITY));
        if active.count() <= self.fallback_lanes {
            self.bvh.intersect_x8_lanes(r, active, &mut hit, steps);
        } else {
            self.bvh.intersect_x8(r, active, &mut hit, steps);
        }
        hit
    }

    /// Lanes of `active` blocked before `t_max`.
    fn occluded(&self, r: &RayPacket8, active: Mask8, t_max: f32x8, steps: &mut Steps) -> Mask8 {
        if active.count() <= self.fallback_lanes {
            self.bvh.occluded_x8_lanes(r, active, t_max, steps)
        } else {
            self.bvh.occluded_x8(r, active, t_max, steps)
        }
    }

    /// Lanes of `active` whose nearest hit lies before `t_max` (the shadow query with
    /// `shadow_any_hit = false`).
    fn occluded_closest(
        &self,
        r: &RayPacket8,
        active: Mask8,
        t_max: f32x8,
        steps: &mut Steps,
    ) -> Mask8 {
        let hit = self.closest(r, active, steps);
        active & hit.hit_mask() & hit.t.lt(t_max)
    }

    /// The origin of a secondary ray leaving `p` (normal `n`, error bound `err`) along
    /// `w`: past the error bound, or by the fixed epsilon if `EPS`.
    #[inline(always)]
    fn leave<const EPS: bool>(&self, p: Vec3x8, err: Vec3x8, n: Vec3x8, w: Vec3x8) -> Vec3x8 {
        if EPS {
            let e = f32x8::splat(self.offset_epsilon.unwrap_or(0.0));
            p + n * w.dot(n).lt(f32x8::ZERO).select(-e, e)
        } else {
            offset_origin_x8(p, err, n, w)
        }
    }

    /// Surface, colour and material of each hit lane: floor lanes in SIMD (on most
    /// scenes the floor takes most lanes), the others lane by lane.
    fn gather(&self, r: &RayPacket8, hit: &HitPacket8, lanes: Mask8) -> Gathered {
        let Some(floor) = self.bvh.prims.floor else {
            return self.gather_lanes(r, hit, lanes);
        };
        let code = i32x8::splat(prim_code(PrimKind::Floor, 0));
        let on_floor = lanes & Mask8(wide::bytemuck::cast(hit.prim.simd_eq(code)));
        if on_floor.none() {
            return self.gather_lanes(r, hit, lanes);
        }
        let others = lanes.and_not(on_floor);
        // Floor32::surface_1 and Floor::color_at, lane for lane the same operations
        let d = r.dir * hit.t;
        let p = r.origin + d;
        let e = (r.origin.abs() + d.abs()) * f32x8::splat(gamma32(3));
        let (zero, one) = (f32x8::ZERO, f32x8::splat(1.0));
        let up = r.dir.z.gt(zero);
        let point = Vec3x8::new(p.x, p.y, f32x8::splat(floor.z));
        let normal = Vec3x8::new(zero, zero, up.select(-one, one));
        let white = checker_white(p.x, p.y, self.base);
        let c = white.select(one, zero);
        let m = &self.floor;
        let g = Gathered {
            point,
            normal,
            flipped: on_floor & up,
            err: Vec3x8::new(e.x, e.y, zero),
            color: Vec3x8::new(c, c, c),
            ka: f32x8::splat(m.ka),
            kd: f32x8::splat(m.kd),
            ks: f32x8::splat(m.ks),
            kr: f32x8::splat(m.kr),
            shine: f32x8::splat(m.shine),
        };
        if others.none() {
            return g;
        }
        let o = self.gather_lanes(r, hit, others);
        let v = |a: Vec3x8, b: Vec3x8| Vec3x8::select(on_floor, a, b);
        let f = |a: f32x8, b: f32x8| on_floor.select(a, b);
        Gathered {
            point: v(g.point, o.point),
            normal: v(g.normal, o.normal),
            flipped: g.flipped | o.flipped,
            err: v(g.err, o.err),
            color: v(g.color, o.color),
            ka: f(g.ka, o.ka),
            kd: f(g.kd, o.kd),
            ks: f(g.ks, o.ks),
            kr: f(g.kr, o.kr),
            shine: f(g.shine, o.shine),
        }
    }

    /// [`PacketRenderer::gather`] for lanes off the floor: lanes that share a primitive
    /// (most of a coherent packet) take its surface in SIMD ([`PrimSet::surface_x8`]), a
    /// lone lane its own ([`PrimSet::surface_1`]); the material is read per lane.
    fn gather_lanes(&self, r: &RayPacket8, hit: &HitPacket8, lanes: Mask8) -> Gathered {
        let mut point = [Vec3::ZERO; 8];
        let mut normal = [Vec3::Z; 8];
        let mut err = [Vec3::ZERO; 8];
        let mut color = [Vec3::ZERO; 8];
        let mut k = [[0.0f32; 8]; 5];
        let mut simd: Option<(Mask8, Surface8)> = None;
        let (t, u, v) = (hit.t.as_array(), hit.u.as_array(), hit.v.as_array());
        let codes = hit.prim.as_array();
        let mut bits = lanes.bits();
        while bits != 0 {
            let code = codes[bits.trailing_zeros() as usize];
            let mut same = 0;
            for (i, &c) in codes.iter().enumerate() {
                same |= ((c == code) as u32) << i;
            }
            same &= bits;
            bits &= !same;
            let surface = if same.count_ones() > 1 {
                self.bvh.prims.surface_x8(code, r, hit.t, hit.u, hit.v)
            } else {
                None
            };
            let mut group = same;
            if let Some(s) = surface {
                let m = Mask8::from_bits(same);
                simd = Some(match simd {
                    None => (m, s),
                    Some((old, o)) => (
                        old | m,
                        Surface8 {
                            point: Vec3x8::select(m, s.point, o.point),
                            normal: Vec3x8::select(m, s.normal, o.normal),
                            err: Vec3x8::select(m, s.err, o.err),
                        },
                    ),
                });
            }
            // one primitive, one material (the floor's colour is per point)
            let on_floor = split_code(code).0 == PrimKind::Floor;
            let m = if on_floor {
                &self.floor
            } else {
                &self.materials[self.bvh.prims.object(code) as usize]
            };
            while group != 0 {
                let i = group.trailing_zeros() as usize;
                group &= group - 1;
                if surface.is_none() {
                    let ray = Ray1 {
                        origin: r.origin.lane(i),
                        dir: r.dir.lane(i),
                        ..Ray1::new(Vec3::ZERO, Vec3::Z)
                    };
                    let s = self.bvh.prims.surface_1(code, &ray, t[i], u[i], v[i]);
                    (point[i], normal[i], err[i]) = (s.point, s.normal, s.err);
                }
                color[i] = if on_floor {
                    // (floor lanes never take the SIMD surface: point[i] is set)
                    let w = point[i].as_dvec3() + self.base;
                    Floor::color_at(w.x, w.y).as_vec3()
                } else {
                    m.color
                };
                for (kk, val) in k.iter_mut().zip([m.ka, m.kd, m.ks, m.kr, m.shine]) {
                    kk[i] = val;
                }
            }
        }
        let mut s = Surface8 {
            point: Vec3x8::from_lanes(&point),
            normal: Vec3x8::from_lanes(&normal),
            err: Vec3x8::from_lanes(&err),
        };
        if let Some((m, o)) = simd {
            s = if m.bits() == lanes.bits() {
                o
            } else {
                Surface8 {
                    point: Vec3x8::select(m, o.point, s.point),
                    normal: Vec3x8::select(m, o.normal, s.normal),
                    err: Vec3x8::select(m, o.err, s.err),
                }
            };
        }
        // every normal is turned to face the incoming ray
        let flipped = lanes & s.normal.dot(r.dir).gt(f32x8::ZERO);
        Gathered {
            point: s.point,
            normal: Vec3x8::select(flipped, -s.normal, s.normal),
            flipped,
            err: s.err,
            color: Vec3x8::from_lanes(&color),
            ka: f32x8::new(k[0]),
            kd: f32x8::new(k[1]),
            ks: f32x8::new(k[2]),
            kr: f32x8::new(k[3]),
            shine: f32x8::new(k[4]),
        }
    }

    /// Camera packets: floor lanes whose f32 hit lies near a tile line (within
    /// [`TILE_TRIGGER`] f32 ulps of |o| + t) take their tile from the
    /// hit recomputed in f64 from the frame's f64 pixel grid, as the reference
    /// computes it ([`Floor::color_at_within`]). Cameras with integer, axis-aligned
    /// geometry put whole rows of pixel rays exactly on tile lines, where the f32
    /// rounding of the direction (1e-5 at the floor) picked either tile: 77 % of such
    /// pixels were wrong (found by an independent renderer, checked in 60-digit
    /// arithmetic). Snapping the f32 point itself instead (4× its error bound)
    /// moved near-ties 1e-5 from a line onto the wrong tile. Lanes at (x + k % 4,
    /// y + k / 4) of `pixel`.
    #[inline]
    fn camera_tiles(
        &self,
        ray: &RayPacket8,
        hit: &HitPacket8,
        lanes: Mask8,
        grid: &PixelGrid,
        pixel: [u32; 2],
        g: &mut Gathered,
    ) {
        let code = i32x8::splat(prim_code(PrimKind::Floor, 0));
        let on_floor = lanes & Mask8(wide::bytemuck::cast(hit.prim.simd_eq(code)));
        if on_floor.none() {
            return;
        }
        // the rounding of the f32 hit: of o + t·d, and of d itself (relative to
        // |d| = 1, so also along a coordinate the ray hardly moves in)
        let o = ray
            .origin
            .x
            .abs()
            .max(ray.origin.y.abs())
            .max(ray.origin.z.abs());
        let eps = f32x8::splat(f32::EPSILON);
        let tol = f32x8::splat(TILE_TRIGGER) * eps * (o + hit.t);
        // distance to the nearest tile line, in f32 (world = frame + base), with the
        // rounding of this very test as slack: a wider net only costs a recomputation
        let tile = f32x8::splat(Floor::TILE as f32);
        let near = |v: f32x8, b: f64| {
            let u = v + f32x8::splat(b as f32);
            let r = u - (u / tile).round() * tile;
            let slack = f32x8::splat(8.0) * eps * (u.abs() + f32x8::splat(b.abs() as f32));
            r.abs().le(tol + slack)
        };
        let near = on_floor & (near(g.point.x, self.base.x) | near(g.point.y, self.base.y));
        if near.any() {
            self.camera_tiles_f64(near, grid, pixel, g);
        }
    }

    /// The lanes `near` of [`PacketRenderer::camera_tiles`], recomputed in f64.
    #[cold]
    fn camera_tiles_f64(&self, near: Mask8, grid: &PixelGrid, pixel: [u32; 2], g: &mut Gathered) {
        let mut color = [g.color.x, g.color.y, g.color.z].map(|v| v.to_array());
        for k in 0..8 {
            if !near.lane(k) {
                continue;
            }
            // the reference's camera ray, floor hit and colour
            let (i, j) = (pixel[0] + k as u32 % 4, pixel[1] + k as u32 / 4);
            let ray = Ray::new(grid.eye, grid.direction(i as f64, j as f64));
            let Some(t) = floor::intersect_ref(&ray, f64::INFINITY) else {
                continue;
            };
            let c = floor::color_ref(&ray, t).as_vec3();
            for (ch, v) in color.iter_mut().zip(c.to_array()) {
                ch[k] = v;
            }
        }
        g.color = Vec3x8::new(
            f32x8::new(color[0]),
            f32x8::new(color[1]),
            f32x8::new(color[2]),
        );
    }

    /// Ambient plus, per light, Phong diffuse and specular where the light is inside
    /// its cone, in front of the surface and unshadowed.
    fn phong<const ANY_HIT: bool, const EPS: bool>(
        &self,
        g: &Gathered,
        view: Vec3x8,
        lanes: Mask8,
        stats: &mut RenderStats,
        steps: &mut Steps,
    ) -> Vec3x8 {
        let zero = f32x8::ZERO;
        let mut out = g.color * g.ka;
        let n = g.normal;
        // A few lights' shadow packets are set up before any is traced: their square
        // roots and divisions then overlap instead of each waiting behind the previous
        // light's (branchy) traversal.
        for lights in self.lights.chunks(SHADOW_BATCH) {
            let mut rays = [None; SHADOW_BATCH];
            for (ray, light) in rays.iter_mut().zip(lights) {
                *ray = self.shadow_ray::<EPS>(light, g, lanes, stats);
            }
            for (ray, light) in rays.iter().zip(lights) {
                let Some(s) = ray else { continue };
                let blocked = if ANY_HIT {
                    self.occluded(&s.ray, s.m_ray, s.len, steps)
                } else {
                    self.occluded_closest(&s.ray, s.m_ray, s.len, steps)
                };
                let lit = s.m.and_not(blocked);
                if lit.none() {
                    continue;
                }
                let r = n * (f32x8::splat(2.0) * s.n_dot_l) - s.l;
                let lc = Vec3x8::splat(light.color);
                let diffuse = g.kd * s.n_dot_l;
                let rv = r.dot(view).max(zero);
                // x^0 = 1 and 0^s = 0 (s > 0), as f64::powf
                let pow = match self.whole_shine {
                    Some(bits) => pow_whole(rv, g.shine, bits),
                    None => rv.powf_simd(g.shine),
                };
                let spec = rv
                    .gt(zero)
                    .select(pow, g.shine.eq8(zero).select(f32x8::splat(1.0), zero));
                let spec = g.shine.eq8(zero).select(f32x8::splat(1.0), spec);
                let w = diffuse + g.ks * spec;
                let add = (lc * g.color) * w;
                out = out + Vec3x8::select(lit, add, Vec3x8::ZERO);
            }
        }
        out
    }

    /// The shadow packet towards `light` from the lanes it can light (inside its cone,
    /// in front of the surface); `None` if there are none.
    #[inline(always)]
    fn shadow_ray<const EPS: bool>(
        &self,
        light: &Light32,
        g: &Gathered,
        lanes: Mask8,
        stats: &mut RenderStats,
    ) -> Option<ShadowRay> {
        let zero = f32x8::ZERO;
        let (p, n) = (g.point, g.normal);
        let lp = Vec3x8::splat(light.position);
        let mut m = lanes;
        // spotlight only: skip lanes outside the cone (hard edge)
        if let Some(cone) = &light.cone {
            stats.cone_tests += m.count() as u64;
            m = m & cone.contains(p, lp);
            // (most shading points of a narrow spotlight's scene lie outside it)
            if m.none() {
                return None;
            }
        }
        let to_light = lp - p;
        let dist = to_light.length();
        m = m & dist.gt(zero);
        let l = to_light * (f32x8::splat(1.0) / dist);
        let n_dot_l = n.dot(l);
        m = m & n_dot_l.gt(zero);
        if m.none() {
            return None;
        }
        // shadow: anything on the segment between the surface and the light
        let origin = self.leave::<EPS>(p, g.err, n, l);
        let seg = lp - origin;
        let len = seg.length();
        let m_ray = m & len.gt(zero);
        stats.shadow_rays += m.count() as u64;
        Some(ShadowRay {
            m,
            l,
            n_dot_l,
            ray: RayPacket8::new(origin, seg * (f32x8::splat(1.0) / len), m_ray),
            len,
            m_ray,
        })
    }

    /// The object this renderer traces that is smallest against its distance, for the
    /// warning where f32 loses it ([`super::precision`]).
    pub fn smallest_detail(&self) -> Option<super::precision::Detail> {
        super::precision::smallest_detail(&self.bvh.prims)
    }

    /// The colours seen along a packet of camera rays (traced at level 1), each
    /// channel in [0, 1]; lanes outside `active` are black. Should a ray meet glass,
    /// lane k takes the wavelengths of pixel (k % 4, k / 4).
    pub fn trace(
        &self,
        camera: &RayPacket8,
        active: Mask8,
        stats: &mut RenderStats,
        steps: &mut Steps,
    ) -> Vec3x8 {
        self.trace_with(camera, active, [0, 0], &mut Vec::new(), stats, steps)
    }

    /// [`PacketRenderer::trace`] for the 4 × 2 pixels whose top-left is `pixel` (their
    /// wavelengths, should they meet glass), with a reusable buffer for the mirror
    /// chain (one allocation per band instead of one per packet: malloc/free took 7 %
    /// of a 1-thread render of the given scene under perf).
    pub fn trace_with(
        &self,
        camera: &RayPacket8,
        active: Mask8,
        pixel: [u32; 2],
        chain: &mut Chain,
        stats: &mut RenderStats,
        steps: &mut Steps,
    ) -> Vec3x8 {
        crate::with_packet_knobs!(
            self,
            trace_knobs(camera, active, pixel, None, chain, stats, steps)
        )
    }

    /// [`PacketRenderer::trace_with`] with the knobs as constants: `ANY_HIT` must be
    /// `self.shadow_any_hit`, `EPS` `self.offset_epsilon.is_some()` and `GLASS`
    /// `self.has_glass()` (a frame loop picks the instance once, with
    /// [`crate::with_packet_knobs`]). `grid`: the frame's f64 pixel grid, on which the
    /// lanes are the pixels at `pixel` (their floor hits near tile lines are
    /// recomputed from it, [`PacketRenderer::camera_tiles`]).
    // (the packet, its lanes, where they are in the frame, and the thread's scratch)
    #[allow(clippy::too_many_arguments)]
    pub fn trace_knobs<const ANY_HIT: bool, const EPS: bool, const GLASS: bool>(
        &self,
        camera: &RayPacket8,
        active: Mask8,
        pixel: [u32; 2],
        grid: Option<&PixelGrid>,
        chain: &mut Chain,
        stats: &mut RenderStats,
        steps: &mut Steps,
    ) -> Vec3x8 {
        debug_assert_eq!(
            (ANY_HIT, EPS, GLASS),
            (
                self.shadow_any_hit,
                self.offset_epsilon.is_some(),
                self.has_glass()
            )
        );
        let path = PathState::camera(pixel, grid.copied());
        self.trace_path::<ANY_HIT, EPS, GLASS>(camera, active, &path, chain, stats, steps)
    }

    /// The colours along a packet traced from `path.level` on: the mirror chain in a
    /// loop, per-level clamping folded back from the deepest level. In glass scenes a
    /// glass lane's heavier branch goes on in the loop (an RGB lane's reflection,
    /// weighted per channel; a monochromatic lane's heavier ray) and [`glass`] traces the
    /// others one level deeper, nested.
    fn trace_path<const ANY_HIT: bool, const EPS: bool, const GLASS: bool>(
        &self,
        camera: &RayPacket8,
        active: Mask8,
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
            let hit = self.closest(ray, active, steps);
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
            }
            let mut local = self.phong::<ANY_HIT, EPS>(&g, -ray.dir, lanes, stats, steps);
            let mut kr = g.kr;
            // glass lanes' per-channel weight of the next level (RGB lanes)
            let mut tint: Option<Vec3x8> = None;
            // glass lanes that go on in this loop: their direction and whether they
            // were refracted (monochromatic lanes follow their heavier branch here)
            let mut turn: Option<(Mask8, Vec3x8, Mask8)> = None;
            if GLASS {
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
                            let (side, w) =
                                self.split_rgb::<ANY_HIT, EPS>(ray, &g, &gh, &here, stats, steps);
                            local = local + side;
                            kr = glass.select(w.x.max(w.y).max(w.z), kr);
                            tint = Some(Vec3x8::select(glass, w, Vec3x8::new(kr, kr, kr)));
                        } else {
                            let m =
                                self.split_mono::<ANY_HIT, EPS>(ray, &g, &gh, &here, stats, steps);
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
            let o = self.leave::<EPS>(g.point, g.err, n, d);
            bounced = RayPacket8::new(o, d, next);
            ray = &bounced;
            active = next;
            stats.reflection_rays += next.and_not(refracted).count() as u64;
            stats.refraction_rays += refracted.count() as u64;
            level += 1;
            if GLASS {
                weight *= kr;
            }
        }
        let (zero, one) = (f32x8::ZERO, f32x8::splat(1.0));
        let clamp = |v: f32x8| v.max(zero).min(one);
        chain
            .iter()
            .rev()
            .fold(Vec3x8::ZERO, |deeper, &(local, kr, lanes)| {
                let c = local + deeper * kr;
                let c = Vec3x8::new(clamp(c.x), clamp(c.y), clamp(c.z));
                Vec3x8::select(lanes, c, Vec3x8::ZERO)
            })
    }

    /// Renders a frame: 4 × 2 pixel packets of camera rays through pixel centres. The
    /// knobs (`shadow_any_hit`, `offset_epsilon`) and the scene's glass pick one
    /// compiled instance here, once per frame.
    pub fn render(&self, settings: &RenderSettings) -> Rendered {
        crate::with_packet_knobs!(self, render_knobs(settings))
    }

    fn render_knobs<const ANY_HIT: bool, const EPS: bool, const GLASS: bool>(
        &self,
        settings: &RenderSettings,
    ) -> Rendered {
        let grid = settings.camera.pixel_grid(settings.width, settings.height);
        let camera = CameraPackets::new(&grid, self.base);
        let width = settings.width as usize;
        let height = settings.height as usize;
        render_bands(settings, BAND_ROWS, |first_row, pixels| {
            let mut stats = RenderStats::default();
            let mut steps = Steps::default();
            let mut chain = Vec::new();
            let rows = pixels.len() / width;
            for py in (0..rows).step_by(2) {
                for px in (0..width).step_by(4) {
                    let row = first_row as usize + py;
                    let bits = CameraPackets::lanes(px, py, width, rows, row, height);
                    let full = bits == 0xff;
                    let active = Mask8::from_bits(bits);
                    let ray = camera.packet(px, row, active);
                    let pixel = [px as u32, row as u32];
                    let c = self.trace_knobs::<ANY_HIT, EPS, GLASS>(
                        &ray,
                        active,
                        pixel,
                        Some(&grid),
                        &mut chain,
                        &mut stats,
                        &mut steps,
                    );
                    stats.primary_rays += active.count() as u64;
                    // channels in [0, 1]: rounded half away from zero (`round`),
                    // then converted in SIMD, exactly (NaN → 0, as `as u8`)
                    let q = |v: f32x8| (v * f32x8::splat(255.0)).round().round_int().to_array();
                    let (r, g, b) = (q(c.x), q(c.y), q(c.z));
                    let rgb = |lane: usize| [r[lane] as u8, g[lane] as u8, b[lane] as u8];
                    if full {
                        for row in 0..2 {
                            let at = (py + row) * width + px;
                            let k = 4 * row;
                            pixels[at..at + 4].copy_from_slice(&[
                                rgb(k),
                                rgb(k + 1),
                                rgb(k + 2),
                                rgb(k + 3),
                            ]);
                        }
                    } else {
                        for lane in 0..8 {
                            if bits >> lane & 1 == 1 {
                                let (x, y) = (px + lane % 4, py + lane / 4);
                                pixels[y * width + x] = rgb(lane);
                            }
                        }
                    }
                }
            }
            stats.quadric_tests += steps.quadrics;
            stats
        })
    }
}

/// The camera packets of a frame: 4 × 2 pixels through their centres on the frame's
/// pixel grid, in the renderer's f32 frame (the plain and the supersampled frame loop).
pub(crate) struct CameraPackets {
    eye: Vec3,
    top_left: Vec3,
    du: Vec3,
    dv: Vec3,
}

impl CameraPackets {
    /// The packets of `grid` in the frame centred on `base`.
    pub(crate) fn new(grid: &PixelGrid, base: DVec3) -> CameraPackets {
        CameraPackets {
            eye: (grid.eye - base).as_vec3(),
            top_left: (grid.top_left - grid.eye).as_vec3(),
            du: grid.du.as_vec3(),
            dv: grid.dv.as_vec3(),
        }
    }

    /// The lane bits of the packet at column `x`, row `y` of a band of `rows` rows and
    /// `width` columns whose row `y` is the image's row `image_row` (of `height`): the
    /// lanes on pixels of both.
    #[inline]
    pub(crate) fn lanes(
        x: usize,
        y: usize,
        width: usize,
        rows: usize,
        image_row: usize,
        height: usize,
    ) -> u32 {
        let inside = |lane: usize| {
            let (dx, dy) = (lane % 4, lane / 4);
            x + dx < width && y + dy < rows && image_row + dy < height
        };
        if inside(7) {
            0xff
        } else {
            (0..8).filter(|&l| inside(l)).fold(0, |b, l| b | 1 << l)
        }
    }

    /// The packet whose lane 0 is the pixel at column `x` of image row `row`.
    #[inline]
    pub(crate) fn packet(&self, x: usize, row: usize, active: Mask8) -> RayPacket8 {
        let lane_x = f32x8::new([0.0, 1.0, 2.0, 3.0, 0.0, 1.0, 2.0, 3.0]);
        let lane_y = f32x8::new([0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0]);
        let i = lane_x + f32x8::splat(x as f32);
        let j = lane_y + f32x8::splat(row as f32);
        let p =
            Vec3x8::splat(self.top_left) + Vec3x8::splat(self.du) * i + Vec3x8::splat(self.dv) * j;
        let d = p * (f32x8::splat(1.0) / p.length());
        RayPacket8::new(Vec3x8::splat(self.eye), d, active)
    }
}

/// `x^e` per lane by repeated squaring, for exponents `e` that are whole numbers
/// below 2^`bits`: `bits` multiplies and selects, where `powf` takes a logarithm and
/// an exponential.
#[inline(always)]
fn pow_whole(x: f32x8, e: f32x8, bits: u32) -> f32x8 {
    let (mut acc, mut sq, mut e) = (f32x8::splat(1.0), x, e);
    for k in 0..bits {
        if k > 0 {
            sq = sq * sq;
        }
        let half = (e * f32x8::splat(0.5)).floor();
        acc = e.gt(half + half).select(acc * sq, acc);
        e = half;
    }
    acc
}

/// Lanes at (x, y) (frame coordinates, `base` the frame's origin) on a white tile:
/// [`Floor::color_at`] on four lanes at a time, in f64: the same tile indices, whose
/// parity is taken exactly while they are below 2^53 (every point of the floor).
fn checker_white(x: f32x8, y: f32x8, base: DVec3) -> Mask8 {
    let (x, y) = (x.to_array(), y.to_array());
    let tile = |v: [f32; 4], b: f64| {
        let w = f64x4::new(v.map(|c| c as f64)) + f64x4::splat(b);
        ((w + f64x4::splat(Floor::HALF_WIDTH)) / f64x4::splat(Floor::TILE)).floor()
    };
    let mut bits = 0;
    for h in 0..2 {
        let quad = |a: &[f32; 8]| [a[4 * h], a[4 * h + 1], a[4 * h + 2], a[4 * h + 3]];
        // i + j is an exact integer: tiles of the finite floor are a few hundred
        let s = tile(quad(&x), base.x) + tile(quad(&y), base.y);
        let odd = s - f64x4::splat(2.0) * (s * f64x4::splat(0.5)).floor();
        bits |= odd.simd_eq(f64x4::ZERO).to_bitmask() << (4 * h);
    }
    Mask8::from_bits(bits)
}

/// Renders a frame on the packet path (builds the BVH centred on the camera first).
pub fn render(scene: &Scene, settings: &RenderSettings) -> Rendered {
    let start = std::time::Instant::now();
    let renderer = PacketRenderer::new(scene, settings.camera.eye);
    let mut out = renderer.render(settings);
    out.stats.elapsed = start.elapsed();
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::reference;

    #[test]
    fn checker_lanes_match_color_at_at_tile_edges_and_off_origin() {
        // points on, just beside and between tile edges, in frames far from the origin
        let mut seed = 7u64;
        let mut rnd = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 40) as f64 / (1u64 << 24) as f64
        };
        for base in [
            DVec3::ZERO,
            DVec3::new(123.25, -77.5, 9.0),
            DVec3::new(-480.0, 499.0, 0.0),
        ] {
            for _ in 0..200 {
                let mut xs = [0.0f32; 8];
                let mut ys = [0.0f32; 8];
                for k in 0..8 {
                    let edge = |r: f64| (r * 50.0).floor() * 20.0 - 500.0;
                    let (x, y) = if k % 2 == 0 {
                        (edge(rnd()), edge(rnd()) + (rnd() - 0.5) * 1e-3)
                    } else {
                        (rnd() * 1000.0 - 500.0, rnd() * 1000.0 - 500.0)
                    };
                    xs[k] = (x - base.x) as f32;
                    ys[k] = (y - base.y) as f32;
                }
                let white = checker_white(f32x8::new(xs), f32x8::new(ys), base);
                for k in 0..8 {
                    let c = Floor::color_at(xs[k] as f64 + base.x, ys[k] as f64 + base.y);
                    assert_eq!(
                        white.lane(k),
                        c == DVec3::ONE,
                        "({}, {}) + {base}",
                        xs[k],
                        ys[k]
                    );
                }
            }
        }
    }

    #[test]
    fn simd_gather_equals_the_per_lane_surfaces() {
        // packets mixing floor, shared-primitive, lone and missing lanes, in a frame off
        // the origin
        let scene = Scene::given();
        let base = DVec3::new(100.0, 100.0, 50.0);
        let r = PacketRenderer::new(&scene, base);
        let mut seed = 11u64;
        let mut rnd = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 40) as f32 / (1u64 << 24) as f32 - 0.5
        };
        let (mut floor_lanes, mut other_lanes, mut mixed) = (0, 0, 0);
        for packet in 0..4000 {
            let spread = if packet % 2 == 0 { 0.05 } else { 2.0 };
            let aim = Vec3::new(-1.0 + rnd() * 0.6, -1.0 + rnd() * 0.6, -0.3 + rnd() * 0.6);
            let d: [Vec3; 8] = std::array::from_fn(|_| {
                (aim + Vec3::new(rnd(), rnd(), rnd()) * spread).normalize()
            });
            let ray = RayPacket8::from_lanes(&[Vec3::ZERO; 8], &d);
            let hit = r.closest(&ray, Mask8::ALL, &mut Steps::default());
            let lanes = hit.hit_mask();
            let g = r.gather(&ray, &hit, lanes);
            let (t, u, v) = (hit.t.to_array(), hit.u.to_array(), hit.v.to_array());
            let (mut on_floor, mut off_floor) = (false, false);
            for i in (0..8).filter(|&i| lanes.lane(i)) {
                let code = hit.prim_lane(i);
                let s = r.bvh.prims.surface_1(code, &ray.ray(i), t[i], u[i], v[i]);
                let flip = s.normal.dot(d[i]) > 0.0;
                let (m, c) = if split_code(code).0 == PrimKind::Floor {
                    on_floor = true;
                    floor_lanes += 1;
                    let w = s.point.as_dvec3() + base;
                    (&r.floor, Floor::color_at(w.x, w.y).as_vec3())
                } else {
                    off_floor = true;
                    other_lanes += 1;
                    let m = &r.materials[r.bvh.prims.object(code) as usize];
                    (m, m.color)
                };
                let bits = |w: Vec3| w.to_array().map(f32::to_bits);
                assert_eq!(bits(g.point.lane(i)), bits(s.point), "point, lane {i}");
                let n = if flip { -s.normal } else { s.normal };
                assert_eq!(bits(g.normal.lane(i)), bits(n), "normal, lane {i}");
                assert_eq!(g.flipped.lane(i), flip, "flipped, lane {i}");
                assert_eq!(bits(g.err.lane(i)), bits(s.err), "error bound, lane {i}");
                assert_eq!(g.color.lane(i), c, "colour, lane {i}");
                let k = [g.ka, g.kd, g.ks, g.kr, g.shine].map(|k| k.to_array()[i]);
                assert_eq!(k, [m.ka, m.kd, m.ks, m.kr, m.shine], "material, lane {i}");
            }
            assert!(
                !g.flipped.and_not(lanes).any(),
                "flipped outside the hit lanes"
            );
            mixed += (on_floor && off_floor) as u32;
        }
        assert!(floor_lanes > 1000 && other_lanes > 1000 && mixed > 100);
    }

    #[test]
    fn whole_powers_by_squaring_match_powf() {
        let x = f32x8::new([0.0, 1e-3, 0.1, 0.5, 0.7, 0.9, 0.999, 1.0]);
        for e in [0u32, 1, 2, 3, 5, 10, 15, 16, 100, 255] {
            let bits = u32::BITS - e.leading_zeros();
            let got = pow_whole(x, f32x8::splat(e as f32), bits).to_array();
            for (g, xv) in got.iter().zip(x.to_array()) {
                // relative, down to where f32 goes subnormal
                let want = (xv as f64).powi(e as i32);
                let tol = want.max(f32::MIN_POSITIVE as f64) * 1e-5;
                assert!(
                    (*g as f64 - want).abs() <= tol,
                    "{xv}^{e}: {g} against {want}"
                );
            }
        }
        // lanes with different exponents
        let e = f32x8::new([0.0, 1.0, 2.0, 3.0, 4.0, 7.0, 8.0, 9.0]);
        let got = pow_whole(f32x8::splat(0.5), e, 4).to_array();
        for (g, k) in got.iter().zip(e.to_array()) {
            assert_eq!(*g, 0.5f32.powi(k as i32));
        }
    }

    #[test]
    fn given_scene_matches_reference_closely() {
        let scene = Scene::given();
        let mut settings = RenderSettings::for_scene(&scene);
        settings.width = 200;
        settings.height = 200;
        let a = reference::render(&scene, &settings).image;
        let b = render(&scene, &settings).image;
        let off: usize = a
            .pixels
            .iter()
            .zip(&b.pixels)
            .filter(|(p, q)| (0..3).any(|c| p[c].abs_diff(q[c]) > 2))
            .count();
        let exact = a
            .pixels
            .iter()
            .zip(&b.pixels)
            .filter(|(p, q)| p == q)
            .count();
        let sum: u64 = b
            .pixels
            .iter()
            .map(|p| p[0] as u64 + p[1] as u64 + p[2] as u64)
            .sum();
        eprintln!(
            "off by > 2: {off} of {}, exact {exact}, sum {sum}",
            a.pixels.len()
        );
        assert!(sum > 0);
        assert!(
            off * 100 <= a.pixels.len(),
            "{off} pixels off by more than 2/255"
        );
    }
}
