//! Packets of rays at any width, as the kernels written over [`Lanes`] read them, and
//! the 16-lane packet of the `avx512` kernels.
//!
//! [`RayLanes`] holds what [`RayPacket8`] holds (origins, directions, 1/d under the slab
//! rule, the watertight test's permutation and shear) in lanes of `L`. The 16-lane
//! [`RayPacket16`] is made of two [`RayPacket8`]s, each built by `RayPacket8::new`, so a
//! lane holds bit for bit what the 8-lane packet holds for that ray; the halves stay
//! beside the 16 lanes for the kernels that have only an 8-lane form (spheres and
//! clipped quadrics).
//!
//! No closure (nor `map`, which takes one) touches a 16-lane value: a closure is
//! compiled on its own, without the AVX-512 of the function it sits in, and would call
//! each 16-lane operation instead of inlining it. Functions marked
//! `#[inline(always)]` do the same work.
//!
//! [`RayPacket8`]: crate::math::packet::RayPacket8

use super::{LaneMask, Lanes};

/// A packet's rays in lanes of `L` (fields as [`crate::math::packet::RayPacket8`]'s).
#[derive(Clone, Copy, Debug)]
pub struct RayLanes<L: Lanes> {
    pub origin: [L; 3],
    pub dir: [L; 3],
    pub inv_dir: [L; 3],
    /// Lanes whose largest |dir| component is x (kz = 0), resp. y (kz = 1); else z.
    pub kz_x: L::Mask,
    pub kz_y: L::Mask,
    /// `−d[kx]·s, −d[ky]·s, s` with `s = 1/d[kz]`.
    pub shear: [L; 3],
    /// The kz of every lane when they all share it (0, 1, 2), else 3.
    pub kz_all: u32,
}

impl<L: Lanes> RayLanes<L> {
    /// `v` per lane in the watertight test's frame, `(v[kx], v[ky], v[kz])`, as
    /// `RayPacket8::permute`.
    #[inline(always)]
    pub fn permute(&self, v: [L; 3]) -> [L; 3] {
        // kz = 0: (y, z, x); kz = 1: (z, x, y); kz = 2: (x, y, z)
        match self.kz_all {
            0 => return [v[1], v[2], v[0]],
            1 => return [v[2], v[0], v[1]],
            2 => return v,
            _ => {}
        }
        let (kx, ky) = (self.kz_x, self.kz_y);
        [
            L::select(kx, v[1], L::select(ky, v[2], v[0])),
            L::select(kx, v[2], L::select(ky, v[0], v[1])),
            L::select(kx, v[0], L::select(ky, v[1], v[2])),
        ]
    }
}

impl RayLanes<wide::f32x8> {
    /// The lanes of an 8-ray packet, field for field.
    #[inline(always)]
    pub fn of(r: &crate::math::packet::RayPacket8) -> Self {
        let a = |v: crate::math::packet::Vec3x8| [v.x, v.y, v.z];
        RayLanes {
            origin: a(r.origin),
            dir: a(r.dir),
            inv_dir: a(r.inv_dir),
            kz_x: r.kz_x,
            kz_y: r.kz_y,
            shear: a(r.shear),
            kz_all: r.kz_all,
        }
    }
}

/// What packet kernels write, in lanes of `L` (fields as
/// [`crate::math::packet::HitPacket8`]'s): distance, the hit primitive (−1: none) and
/// two barycentric coordinates.
#[derive(Clone, Copy, Debug)]
pub struct HitLanes<L: Lanes> {
    pub t: L,
    pub prim: L::Int,
    pub u: L,
    pub v: L,
}

/// `a − b` per axis.
#[inline(always)]
pub fn sub3<L: Lanes>(a: [L; 3], b: [L; 3]) -> [L; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// The dot product in `Vec3x8::dot`'s order (plain products, no FMA).
#[inline(always)]
pub fn dot3<L: Lanes>(a: [L; 3], b: [L; 3]) -> L {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The cross product in `Vec3x8::cross`'s order.
#[inline(always)]
pub fn cross3<L: Lanes>(a: [L; 3], b: [L; 3]) -> [L; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The largest lane of `v` in `m` (−∞ when none). No NaN lane in `m`.
#[inline(always)]
pub fn max_in<L: Lanes>(v: L, m: L::Mask) -> f32 {
    L::select(m, v, L::splat(f32::NEG_INFINITY)).reduce_max()
}

/// The least lane of `v` in `m` (+∞ when none). No NaN lane in `m`.
#[inline(always)]
pub fn min_in<L: Lanes>(v: L, m: L::Mask) -> f32 {
    L::select(m, v, L::splat(f32::INFINITY)).reduce_min()
}

/// Whether every lane of `m` holds `s` in `v`.
#[inline(always)]
pub fn all_eq<L: Lanes>(v: L, s: f32, m: L::Mask) -> bool {
    m.and_not(v.eq(L::splat(s))).none()
}

/// Whether every lane of `m` holds the bits of `s` in `v` (no NaN in `m`): [`all_eq`],
/// with −0 and +0 told apart.
#[inline(always)]
pub fn all_same<L: Lanes>(v: L, s: f32, m: L::Mask) -> bool {
    let sign = if s.is_sign_negative() { -1.0 } else { 1.0 };
    all_eq(v, s, m) && all_eq(L::select_by_sign(v, L::splat(-1.0), L::splat(1.0)), sign, m)
}

#[cfg(target_arch = "x86_64")]
pub(crate) use x16::{HitPacket16, RayPacket16};

#[cfg(target_arch = "x86_64")]
mod x16 {
    use super::{HitLanes, RayLanes};
    use crate::math::packet::{HitPacket8, Mask8, RayPacket8, Vec3x8};
    use crate::simd::LaneMask;
    use crate::simd::w16::{F16, I16, M16};

    /// Sixteen rays: two [`RayPacket8`]s (lanes 0–7 and 8–15) and their lanes as one.
    /// Made only inside the `avx512` kernels (see [`F16`]).
    #[derive(Clone, Copy, Debug)]
    pub struct RayPacket16 {
        pub lanes: RayLanes<F16>,
        pub halves: [RayPacket8; 2],
    }

    #[inline(always)]
    fn cat3(a: Vec3x8, b: Vec3x8) -> [F16; 3] {
        let cat = F16::from_halves;
        [cat(a.x, b.x), cat(a.y, b.y), cat(a.z, b.z)]
    }

    /// Lanes 0–7 from `a`, 8–15 from `b`.
    #[inline(always)]
    pub fn cat_mask(a: Mask8, b: Mask8) -> M16 {
        M16::from_bits(a.bits() | b.bits() << 8)
    }

    /// The lanes of `m` in the half `h` (0: lanes 0–7, 1: lanes 8–15).
    #[inline(always)]
    pub fn half_mask(m: M16, h: usize) -> Mask8 {
        Mask8::from_bits(m.bits() >> (8 * h) & 0xff)
    }

    impl RayPacket16 {
        /// The packet of the two halves, each made by `RayPacket8::new`.
        #[inline(always)]
        pub fn new(halves: [RayPacket8; 2]) -> RayPacket16 {
            let [a, b] = &halves;
            RayPacket16 {
                lanes: RayLanes {
                    origin: cat3(a.origin, b.origin),
                    dir: cat3(a.dir, b.dir),
                    inv_dir: cat3(a.inv_dir, b.inv_dir),
                    kz_x: cat_mask(a.kz_x, b.kz_x),
                    kz_y: cat_mask(a.kz_y, b.kz_y),
                    shear: cat3(a.shear, b.shear),
                    kz_all: if a.kz_all == b.kz_all { a.kz_all } else { 3 },
                },
                halves,
            }
        }
    }

    /// What 16-lane kernels write.
    pub type HitPacket16 = HitLanes<F16>;

    impl HitPacket16 {
        #[inline(always)]
        pub fn from_halves(h: [HitPacket8; 2]) -> HitPacket16 {
            let [a, b] = h;
            HitPacket16 {
                t: F16::from_halves(a.t, b.t),
                prim: I16::from_halves(a.prim, b.prim),
                u: F16::from_halves(a.u, b.u),
                v: F16::from_halves(a.v, b.v),
            }
        }

        #[inline(always)]
        pub fn halves(&self) -> [HitPacket8; 2] {
            let ([t0, t1], [u0, u1], [v0, v1]) =
                (self.t.halves(), self.u.halves(), self.v.halves());
            let [p0, p1] = self.prim.halves();
            [
                HitPacket8 {
                    t: t0,
                    prim: p0,
                    u: u0,
                    v: v0,
                },
                HitPacket8 {
                    t: t1,
                    prim: p1,
                    u: u1,
                    v: v1,
                },
            ]
        }
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use x16::{cat_mask, half_mask};
