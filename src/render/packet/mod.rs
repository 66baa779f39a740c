//! The packet path: the fast, default renderer.
//!
//! f32, eight rays at a time (`wide::f32x8`), through a binned-SAH [`Bvh`]; it computes
//! the picture of `docs/scene-format.md` exactly as the reference states it, and the
//! equivalence tests hold it to the reference per lane and per image. It never calls
//! reference code.
//!
//! - [`PacketRenderer`]: the scene in one f32 frame whose origin is set explicitly (the
//!   camera's eye, or the world origin where a mesh's f32 vertices then stay exact:
//!   [`super::prepared::frame_origin`]; f64 subtraction, then rounding), so scenes far
//!   from the world origin keep their detail; built once from immutable [`PacketOptions`].
//! - [`PacketRenderer::frames`] picks the compiled instance of the tracer for those
//!   options and the scene's glass, once per frame ([`Settings`]).
//! - `camera`: camera packets of 4 × 2 samples for the frame loop; `path`: the mirror
//!   chain of a packet, one closest-hit query per level; `gather`: the winners'
//!   surfaces; `shade`: Phong terms and shadow packets; `lights`: lights and cones in
//!   f32; [`glass`]: refraction and the caustic.
//! - Packets with few active lanes (incoherent secondary rays) go lane by lane through
//!   the single-ray traversal of the same tree (`single_ray_lanes`).

mod camera;
mod chain;
mod gather;
pub(crate) mod glass;
mod lights;
mod path;
mod shade;

use crate::simd::isa::Avx512;
use std::marker::PhantomData;
use std::ops::Deref;

use glam::DVec3;
use wide::f32x8;

use super::FrameRenderer;
use super::caustic::{CausticMap, CausticSettings};
use super::options::{PacketOptions, RayOffset, TriangleTest};
use super::{RenderSettings, Rendered};
use crate::bvh::Bvh;
use crate::geometry::PrimSet;
use crate::geometry::floor::Floor32;
use crate::geometry::moller::Moller;
use crate::geometry::triangle::{TriangleKernel, Watertight};
use crate::math::packet::{Cmp8, Vec3x8, offset_origin_x8};
use crate::scene::{Floor, Glass, Scene};
use lights::{Cone32, Light32, Mat32};

pub use chain::Chain;

/// A scene prepared for the packet path: BVH, materials and lights in one f32 frame
/// whose origin is the world point `base`, and the options it was built with.
pub struct PacketRenderer {
    pub bvh: Bvh,
    base: DVec3,
    options: PacketOptions,
    materials: Vec<Mat32>,
    floor: Mat32,
    lights: Vec<Light32>,
    recursion_level: u32,
    /// Per object, its glass if it is a prism; empty when the scene has none.
    glass: Vec<Option<Glass>>,
    /// Light bent by glass onto other surfaces; `None` without glass.
    caustics: Option<CausticMap>,
    /// Seed of the per-sample wavelengths (the caustic settings' seed).
    seed: u64,
    /// `Some(bits)` when every shininess (the floor's too) is a whole number below
    /// 2^bits ≤ 256: the specular power is then taken by squaring.
    whole_shine: Option<u32>,
}

impl PacketRenderer {
    /// Builds the BVH and tables of `scene` in a frame centred on `base` (use the
    /// camera's eye) with the default options and caustic settings.
    pub fn new(scene: &Scene, base: DVec3) -> PacketRenderer {
        Self::with_options(
            scene,
            base,
            &PacketOptions::default(),
            &CausticSettings::default(),
        )
    }

    /// [`PacketRenderer::new`] with `options`; `caustic` sets the photon count, radius
    /// and seed of the photon pass, which runs here (through this BVH) only if the
    /// scene has glass.
    pub fn with_options(
        scene: &Scene,
        base: DVec3,
        options: &PacketOptions,
        caustic: &CausticSettings,
    ) -> PacketRenderer {
        let bvh = Bvh::build(PrimSet::from_scene(scene, base));
        let rel = |p: DVec3| (p - base).as_vec3();
        // A light keeps its side of the floor plane (z = 0) in the f32 frame: rounded
        // there, one within half an ulp of the plane would land on it, light nothing
        // on the floor and shine through it.
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
            options: *options,
            materials,
            floor,
            lights: points.chain(spots).collect(),
            recursion_level: scene.recursion_level,
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
            r.caustics = r.with_tracer(PhotonPass { scene, caustic });
        }
        r
    }

    /// Traces at most `level` levels (a profile's `max_recursion`); the photon map does
    /// not depend on it.
    pub fn cap_recursion(mut self, level: u32) -> Self {
        self.recursion_level = self.recursion_level.min(level);
        self
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

    /// The options this renderer was built with.
    pub fn options(&self) -> &PacketOptions {
        &self.options
    }

    /// The object this renderer traces that is smallest against its distance, for the
    /// warning where f32 loses it ([`super::precision`]).
    pub fn smallest_detail(&self) -> Option<super::precision::Detail> {
        super::precision::smallest_detail(&self.bvh.prims)
    }

    /// The tracer of this renderer's options and scene, chosen once: the compiled
    /// instance of [`Settings`] they select.
    pub fn frames(&self) -> Box<dyn FrameRenderer + '_> {
        self.with_tracer(Frames)
    }

    /// Hands `job` the tracer of this renderer's options and scene: picks the compiled
    /// instance of [`Settings`], the one dispatch on the options.
    fn with_tracer<'r, J: TracerJob<'r>>(&'r self, job: J) -> J::Out {
        match self.options.triangle_test {
            TriangleTest::Watertight => self.with_kernel::<Watertight, J>(job),
            TriangleTest::Moller => self.with_kernel::<Moller, J>(job),
        }
    }

    fn with_kernel<'r, T: TriangleKernel, J: TracerJob<'r>>(&'r self, job: J) -> J::Out {
        match self.options.ray_offset {
            RayOffset::ErrorBound => self.with_offset::<T, _, J>(ErrorBound, job),
            RayOffset::Epsilon(e) => self.with_offset::<T, _, J>(Epsilon(e), job),
        }
    }

    fn with_offset<'r, T: TriangleKernel, O: Offset, J: TracerJob<'r>>(
        &'r self,
        offset: O,
        job: J,
    ) -> J::Out {
        let r = self;
        // (trees too small for the frustum walk would only pay for the pairing)
        let x16 = (self.options.isa.avx512_kernels()).filter(|_| self.bvh.frustum_spread() >= 0.0);
        match (self.options.shadow_any_hit, self.has_glass()) {
            (true, false) => job.run(Tracer::<Fixed<true, false, O, T>> { r, offset, x16 }),
            (false, false) => job.run(Tracer::<Fixed<false, false, O, T>> { r, offset, x16 }),
            (true, true) => job.run(Tracer::<Fixed<true, true, O, T>> { r, offset, x16 }),
            (false, true) => job.run(Tracer::<Fixed<false, true, O, T>> { r, offset, x16 }),
        }
    }

    /// Renders one frame of one sample per pixel.
    pub fn render(&self, settings: &RenderSettings) -> Rendered {
        self.frames().render(settings, 1)
    }
}

/// The packet path's code-path choices as types, fixed for a frame.
pub(crate) trait Settings: Send + Sync + 'static {
    /// Shadow rays stop at their first blocker (else a closest-hit query).
    const ANY_HIT: bool;
    /// The scene has glass.
    const GLASS: bool;
    /// How secondary rays leave surfaces.
    type Offset: Offset;
    /// The ray/triangle test.
    type Tri: TriangleKernel;
}

/// The [`Settings`] of one compiled instance.
pub(crate) struct Fixed<const ANY_HIT: bool, const GLASS: bool, O, T>(PhantomData<(O, T)>);

impl<const ANY_HIT: bool, const GLASS: bool, O: Offset, T: TriangleKernel> Settings
    for Fixed<ANY_HIT, GLASS, O, T>
{
    const ANY_HIT: bool = ANY_HIT;
    const GLASS: bool = GLASS;
    type Offset = O;
    type Tri = T;
}

/// Something done with the tracer of a renderer's settings
/// ([`PacketRenderer::with_tracer`]).
trait TracerJob<'r> {
    type Out;
    fn run<S: Settings>(self, tracer: Tracer<'r, S>) -> Self::Out;
}

/// Boxes the tracer for the frame loop.
struct Frames;

impl<'r> TracerJob<'r> for Frames {
    type Out = Box<dyn FrameRenderer + 'r>;
    fn run<S: Settings>(self, tracer: Tracer<'r, S>) -> Self::Out {
        Box::new(tracer)
    }
}

/// Traces the caustic photons through the renderer's BVH.
struct PhotonPass<'a> {
    scene: &'a Scene,
    caustic: &'a CausticSettings,
}

impl<'r> TracerJob<'r> for PhotonPass<'_> {
    type Out = Option<CausticMap>;
    fn run<S: Settings>(self, tracer: Tracer<'r, S>) -> Self::Out {
        CausticMap::build(self.scene, self.caustic, &tracer)
    }
}

/// How a secondary ray's origin leaves the surface it starts on.
pub(crate) trait Offset: Copy + Send + Sync + 'static {
    /// The origin of a ray leaving `p` (normal `n`, error bound `err`) along `w`.
    fn origin(&self, p: Vec3x8, err: Vec3x8, n: Vec3x8, w: Vec3x8) -> Vec3x8;
}

/// Past the hit point's error bound along the normal ([`offset_origin_x8`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct ErrorBound;

impl Offset for ErrorBound {
    #[inline(always)]
    fn origin(&self, p: Vec3x8, err: Vec3x8, n: Vec3x8, w: Vec3x8) -> Vec3x8 {
        offset_origin_x8(p, err, n, w)
    }
}

/// A fixed distance along the normal, to the side the ray leaves on.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Epsilon(f32);

impl Offset for Epsilon {
    #[inline(always)]
    fn origin(&self, p: Vec3x8, _err: Vec3x8, n: Vec3x8, w: Vec3x8) -> Vec3x8 {
        let e = f32x8::splat(self.0);
        p + n * w.dot(n).lt(f32x8::ZERO).select(-e, e)
    }
}

/// A [`PacketRenderer`] with its settings fixed as types: what traces a frame.
pub(crate) struct Tracer<'r, S: Settings> {
    r: &'r PacketRenderer,
    offset: S::Offset,
    /// Under `avx512`: camera blocks are traced in pairs, one 16-lane packet.
    x16: Option<Avx512>,
}

impl<S: Settings> Deref for Tracer<'_, S> {
    type Target = PacketRenderer;
    fn deref(&self) -> &PacketRenderer {
        self.r
    }
}

/// Renders a frame on the packet path with the default options (builds the BVH
/// centred on the camera first; `stats.elapsed` includes the build).
pub fn render(scene: &Scene, settings: &RenderSettings) -> Rendered {
    let start = std::time::Instant::now();
    let mut out = PacketRenderer::new(scene, settings.camera.eye).render(settings);
    out.stats.elapsed = start.elapsed();
    out
}
