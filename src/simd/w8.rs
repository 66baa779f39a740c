//! 8 lanes: `wide::f32x8` with [`Mask8`] and `wide::i32x8`, the build's own
//! instructions (one 256-bit instruction each at the default x86-64-v3 target; two
//! SSE2 ones at the baseline target).

use wide::{f32x8, i32x8};

use super::{IntLanes, LaneMask, Lanes};
use crate::math::packet::Mask8;

impl LaneMask for Mask8 {
    const ALL: Mask8 = Mask8::ALL;
    const NONE: Mask8 = Mask8::NONE;
    #[inline(always)]
    fn from_bits(bits: u32) -> Mask8 {
        Mask8::from_bits(bits)
    }
    #[inline(always)]
    fn bits(self) -> u32 {
        Mask8::bits(self)
    }
    #[inline(always)]
    fn any(self) -> bool {
        Mask8::any(self)
    }
    #[inline(always)]
    fn none(self) -> bool {
        Mask8::none(self)
    }
    #[inline(always)]
    fn and_not(self, o: Mask8) -> Mask8 {
        Mask8::and_not(self, o)
    }
}

impl IntLanes for i32x8 {
    type Mask = Mask8;
    type Array = [i32; 8];
    #[inline(always)]
    fn splat(v: i32) -> i32x8 {
        i32x8::splat(v)
    }
    #[inline(always)]
    fn from_array(a: [i32; 8]) -> i32x8 {
        i32x8::new(a)
    }
    #[inline(always)]
    fn to_array(self) -> [i32; 8] {
        i32x8::to_array(self)
    }
    #[inline(always)]
    fn select(m: Mask8, t: i32x8, f: i32x8) -> i32x8 {
        m.select_i32(t, f)
    }
    #[inline(always)]
    fn non_negative(self) -> Mask8 {
        Mask8(wide::bytemuck::cast(self.simd_ge(i32x8::ZERO)))
    }
}

impl Lanes for f32x8 {
    type Mask = Mask8;
    type Int = i32x8;
    type Array = [f32; 8];

    #[inline(always)]
    fn splat(v: f32) -> f32x8 {
        f32x8::splat(v)
    }
    #[inline(always)]
    fn from_array(a: [f32; 8]) -> f32x8 {
        f32x8::new(a)
    }
    #[inline(always)]
    fn to_array(self) -> [f32; 8] {
        f32x8::to_array(self)
    }
    #[inline(always)]
    fn lane(self, i: usize) -> f32 {
        self.as_array()[i]
    }
    #[inline(always)]
    fn zero() -> f32x8 {
        f32x8::ZERO
    }
    #[inline(always)]
    fn abs(self) -> f32x8 {
        f32x8::abs(self)
    }
    #[inline(always)]
    fn fast_min(self, o: f32x8) -> f32x8 {
        f32x8::fast_min(self, o)
    }
    #[inline(always)]
    fn fast_max(self, o: f32x8) -> f32x8 {
        f32x8::fast_max(self, o)
    }
    #[inline(always)]
    fn min(self, o: f32x8) -> f32x8 {
        f32x8::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: f32x8) -> f32x8 {
        f32x8::max(self, o)
    }
    #[inline(always)]
    fn xor_sign(self, s: f32x8) -> f32x8 {
        self ^ (s & f32x8::splat(-0.0))
    }
    #[inline(always)]
    fn lt(self, o: f32x8) -> Mask8 {
        Mask8(self.simd_lt(o))
    }
    #[inline(always)]
    fn le(self, o: f32x8) -> Mask8 {
        Mask8(self.simd_le(o))
    }
    #[inline(always)]
    fn gt(self, o: f32x8) -> Mask8 {
        Mask8(self.simd_gt(o))
    }
    #[inline(always)]
    fn ge(self, o: f32x8) -> Mask8 {
        Mask8(self.simd_ge(o))
    }
    #[inline(always)]
    fn eq(self, o: f32x8) -> Mask8 {
        Mask8(self.simd_eq(o))
    }
    #[inline(always)]
    fn sign_negative(self) -> Mask8 {
        Mask8(self.is_sign_negative())
    }
    #[inline(always)]
    fn select(m: Mask8, t: f32x8, f: f32x8) -> f32x8 {
        m.select(t, f)
    }
    #[inline(always)]
    fn select_by_sign(d: f32x8, neg: f32x8, pos: f32x8) -> f32x8 {
        // one `vblendvps`, which reads only the sign bits of its mask
        #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
        {
            use safe_arch::{blend_varying_m256, m256};
            let m = |v: f32x8| m256(wide::bytemuck::cast(v));
            wide::bytemuck::cast(blend_varying_m256(m(pos), m(neg), m(d)).0)
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
        {
            Mask8(d.is_sign_negative()).select(neg, pos)
        }
    }
    #[inline(always)]
    fn reduce_min(self) -> f32 {
        // a butterfly: three swaps and three minima
        let a = self.to_array();
        let v = self.fast_min(f32x8::new([a[4], a[5], a[6], a[7], a[0], a[1], a[2], a[3]]));
        let a = v.to_array();
        let v = v.fast_min(f32x8::new([a[2], a[3], a[0], a[1], a[6], a[7], a[4], a[5]]));
        let a = v.to_array();
        v.fast_min(f32x8::new([a[1], a[0], a[3], a[2], a[5], a[4], a[7], a[6]]))
            .as_array()[0]
    }
    #[inline(always)]
    fn reduce_max(self) -> f32 {
        let a = self.to_array();
        let v = self.fast_max(f32x8::new([a[4], a[5], a[6], a[7], a[0], a[1], a[2], a[3]]));
        let a = v.to_array();
        let v = v.fast_max(f32x8::new([a[2], a[3], a[0], a[1], a[6], a[7], a[4], a[5]]));
        let a = v.to_array();
        v.fast_max(f32x8::new([a[1], a[0], a[3], a[2], a[5], a[4], a[7], a[6]]))
            .as_array()[0]
    }
}
