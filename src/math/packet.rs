//! 8-wide SIMD types of the fast path (over `wide::f32x8`), and its f32 single ray.
//!
//! - [`Vec3x8`]: eight 3-vectors as structure of arrays, with glam's method names.
//! - [`Mask8`]: a lane mask (`f32x8` lanes of all ones or all zeros), narrowed after
//!   each rejection; kernels leave as soon as it is empty.
//! - [`RayPacket8`], [`HitPacket8`]: eight rays and the little a kernel writes per hit.
//! - [`Ray1`]: one f32 ray with the precomputations of the box and triangle tests.
//!
//! Slab rule (both widths): a direction component with |d| < 1e-18 is replaced by
//! ±1e-18 (its sign kept, −0 → −1e-18) for the box test only, so 1/d is finite and no
//! 0·∞ = NaN can arise; a ray lying exactly in a box face counts as inside. The far
//! bound is widened by 1 + 2γ(3) (pbrt-v4, after Ize 2013).

use std::ops::{Add, BitAnd, BitOr, Mul, Neg, Not, Sub};

use glam::{DVec3, Vec3};
use wide::{f32x8, i32x8};

/// Unit roundoff of f32.
pub const EPS_F32: f32 = f32::EPSILON * 0.5;

/// γ(n) = nε / (1 − nε) for f32: the relative error bound of n chained operations.
pub const fn gamma32(n: u32) -> f32 {
    let ne = n as f32 * EPS_F32;
    ne / (1.0 - ne)
}

/// Factor widening a box's far bound so rays through box edges are not lost.
pub const FAR_WIDEN: f32 = 1.0 + 2.0 * gamma32(3);

/// Smallest |d| used for 1/d in the slab test: 2⁻¹⁰⁰, so that 1/d (±1.3e30) times a box
/// face's gap of [`crate::math::aabb::FACE_GAP`] (2⁻⁵⁰) still passes every distance a
/// ray goes in the tree (its bounds stop at 2⁴⁴). (1/d stays finite and a product
/// with it can overflow only to ±∞: no t is NaN.)
const MIN_DIR: f32 = 7.888_609e-31;

/// 1/d with |d| clamped to at least [`MIN_DIR`], sign kept (the slab rule).
#[inline]
pub fn safe_recip(d: f32) -> f32 {
    if d.abs() < MIN_DIR {
        1.0 / MIN_DIR.copysign(d)
    } else {
        1.0 / d
    }
}

/// A lane mask: each lane all ones (true) or all zeros (false).
#[derive(Clone, Copy, Debug)]
pub struct Mask8(pub f32x8);

impl Mask8 {
    pub const ALL: Mask8 = Mask8(f32x8::new([f32::from_bits(u32::MAX); 8]));
    pub const NONE: Mask8 = Mask8(f32x8::ZERO);

    /// Lanes i with bit i of `bits` set (an and and a compare: the packet traversal
    /// rebuilds a mask from its stack on every pop).
    #[inline]
    pub fn from_bits(bits: u32) -> Mask8 {
        let lanes = i32x8::new([1, 2, 4, 8, 16, 32, 64, 128]);
        let m = (i32x8::splat(bits as i32) & lanes).simd_ge(lanes);
        Mask8(wide::bytemuck::cast(m))
    }

    #[inline]
    pub fn bits(self) -> u32 {
        self.0.to_bitmask()
    }
    #[inline]
    pub fn any(self) -> bool {
        self.0.any()
    }
    #[inline]
    pub fn none(self) -> bool {
        self.0.none()
    }
    #[inline]
    pub fn count(self) -> u32 {
        self.bits().count_ones()
    }
    #[inline]
    pub fn lane(self, i: usize) -> bool {
        self.bits() >> i & 1 == 1
    }
    /// `t` where the mask is set, else `f`.
    #[inline]
    pub fn select(self, t: f32x8, f: f32x8) -> f32x8 {
        self.0.select(t, f)
    }
    #[inline]
    pub fn select_i32(self, t: i32x8, f: i32x8) -> i32x8 {
        let m: i32x8 = wide::bytemuck::cast(self.0);
        m.select(t, f)
    }
    #[inline]
    pub fn select_vec(self, t: Vec3x8, f: Vec3x8) -> Vec3x8 {
        Vec3x8 {
            x: self.select(t.x, f.x),
            y: self.select(t.y, f.y),
            z: self.select(t.z, f.z),
        }
    }
    /// And-not: lanes of `self` not in `o`.
    #[inline]
    pub fn and_not(self, o: Mask8) -> Mask8 {
        Mask8(self.0 & !o.0)
    }
}

impl BitAnd for Mask8 {
    type Output = Mask8;
    #[inline]
    fn bitand(self, o: Mask8) -> Mask8 {
        Mask8(self.0 & o.0)
    }
}
impl BitOr for Mask8 {
    type Output = Mask8;
    #[inline]
    fn bitor(self, o: Mask8) -> Mask8 {
        Mask8(self.0 | o.0)
    }
}
impl Not for Mask8 {
    type Output = Mask8;
    #[inline]
    fn not(self) -> Mask8 {
        Mask8(!self.0)
    }
}

/// Comparisons returning [`Mask8`].
pub trait Cmp8 {
    fn lt(self, o: f32x8) -> Mask8;
    fn le(self, o: f32x8) -> Mask8;
    fn gt(self, o: f32x8) -> Mask8;
    fn ge(self, o: f32x8) -> Mask8;
    fn eq8(self, o: f32x8) -> Mask8;
}
impl Cmp8 for f32x8 {
    #[inline]
    fn lt(self, o: f32x8) -> Mask8 {
        Mask8(self.simd_lt(o))
    }
    #[inline]
    fn le(self, o: f32x8) -> Mask8 {
        Mask8(self.simd_le(o))
    }
    #[inline]
    fn gt(self, o: f32x8) -> Mask8 {
        Mask8(self.simd_gt(o))
    }
    #[inline]
    fn ge(self, o: f32x8) -> Mask8 {
        Mask8(self.simd_ge(o))
    }
    #[inline]
    fn eq8(self, o: f32x8) -> Mask8 {
        Mask8(self.simd_eq(o))
    }
}

/// Eight 3-vectors, structure of arrays.
#[derive(Clone, Copy, Debug)]
pub struct Vec3x8 {
    pub x: f32x8,
    pub y: f32x8,
    pub z: f32x8,
}

impl Vec3x8 {
    pub const ZERO: Vec3x8 = Vec3x8 {
        x: f32x8::ZERO,
        y: f32x8::ZERO,
        z: f32x8::ZERO,
    };

    #[inline]
    pub fn new(x: f32x8, y: f32x8, z: f32x8) -> Vec3x8 {
        Vec3x8 { x, y, z }
    }
    #[inline]
    pub fn splat(v: Vec3) -> Vec3x8 {
        Vec3x8 {
            x: f32x8::splat(v.x),
            y: f32x8::splat(v.y),
            z: f32x8::splat(v.z),
        }
    }
    pub fn from_lanes(v: &[Vec3; 8]) -> Vec3x8 {
        Vec3x8 {
            x: f32x8::new(v.map(|p| p.x)),
            y: f32x8::new(v.map(|p| p.y)),
            z: f32x8::new(v.map(|p| p.z)),
        }
    }
    pub fn lane(&self, i: usize) -> Vec3 {
        Vec3::new(
            self.x.as_array()[i],
            self.y.as_array()[i],
            self.z.as_array()[i],
        )
    }
    #[inline]
    pub fn dot(self, o: Vec3x8) -> f32x8 {
        // plain products, as glam's scalar dot: packet and single-ray kernels then
        // round identically (wide's fallback target has no FMA either)
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    #[inline]
    pub fn cross(self, o: Vec3x8) -> Vec3x8 {
        Vec3x8 {
            x: self.y * o.z - self.z * o.y,
            y: self.z * o.x - self.x * o.z,
            z: self.x * o.y - self.y * o.x,
        }
    }
    #[inline]
    pub fn length_squared(self) -> f32x8 {
        self.dot(self)
    }
    #[inline]
    pub fn length(self) -> f32x8 {
        self.length_squared().sqrt()
    }
    #[inline]
    pub fn abs(self) -> Vec3x8 {
        Vec3x8 {
            x: self.x.abs(),
            y: self.y.abs(),
            z: self.z.abs(),
        }
    }
    /// `mask ? t : f`, lane by lane.
    #[inline]
    pub fn select(mask: Mask8, t: Vec3x8, f: Vec3x8) -> Vec3x8 {
        mask.select_vec(t, f)
    }
    #[inline]
    pub fn min(self, o: Vec3x8) -> Vec3x8 {
        Vec3x8::new(self.x.min(o.x), self.y.min(o.y), self.z.min(o.z))
    }
    #[inline]
    pub fn max(self, o: Vec3x8) -> Vec3x8 {
        Vec3x8::new(self.x.max(o.x), self.y.max(o.y), self.z.max(o.z))
    }
}

impl Add for Vec3x8 {
    type Output = Vec3x8;
    #[inline]
    fn add(self, o: Vec3x8) -> Vec3x8 {
        Vec3x8::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl Sub for Vec3x8 {
    type Output = Vec3x8;
    #[inline]
    fn sub(self, o: Vec3x8) -> Vec3x8 {
        Vec3x8::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl Mul<f32x8> for Vec3x8 {
    type Output = Vec3x8;
    #[inline]
    fn mul(self, s: f32x8) -> Vec3x8 {
        Vec3x8::new(self.x * s, self.y * s, self.z * s)
    }
}
impl Mul<Vec3x8> for Vec3x8 {
    type Output = Vec3x8;
    #[inline]
    fn mul(self, o: Vec3x8) -> Vec3x8 {
        Vec3x8::new(self.x * o.x, self.y * o.y, self.z * o.z)
    }
}
impl Neg for Vec3x8 {
    type Output = Vec3x8;
    #[inline]
    fn neg(self) -> Vec3x8 {
        Vec3x8::new(-self.x, -self.y, -self.z)
    }
}

/// Eight rays `origin + t·dir` (unit `dir`), with the slab test's reciprocals and
/// the watertight triangle test's per-lane permutation masks and shear.
#[derive(Clone, Copy, Debug)]
pub struct RayPacket8 {
    pub origin: Vec3x8,
    pub dir: Vec3x8,
    /// 1/dir under the slab rule (module doc).
    pub inv_dir: Vec3x8,
    /// Lanes whose largest |dir| component is x (kz = 0), resp. y (kz = 1); else z.
    pub kz_x: Mask8,
    pub kz_y: Mask8,
    /// Shear of the watertight test: `−d[kx]·s, −d[ky]·s, s` with `s = 1/d[kz]`.
    pub shear: Vec3x8,
    /// The kz of every lane when they all share it (0, 1, 2), else 3: lets
    /// [`RayPacket8::permute`] move whole vectors instead of blending lane by lane.
    pub kz_all: u32,
    /// Sign bits of lane `first_lane`'s direction (bit k: `dir[k] < 0`), for ordered
    /// traversal.
    pub octant: u32,
}

impl RayPacket8 {
    /// Builds a packet. Lanes not in `active` are replaced by a copy of the first
    /// active lane, so whatever they held (NaN, zero directions) enters no test.
    /// Computes exactly what [`Ray1::new`] computes, lane by lane.
    #[inline]
    pub fn new(origin: Vec3x8, dir: Vec3x8, active: Mask8) -> RayPacket8 {
        let bits = active.bits();
        let (origin, dir) = if bits == 0xff || bits == 0 {
            (origin, dir)
        } else {
            let k = bits.trailing_zeros() as usize;
            let (o, d) = (Vec3x8::splat(origin.lane(k)), Vec3x8::splat(dir.lane(k)));
            (active.select_vec(origin, o), active.select_vec(dir, d))
        };
        let min = f32x8::splat(MIN_DIR);
        let sign = f32x8::splat(-0.0);
        let safe = |d: f32x8| {
            let small = d.abs().lt(min);
            f32x8::splat(1.0) / small.select(min | (d & sign), d)
        };
        let a = dir.abs();
        // same choice as the reference: ties go to the later axis
        let kz_x = a.x.gt(a.y) & a.x.gt(a.z);
        let kz_y = !kz_x & a.y.gt(a.z);
        let mut p = RayPacket8 {
            origin,
            dir,
            inv_dir: Vec3x8::new(safe(dir.x), safe(dir.y), safe(dir.z)),
            kz_x,
            kz_y,
            shear: Vec3x8::ZERO,
            kz_all: match (kz_x.bits(), kz_y.bits()) {
                (0xff, _) => 0,
                (0, 0xff) => 1,
                (0, 0) => 2,
                _ => 3,
            },
            octant: 0,
        };
        // inv_dir[kz] is exactly 1/d[kz] whenever |d[kz]| ≥ MIN_DIR (1/√3 or more for
        // a unit direction; only a zero direction falls below): the shear takes it
        // instead of dividing again (as Ray1::new, lane for lane)
        let d = p.permute(dir);
        let inv_z = p.permute(p.inv_dir).z;
        p.shear = Vec3x8::new(-d.x * inv_z, -d.y * inv_z, inv_z);
        let d0 = dir.lane(if bits == 0 {
            0
        } else {
            bits.trailing_zeros() as usize
        });
        p.octant = (d0.x < 0.0) as u32 | ((d0.y < 0.0) as u32) << 1 | ((d0.z < 0.0) as u32) << 2;
        p
    }

    /// Builds a packet from eight rays (all used).
    pub fn from_lanes(o: &[Vec3; 8], d: &[Vec3; 8]) -> RayPacket8 {
        RayPacket8::new(Vec3x8::from_lanes(o), Vec3x8::from_lanes(d), Mask8::ALL)
    }

    /// Lane i as a single ray.
    pub fn ray(&self, i: usize) -> Ray1 {
        Ray1::new(self.origin.lane(i), self.dir.lane(i))
    }

    /// Permutes a vector per lane into the watertight test's frame:
    /// `(v[kx], v[ky], v[kz])`.
    #[inline]
    pub fn permute(&self, v: Vec3x8) -> Vec3x8 {
        // kz = 0: (y, z, x); kz = 1: (z, x, y); kz = 2: (x, y, z)
        match self.kz_all {
            0 => return Vec3x8::new(v.y, v.z, v.x),
            1 => return Vec3x8::new(v.z, v.x, v.y),
            2 => return v,
            _ => {}
        }
        let x = self.kz_x.select(v.y, self.kz_y.select(v.z, v.x));
        let y = self.kz_x.select(v.z, self.kz_y.select(v.x, v.y));
        let z = self.kz_x.select(v.x, self.kz_y.select(v.y, v.z));
        Vec3x8::new(x, y, z)
    }
}

/// What packet kernels write: distance, the hit primitive (−1: none) and two
/// barycentric coordinates (triangles only).
#[derive(Clone, Copy, Debug)]
pub struct HitPacket8 {
    pub t: f32x8,
    pub prim: i32x8,
    pub u: f32x8,
    pub v: f32x8,
}

impl HitPacket8 {
    /// No hit yet; lanes accept hits with t below `t_max`.
    pub fn new(t_max: f32x8) -> HitPacket8 {
        HitPacket8 {
            t: t_max,
            prim: i32x8::splat(-1),
            u: f32x8::ZERO,
            v: f32x8::ZERO,
        }
    }
    pub fn hit_mask(&self) -> Mask8 {
        let m: f32x8 = wide::bytemuck::cast(self.prim.simd_ge(i32x8::ZERO));
        Mask8(m)
    }
    pub fn prim_lane(&self, i: usize) -> i32 {
        self.prim.as_array()[i]
    }
}

/// One f32 ray with the precomputations of the slab and watertight triangle tests.
#[derive(Clone, Copy, Debug)]
pub struct Ray1 {
    pub origin: Vec3,
    /// Unit length.
    pub dir: Vec3,
    /// 1/dir under the slab rule (module doc).
    pub inv_dir: Vec3,
    /// Axis of the largest |dir| component, and the two others (kx, ky) = (kz+1, kz+2) mod 3.
    pub kz: usize,
    /// `−d[kx]·s, −d[ky]·s, s` with `s = 1/d[kz]` (the watertight test's shear).
    pub shear: Vec3,
}

impl Ray1 {
    pub fn new(origin: Vec3, dir: Vec3) -> Ray1 {
        let inv_dir = Vec3::new(safe_recip(dir.x), safe_recip(dir.y), safe_recip(dir.z));
        let a = dir.abs();
        // same choice as the reference: ties go to the later axis
        // (x if it beats both, else y if it beats z, else z; as arithmetic on the
        // comparisons, not branches: incoherent rays make them a coin toss)
        let x_wins = (a.x > a.y) & (a.x > a.z);
        let kz = usize::from(!x_wins) * (2 - usize::from(a.y > a.z));
        let (kx, ky) = ((kz + 1) % 3, (kz + 2) % 3);
        // 1/d[kz] once: inv_dir's own when |d[kz]| ≥ MIN_DIR (every direction but a zero
        // one, which no caller builds); multiplies, not divisions
        let (d, inv) = (dir.to_array(), inv_dir.to_array());
        let inv_z = inv[kz];
        let shear = Vec3::new(-d[kx] * inv_z, -d[ky] * inv_z, inv_z);
        Ray1 {
            origin,
            dir,
            inv_dir,
            kz,
            shear,
        }
    }

    /// A ray from f64 data relative to `base` (the frame's origin, e.g. the camera).
    pub fn from_f64(origin: DVec3, dir: DVec3, base: DVec3) -> Ray1 {
        Ray1::new((origin - base).as_vec3(), dir.as_vec3())
    }

    #[inline]
    pub fn permute(&self, v: Vec3) -> Vec3 {
        let (kx, ky) = ((self.kz + 1) % 3, (self.kz + 2) % 3);
        Vec3::new(v[kx], v[ky], v[self.kz])
    }

    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// Moves points `p` (per-component error bound `err`) off their surfaces along unit
/// normals `n`, to the side direction `w` leaves towards, then one more ulp bound
/// (|x|·2⁻²³, at least the smallest normal) away, so rounding the sum cannot undo it.
/// The f32 twin of `math::float::offset_ray_origin`.
#[inline]
pub fn offset_origin_x8(p: Vec3x8, err: Vec3x8, n: Vec3x8, w: Vec3x8) -> Vec3x8 {
    let d = n.abs().dot(err);
    let flip = w.dot(n).lt(f32x8::ZERO);
    let s = flip.select(-d, d);
    let off = n * s;
    let step = |po: f32x8, o: f32x8| {
        let ulp = po.abs().mul_add(
            f32x8::splat(2.0 * f32::EPSILON),
            f32x8::splat(f32::MIN_POSITIVE),
        );
        let up = o.gt(f32x8::ZERO);
        let down = o.lt(f32x8::ZERO);
        po + up.select(ulp, f32x8::ZERO) - down.select(ulp, f32x8::ZERO)
    };
    let po = p + off;
    Vec3x8::new(step(po.x, off.x), step(po.y, off.y), step(po.z, off.z))
}

/// Single-ray twin of [`offset_origin_x8`].
pub fn offset_origin_1(p: Vec3, err: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let d = n.abs().dot(err);
    let off = if w.dot(n) < 0.0 { -n * d } else { n * d };
    let mut po = p + off;
    for i in 0..3 {
        let ulp = po[i].abs() * (2.0 * f32::EPSILON) + f32::MIN_POSITIVE;
        if off[i] > 0.0 {
            po[i] += ulp;
        } else if off[i] < 0.0 {
            po[i] -= ulp;
        }
    }
    po
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn masks_count_and_select() {
        let m = Mask8::from_bits(0b1010_0101);
        assert_eq!(m.bits(), 0b1010_0101);
        assert_eq!(m.count(), 4);
        assert!(m.lane(0) && !m.lane(1));
        let s = m.select(f32x8::splat(1.0), f32x8::splat(2.0));
        assert_eq!(s.to_array()[0], 1.0);
        assert_eq!(s.to_array()[1], 2.0);
        assert!(Mask8::NONE.none() && Mask8::ALL.count() == 8);
    }

    /// The ray's triangle permutation (the axis of its largest |d|) is the reference's
    /// choice, `x` only when it beats both, else `y` when it beats `z`, else `z`:
    /// ties go to the later axis, and a NaN comparison is lost, as there.
    #[test]
    fn the_largest_axis_is_the_references_choice() {
        let reference = |d: Vec3| {
            let a = d.abs();
            if a.x > a.y && a.x > a.z {
                0
            } else if a.y > a.z {
                1
            } else {
                2
            }
        };
        let values = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.0,
            f32::NAN,
            f32::INFINITY,
        ];
        let mut n = 0;
        for &x in &values {
            for &y in &values {
                for &z in &values {
                    let d = Vec3::new(x, y, z);
                    assert_eq!(Ray1::new(Vec3::ZERO, d).kz, reference(d), "d = {d:?}");
                    n += 1;
                }
            }
        }
        assert_eq!(n, 729);
    }

    #[test]
    fn safe_recip_keeps_sign_of_zero() {
        assert!(safe_recip(0.0) > 1e17);
        assert!(safe_recip(-0.0) < -1e17);
        assert_eq!(safe_recip(2.0), 0.5);
    }

    #[test]
    fn permutation_matches_single_ray() {
        let dirs = [
            Vec3::X,
            Vec3::Y,
            Vec3::Z,
            Vec3::new(-0.9, 0.1, 0.1).normalize(),
            Vec3::new(0.1, -0.9, 0.3).normalize(),
            Vec3::new(0.3, 0.3, -0.9).normalize(),
            Vec3::new(0.5, 0.5, 0.5).normalize(),
            Vec3::new(-0.0, 0.0, -1.0),
        ];
        let p = RayPacket8::from_lanes(&[Vec3::ZERO; 8], &dirs);
        let v = Vec3x8::splat(Vec3::new(1.0, 2.0, 3.0));
        let pv = p.permute(v);
        for (i, d) in dirs.iter().enumerate() {
            let r = Ray1::new(Vec3::ZERO, *d);
            assert_eq!(pv.lane(i), r.permute(Vec3::new(1.0, 2.0, 3.0)), "lane {i}");
            assert_eq!(p.shear.lane(i), r.shear);
        }
    }

    #[test]
    fn offset_moves_to_the_leaving_side() {
        let p = Vec3x8::splat(Vec3::new(1e5, 0.0, 0.0));
        let err = Vec3x8::splat(Vec3::splat(1e-3));
        let n = Vec3x8::splat(Vec3::X);
        let out = offset_origin_x8(p, err, n, Vec3x8::splat(Vec3::new(1.0, 1.0, 0.0)));
        let inn = offset_origin_x8(p, err, n, Vec3x8::splat(Vec3::NEG_X));
        assert!(out.lane(0).x > 1e5 && inn.lane(0).x < 1e5);
        assert_eq!(out.lane(0).y, 0.0);
        let o1 = offset_origin_1(
            Vec3::new(1e5, 0.0, 0.0),
            Vec3::splat(1e-3),
            Vec3::X,
            Vec3::NEG_X,
        );
        assert_eq!(o1, inn.lane(0));
    }
}
