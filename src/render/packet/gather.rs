//! Gathering: the surface, colour and material of each lane's winning hit, computed once
//! per level for the lanes that hit.

use glam::Vec3;
use wide::{f32x8, i32x8};

use super::PacketRenderer;
use crate::geometry::floor;
use crate::geometry::triangle::surface_lanes;
use crate::geometry::{PrimKind, Surface8, prim_code, split_code};
use crate::math::Ray;
use crate::math::packet::{Cmp8, HitPacket8, Mask8, Ray1, RayPacket8, Vec3x8};
use crate::render::frame::Samples;
use crate::scene::Floor;

/// The per-lane surface data a level's shading needs, gathered for the winners.
pub(super) struct Gathered {
    pub point: Vec3x8,
    /// Facing the incoming ray.
    pub normal: Vec3x8,
    /// Lanes whose geometric normal was turned round to face the ray (glass needs
    /// the outward one).
    pub flipped: Mask8,
    pub err: Vec3x8,
    pub color: Vec3x8,
    pub ka: f32x8,
    pub kd: f32x8,
    pub ks: f32x8,
    pub kr: f32x8,
    pub shine: f32x8,
}

/// [`PacketRenderer::camera_tiles`] recomputes a camera ray's floor hit in f64 when
/// the f32 point lies within this many f32 ulps of |o| + t of a tile line.
const TILE_TRIGGER: f32 = 16.0;

impl PacketRenderer {
    /// Surface, colour and material of each hit lane: floor lanes in SIMD (on most
    /// scenes the floor takes most lanes), the others lane by lane.
    pub(super) fn gather(&self, r: &RayPacket8, hit: &HitPacket8, lanes: Mask8) -> Gathered {
        let Some(floor) = self.bvh.prims.floor else {
            return self.gather_lanes(r, hit, lanes);
        };
        let code = i32x8::splat(prim_code(PrimKind::Floor, 0));
        let on_floor = lanes & Mask8(wide::bytemuck::cast(hit.prim.simd_eq(code)));
        if on_floor.none() {
            return self.gather_lanes(r, hit, lanes);
        }
        let others = lanes.and_not(on_floor);
        // the floor's surface and tile colour, lane for lane those of `surface_1` and
        // `Floor::color_at`; its normal turned to face the ray
        let s = floor.surface_x8(r, hit.t);
        let (zero, one) = (f32x8::ZERO, f32x8::splat(1.0));
        let up = r.dir.z.gt(zero);
        let normal = Vec3x8::new(zero, zero, up.select(-one, one));
        let c = floor.white_x8(s.point.x, s.point.y).select(one, zero);
        let m = &self.floor;
        let g = Gathered {
            point: s.point,
            normal,
            flipped: on_floor & up,
            err: s.err,
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

    /// [`PacketRenderer::gather`] for lanes off the floor: lanes that all hit triangles
    /// of one object take their surfaces in SIMD ([`PacketRenderer::gather_triangles`]);
    /// otherwise lanes that share a primitive (most of a coherent packet) take its surface
    /// in SIMD ([`PrimSet::surface_x8`]), a lone lane its own ([`PrimSet::surface_1`]),
    /// and the material is read per lane.
    ///
    /// [`PrimSet::surface_x8`]: crate::geometry::PrimSet::surface_x8
    /// [`PrimSet::surface_1`]: crate::geometry::PrimSet::surface_1
    fn gather_lanes(&self, r: &RayPacket8, hit: &HitPacket8, lanes: Mask8) -> Gathered {
        if let Some(g) = self.gather_triangles(r, hit, lanes) {
            return g;
        }
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
            let on_floor = split_code(code).is_some_and(|(k, _)| k == PrimKind::Floor);
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
        let k = k.map(f32x8::new);
        facing(r, lanes, s, Vec3x8::from_lanes(&color), k)
    }

    /// [`PacketRenderer::gather_lanes`] when every lane of `lanes` hit a triangle of one
    /// object (a mesh, whose lanes mostly hit different triangles): the triangles'
    /// corners gathered into lanes and their surfaces computed at once
    /// ([`surface_lanes`], lane for lane `surface_1`), the lanes outside `lanes` as
    /// `gather_lanes` leaves them. `None` for any other packet.
    fn gather_triangles(&self, r: &RayPacket8, hit: &HitPacket8, lanes: Mask8) -> Option<Gathered> {
        let prims = &self.bvh.prims;
        let codes = hit.prim.as_array();
        // lanes outside `lanes` keep zero corners: their surfaces are replaced below
        let mut corners = [[Vec3::ZERO; 8]; 3];
        let mut object = None;
        let mut rest = lanes.bits();
        while rest != 0 {
            let i = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            let (k, of) = prims.triangle_and_object(codes[i])?;
            if *object.get_or_insert(of) != of {
                return None;
            }
            for (c, v) in corners.iter_mut().zip(prims.triangle(k).v) {
                c[i] = v;
            }
        }
        let object = object?;
        let s = surface_lanes(corners.map(|c| Vec3x8::from_lanes(&c)), hit.u, hit.v);
        let m = &self.materials[object as usize];
        let on = |v: f32| lanes.select(f32x8::splat(v), f32x8::ZERO);
        let v = |a: Vec3x8, b: Vec3x8| Vec3x8::select(lanes, a, b);
        let s = Surface8 {
            point: v(s.point, Vec3x8::ZERO),
            normal: v(s.normal, Vec3x8::splat(Vec3::Z)),
            err: v(s.err, Vec3x8::ZERO),
        };
        let color = Vec3x8::new(on(m.color.x), on(m.color.y), on(m.color.z));
        let k = [m.ka, m.kd, m.ks, m.kr, m.shine].map(on);
        Some(facing(r, lanes, s, color, k))
    }

    /// Camera packets: floor lanes whose f32 hit lies near a tile line (within
    /// [`TILE_TRIGGER`] f32 ulps of |o| + t) take their tile from the
    /// hit recomputed in f64 from the frame's f64 pixel grid, as the reference
    /// computes it ([`Floor::color_at_within`]). Cameras with integer, axis-aligned
    /// geometry put whole rows of pixel rays exactly on tile lines, where the f32
    /// rounding of the direction picks either tile; snapping the f32 point itself
    /// would move near-ties onto the wrong tile. Lanes at (x + k % 4, y + k / 4) of
    /// `pixel` on the sample grid.
    #[inline]
    pub(super) fn camera_tiles(
        &self,
        ray: &RayPacket8,
        hit: &HitPacket8,
        lanes: Mask8,
        grid: &Samples,
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
    fn camera_tiles_f64(&self, near: Mask8, samples: &Samples, pixel: [u32; 2], g: &mut Gathered) {
        let mut color = [g.color.x, g.color.y, g.color.z].map(|v| v.to_array());
        for k in 0..8 {
            if !near.lane(k) {
                continue;
            }
            // the reference's camera ray, floor hit and colour
            let (i, j) = (pixel[0] + k as u32 % 4, pixel[1] + k as u32 / 4);
            let ray = Ray::new(samples.grid.eye, samples.direction(i, j));
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
}

/// A level's [`Gathered`] from the lanes' surfaces, colours and material factors
/// (ka, kd, ks, kr, shine): every normal turned to face the incoming ray, the lanes of
/// `lanes` whose geometric normal was turned marked `flipped`.
#[inline]
fn facing(r: &RayPacket8, lanes: Mask8, s: Surface8, color: Vec3x8, k: [f32x8; 5]) -> Gathered {
    let flipped = lanes & s.normal.dot(r.dir).gt(f32x8::ZERO);
    let [ka, kd, ks, kr, shine] = k;
    Gathered {
        point: s.point,
        normal: Vec3x8::select(flipped, -s.normal, s.normal),
        flipped,
        err: s.err,
        color,
        ka,
        kd,
        ks,
        kr,
        shine,
    }
}
