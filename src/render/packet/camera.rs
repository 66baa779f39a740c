//! Camera packets: the packet path's side of the frame loop.

use glam::{DVec3, Vec3};
use wide::f32x8;

use super::chain::Chain;
use super::path::PathState;
use super::{Settings, Tracer};
use crate::bvh::Bvh;
use crate::bvh::Steps;
use crate::geometry::triangle::TriangleKernel;
use crate::math::packet::{HitPacket8, Mask8, RayPacket8, Vec3x8};
use crate::output::framebuffer::quantize;
use crate::render::RenderStats;
use crate::render::frame::{SampleBlock, SampleColors, SampleTracer, Samples};
use crate::scene::camera::PixelGrid;
use crate::simd::isa::Avx512;
#[cfg(target_arch = "x86_64")]
use crate::simd::packet::{HitPacket16, RayPacket16, cat_mask};

/// The camera rays of a sample grid in the renderer's f32 frame.
pub(crate) struct CameraPackets {
    eye: Vec3,
    top_left: Vec3,
    du: Vec3,
    dv: Vec3,
}

impl CameraPackets {
    /// The rays of `grid` in the frame centred on `base`.
    pub(crate) fn new(grid: &PixelGrid, base: DVec3) -> CameraPackets {
        CameraPackets {
            eye: (grid.eye - base).as_vec3(),
            top_left: (grid.top_left - grid.eye).as_vec3(),
            du: grid.du.as_vec3(),
            dv: grid.dv.as_vec3(),
        }
    }

    /// The packet of `block` of `samples`: lane k through sample (x + k % 4, y + k / 4).
    #[inline]
    pub(crate) fn packet(&self, block: SampleBlock, samples: &Samples) -> RayPacket8 {
        let lane_x = f32x8::new([0.0, 1.0, 2.0, 3.0, 0.0, 1.0, 2.0, 3.0]);
        let lane_y = f32x8::new([0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0]);
        let mut i = lane_x + f32x8::splat(block.x as f32);
        let mut j = lane_y + f32x8::splat(block.y as f32);
        if !samples.centred() {
            let at = |k: u32| samples.offset(block.x + k % 4, block.y + k / 4);
            let o: [[f64; 2]; 8] = std::array::from_fn(|k| at(k as u32));
            i += f32x8::new(o.map(|v| v[0] as f32));
            j += f32x8::new(o.map(|v| v[1] as f32));
        }
        let p =
            Vec3x8::splat(self.top_left) + Vec3x8::splat(self.du) * i + Vec3x8::splat(self.dv) * j;
        let d = p * (f32x8::splat(1.0) / p.length());
        RayPacket8::new(Vec3x8::splat(self.eye), d, Mask8::from_bits(block.bits))
    }
}

/// A block's colours, each channel in [0, 1] (lanes outside the block black).
#[derive(Clone, Copy, Debug)]
pub(crate) struct PacketColors(pub Vec3x8);

impl SampleColors for PacketColors {
    type Sum = [f32; 3];

    #[inline]
    fn rgb8(&self) -> [[u8; 3]; 8] {
        // rounded half away from zero (`round`), then converted in SIMD, exactly
        // (NaN → 0, as `as u8`)
        let q = |v: f32x8| (v * f32x8::splat(255.0)).round().round_int().to_array();
        let (r, g, b) = (q(self.0.x), q(self.0.y), q(self.0.z));
        std::array::from_fn(|k| [r[k] as u8, g[k] as u8, b[k] as u8])
    }

    #[inline]
    fn lane(&self, k: usize) -> [f32; 3] {
        let c = &self.0;
        [c.x.as_array()[k], c.y.as_array()[k], c.z.as_array()[k]]
    }

    #[inline]
    fn add(sum: [f32; 3], c: [f32; 3]) -> [f32; 3] {
        [sum[0] + c[0], sum[1] + c[1], sum[2] + c[2]]
    }

    fn resolve(sum: [f32; 3], count: u32) -> [u8; 3] {
        let inv = 1.0 / count as f32;
        sum.map(|v| quantize((v * inv) as f64))
    }

    fn linear(sum: [f32; 3], count: u32) -> DVec3 {
        DVec3::from(sum.map(|v| v as f64)) / count as f64
    }
}

/// Per band: the camera in the f32 frame and the mirror chain's buffer (one
/// allocation per band, not per packet).
#[derive(Default)]
pub(crate) struct Scratch {
    camera: Option<CameraPackets>,
    chain: Chain,
}

impl<S: Settings> SampleTracer for Tracer<'_, S> {
    type Scratch = Scratch;
    type Colors = PacketColors;

    #[inline]
    fn trace_block(
        &self,
        samples: &Samples,
        block: SampleBlock,
        scratch: &mut Scratch,
        stats: &mut RenderStats,
    ) -> PacketColors {
        let camera =
            (scratch.camera).get_or_insert_with(|| CameraPackets::new(&samples.grid, self.base));
        let ray = camera.packet(block, samples);
        self.shade_block(samples, block, &ray, None, scratch, stats)
    }

    /// Under `avx512`, the camera rays of both blocks as one 16-lane packet (each ray
    /// gets the hit the 8-lane packet gives it: the same image), then each block's
    /// path on its own.
    #[inline]
    fn trace_pair(
        &self,
        samples: &Samples,
        blocks: [SampleBlock; 2],
        scratch: &mut Scratch,
        stats: &mut RenderStats,
    ) -> [PacketColors; 2] {
        let Some(token) = self.x16 else {
            let first = self.trace_block(samples, blocks[0], scratch, stats);
            return [first, self.trace_block(samples, blocks[1], scratch, stats)];
        };
        let camera =
            (scratch.camera).get_or_insert_with(|| CameraPackets::new(&samples.grid, self.base));
        // (an array literal: `blocks.map` moved each 480-byte packet through copies)
        let rays = [
            camera.packet(blocks[0], samples),
            camera.packet(blocks[1], samples),
        ];
        let active = blocks.map(|b| Mask8::from_bits(b.bits));
        let mut steps = Steps::default();
        let hits = closest_x16::<S::Tri>(token, &self.bvh, &rays, active, &mut steps);
        stats.node_tests += steps.boxes;
        stats.quadric_tests += steps.quadrics;
        let first = self.shade_block(samples, blocks[0], &rays[0], Some(hits[0]), scratch, stats);
        let second = self.shade_block(samples, blocks[1], &rays[1], Some(hits[1]), scratch, stats);
        [first, second]
    }
}

impl<S: Settings> Tracer<'_, S> {
    /// The colours of a block's camera packet `ray` (`hit`: its closest hits, if found).
    #[inline]
    fn shade_block(
        &self,
        samples: &Samples,
        block: SampleBlock,
        ray: &RayPacket8,
        hit: Option<HitPacket8>,
        scratch: &mut Scratch,
        stats: &mut RenderStats,
    ) -> PacketColors {
        let active = Mask8::from_bits(block.bits);
        let path = PathState::camera([block.x, block.y], Some(*samples));
        let mut steps = Steps::default();
        let c = self.trace_path(
            ray,
            active,
            hit,
            &path,
            &mut scratch.chain,
            stats,
            &mut steps,
        );
        stats.quadric_tests += steps.quadrics;
        stats.node_tests += steps.boxes;
        PacketColors(c)
    }
}

/// The closest hits of two 8-ray packets traced as one of 16 lanes
/// ([`Bvh::intersect_x16`]).
#[inline]
fn closest_x16<T: TriangleKernel>(
    token: Avx512,
    bvh: &Bvh,
    rays: &[RayPacket8; 2],
    active: [Mask8; 2],
    steps: &mut Steps,
) -> [HitPacket8; 2] {
    #[cfg(target_arch = "x86_64")]
    {
        let _ = token;
        // SAFETY: `token` proves this CPU has the features `x16` is compiled with
        unsafe { x16::<T>(bvh, rays, active, steps) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (token, bvh, rays, active, steps);
        unreachable!("no AVX-512 outside x86-64")
    }
}

/// [`closest_x16`], compiled with AVX-512.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,avx512f,avx512vl,avx512bw,avx512dq")]
fn x16<T: TriangleKernel>(
    bvh: &Bvh,
    rays: &[RayPacket8; 2],
    active: [Mask8; 2],
    steps: &mut Steps,
) -> [HitPacket8; 2] {
    let p = RayPacket16::new(*rays);
    let inf = HitPacket8::new(f32x8::splat(f32::INFINITY));
    let mut hit = HitPacket16::from_halves([inf, inf]);
    bvh.intersect_x16::<T>(&p, cat_mask(active[0], active[1]), &mut hit, steps);
    hit.halves()
}
