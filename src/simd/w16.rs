//! 16 lanes over AVX-512: [`F16`] (`__m512`), [`M16`] (a `__mmask16`) and [`I16`]
//! (`__m512i`).
//!
//! Private to the crate. Only the `avx512` kernels use them, inlined into functions
//! compiled with `#[target_feature(enable = "avx2,fma,avx512f,avx512vl,avx512bw,avx512dq")]`
//! and called only with an `isa::Avx512` token, with everything below
//! `#[inline(always)]`, so that each method here becomes the one instruction it names. The operations are those of `wide::f32x8` lane for lane
//! (the same comparison predicates, the same `min`/`max` operand order, negation by
//! the sign bit), so a kernel gives the same bits per lane at both widths.

#[cfg(target_arch = "x86_64")]
pub use imp::{F16, I16, M16};

#[cfg(target_arch = "x86_64")]
mod imp {
    use std::arch::x86_64::*;
    use std::mem::transmute;
    use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

    use wide::{f32x8, i32x8};

    use crate::simd::{IntLanes, LaneMask, Lanes};

    /// 16 f32 lanes, used only in code reached through an `isa::Avx512` token (module
    /// doc).
    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub struct F16(__m512);

    /// 16 i32 lanes (as [`F16`]).
    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub struct I16(__m512i);

    /// A mask of 16 lanes, bit i for lane i (a `__mmask16`).
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    #[repr(transparent)]
    pub struct M16(pub u16);

    // SAFETY (every `unsafe` block below): the intrinsics need AVX-512 F and DQ (the
    // float xor/and/or) at run time. These types are private to the crate, and every
    // use of them is inlined into a function compiled with AVX-512 that is called
    // only with an `Avx512` token, which only a CPU that has the features yields
    // (`isa.rs`). The loads and stores read or write exactly the 64 bytes of an
    // `[f32; 16]` or `[i32; 16]` owned by the caller, unaligned. The transmutes
    // reinterpret 32 bytes of eight f32 or i32 lanes (`wide`'s `f32x8`, `i32x8`) as
    // `__m256`/`__m256i` and back: the same size, and every bit pattern a valid value.

    // `wide`'s eight-lane types are 32 bytes of lanes in order (one `__m256`, or two
    // `__m128` halves on a target without AVX): what the transmutes below rely on
    const _: () = assert!(std::mem::size_of::<f32x8>() == 32 && std::mem::size_of::<i32x8>() == 32);

    /// 256-bit halves of the 16-lane types, joined and split in registers (through an
    /// array, the 512-bit load of two 256-bit stores waited for both to retire).
    impl F16 {
        /// Lanes 0–7 from `lo`, 8–15 from `hi`.
        #[inline(always)]
        pub fn from_halves(lo: f32x8, hi: f32x8) -> F16 {
            let (lo, hi) = unsafe {
                (
                    transmute::<f32x8, __m256>(lo),
                    transmute::<f32x8, __m256>(hi),
                )
            };
            unsafe { F16(_mm512_insertf32x8::<1>(_mm512_castps256_ps512(lo), hi)) }
        }

        /// Lanes 0–7 and 8–15.
        #[inline(always)]
        pub fn halves(self) -> [f32x8; 2] {
            let (lo, hi) = unsafe {
                (
                    _mm512_castps512_ps256(self.0),
                    _mm512_extractf32x8_ps::<1>(self.0),
                )
            };
            unsafe {
                [
                    transmute::<__m256, f32x8>(lo),
                    transmute::<__m256, f32x8>(hi),
                ]
            }
        }
    }

    impl I16 {
        /// Lanes 0–7 from `lo`, 8–15 from `hi` (as [`F16::from_halves`]).
        #[inline(always)]
        pub fn from_halves(lo: i32x8, hi: i32x8) -> I16 {
            let (lo, hi) = unsafe {
                (
                    transmute::<i32x8, __m256i>(lo),
                    transmute::<i32x8, __m256i>(hi),
                )
            };
            unsafe { I16(_mm512_inserti32x8::<1>(_mm512_castsi256_si512(lo), hi)) }
        }

        /// Lanes 0–7 and 8–15.
        #[inline(always)]
        pub fn halves(self) -> [i32x8; 2] {
            let (lo, hi) = unsafe {
                (
                    _mm512_castsi512_si256(self.0),
                    _mm512_extracti32x8_epi32::<1>(self.0),
                )
            };
            unsafe {
                [
                    transmute::<__m256i, i32x8>(lo),
                    transmute::<__m256i, i32x8>(hi),
                ]
            }
        }
    }

    impl LaneMask for M16 {
        const ALL: M16 = M16(u16::MAX);
        const NONE: M16 = M16(0);
        #[inline(always)]
        fn from_bits(bits: u32) -> M16 {
            M16(bits as u16)
        }
        #[inline(always)]
        fn bits(self) -> u32 {
            self.0 as u32
        }
        #[inline(always)]
        fn and_not(self, o: M16) -> M16 {
            M16(self.0 & !o.0)
        }
    }

    impl BitAnd for M16 {
        type Output = M16;
        #[inline(always)]
        fn bitand(self, o: M16) -> M16 {
            M16(self.0 & o.0)
        }
    }
    impl BitOr for M16 {
        type Output = M16;
        #[inline(always)]
        fn bitor(self, o: M16) -> M16 {
            M16(self.0 | o.0)
        }
    }
    impl Not for M16 {
        type Output = M16;
        #[inline(always)]
        fn not(self) -> M16 {
            M16(!self.0)
        }
    }

    impl IntLanes for I16 {
        type Mask = M16;
        type Array = [i32; 16];
        #[inline(always)]
        fn splat(v: i32) -> I16 {
            unsafe { I16(_mm512_set1_epi32(v)) }
        }
        #[inline(always)]
        fn from_array(a: [i32; 16]) -> I16 {
            unsafe { I16(_mm512_loadu_si512(a.as_ptr().cast())) }
        }
        #[inline(always)]
        fn to_array(self) -> [i32; 16] {
            let mut a = [0i32; 16];
            unsafe { _mm512_storeu_si512(a.as_mut_ptr().cast(), self.0) };
            a
        }
        #[inline(always)]
        fn select(m: M16, t: I16, f: I16) -> I16 {
            unsafe { I16(_mm512_mask_blend_epi32(m.0, f.0, t.0)) }
        }
        #[inline(always)]
        fn non_negative(self) -> M16 {
            unsafe { M16(_mm512_cmpge_epi32_mask(self.0, _mm512_setzero_si512())) }
        }
    }

    macro_rules! binop {
        ($tr:ident, $f:ident, $intr:ident) => {
            impl $tr for F16 {
                type Output = F16;
                #[inline(always)]
                fn $f(self, o: F16) -> F16 {
                    unsafe { F16($intr(self.0, o.0)) }
                }
            }
        };
    }
    binop!(Add, add, _mm512_add_ps);
    binop!(Sub, sub, _mm512_sub_ps);
    binop!(Mul, mul, _mm512_mul_ps);
    binop!(Div, div, _mm512_div_ps);

    impl Neg for F16 {
        type Output = F16;
        #[inline(always)]
        fn neg(self) -> F16 {
            // the sign bit flipped, as wide's f32x8 (−(+0) = −0)
            unsafe { F16(_mm512_xor_ps(self.0, _mm512_set1_ps(-0.0))) }
        }
    }

    impl F16 {
        #[inline(always)]
        fn cmp<const P: i32>(self, o: F16) -> M16 {
            unsafe { M16(_mm512_cmp_ps_mask::<P>(self.0, o.0)) }
        }
    }

    impl Lanes for F16 {
        type Mask = M16;
        type Int = I16;
        type Array = [f32; 16];

        #[inline(always)]
        fn splat(v: f32) -> F16 {
            unsafe { F16(_mm512_set1_ps(v)) }
        }
        #[inline(always)]
        fn from_array(a: [f32; 16]) -> F16 {
            unsafe { F16(_mm512_loadu_ps(a.as_ptr())) }
        }
        #[inline(always)]
        fn to_array(self) -> [f32; 16] {
            let mut a = [0f32; 16];
            unsafe { _mm512_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }
        #[inline(always)]
        fn zero() -> F16 {
            unsafe { F16(_mm512_setzero_ps()) }
        }
        #[inline(always)]
        fn abs(self) -> F16 {
            unsafe { F16(_mm512_andnot_ps(_mm512_set1_ps(-0.0), self.0)) }
        }
        #[inline(always)]
        fn fast_min(self, o: F16) -> F16 {
            unsafe { F16(_mm512_min_ps(self.0, o.0)) }
        }
        #[inline(always)]
        fn fast_max(self, o: F16) -> F16 {
            unsafe { F16(_mm512_max_ps(self.0, o.0)) }
        }
        #[inline(always)]
        fn min(self, o: F16) -> F16 {
            // `o` NaN: `self` (wide's rule; the instruction alone gives `o`)
            let nan = o.cmp::<_CMP_UNORD_Q>(o);
            F16::select(nan, self, self.fast_min(o))
        }
        #[inline(always)]
        fn max(self, o: F16) -> F16 {
            let nan = o.cmp::<_CMP_UNORD_Q>(o);
            F16::select(nan, self, self.fast_max(o))
        }
        #[inline(always)]
        fn xor_sign(self, s: F16) -> F16 {
            unsafe {
                F16(_mm512_xor_ps(
                    self.0,
                    _mm512_and_ps(s.0, _mm512_set1_ps(-0.0)),
                ))
            }
        }
        #[inline(always)]
        fn lt(self, o: F16) -> M16 {
            self.cmp::<_CMP_LT_OQ>(o)
        }
        #[inline(always)]
        fn le(self, o: F16) -> M16 {
            self.cmp::<_CMP_LE_OQ>(o)
        }
        #[inline(always)]
        fn gt(self, o: F16) -> M16 {
            self.cmp::<_CMP_GT_OQ>(o)
        }
        #[inline(always)]
        fn ge(self, o: F16) -> M16 {
            self.cmp::<_CMP_GE_OQ>(o)
        }
        #[inline(always)]
        fn eq(self, o: F16) -> M16 {
            self.cmp::<_CMP_EQ_OQ>(o)
        }
        #[inline(always)]
        fn sign_negative(self) -> M16 {
            unsafe { M16(_mm512_movepi32_mask(_mm512_castps_si512(self.0))) }
        }
        #[inline(always)]
        fn select(m: M16, t: F16, f: F16) -> F16 {
            unsafe { F16(_mm512_mask_blend_ps(m.0, f.0, t.0)) }
        }
        #[inline(always)]
        fn reduce_min(self) -> f32 {
            unsafe { _mm512_reduce_min_ps(self.0) }
        }
        #[inline(always)]
        fn reduce_max(self) -> f32 {
            unsafe { _mm512_reduce_max_ps(self.0) }
        }
    }
}
