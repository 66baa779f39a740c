//! Lanes: the SIMD vector types the fast path's kernels are written over, once for
//! every width, and the instruction set chosen at run time.
//!
//! - [`Lanes`]: N f32 lanes with their mask ([`LaneMask`]) and i32 lanes ([`IntLanes`]).
//!   Implemented for `wide::f32x8` (8 lanes, the build's own instructions: AVX2 + FMA
//!   at the default target, SSE2 at the baseline one) and for [`w16::F16`] (16 lanes
//!   over AVX-512).
//! - [`Isa`]: which compiled kernels a process runs: `avx2` (8 lanes) or `avx512` (16
//!   lanes, the kernels compiled with AVX-512 enabled), detected once at start,
//!   forced with `--isa` or `OCTARAY_ISA`.
//!
//! Every operation is the IEEE operation of the scalar code, lane by lane, with no
//! fused multiply-add: a kernel written over `L: Lanes` returns bit for bit the same
//! per lane at 8 and 16 lanes (`tests/lanes.rs` checks the walks built on them ray by
//! ray).

pub mod isa;
pub mod packet;
pub(crate) mod w16;
mod w8;

use std::fmt::Debug;
use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

pub use isa::Isa;

/// A lane mask: a set of lanes.
pub trait LaneMask:
    Copy + Debug + Send + Sync + BitAnd<Output = Self> + BitOr<Output = Self> + Not<Output = Self>
{
    /// Every lane.
    const ALL: Self;
    /// No lane.
    const NONE: Self;
    /// Lanes i with bit i of `bits` set (bits beyond the width ignored).
    fn from_bits(bits: u32) -> Self;
    /// Bit i set for lane i.
    fn bits(self) -> u32;
    #[inline(always)]
    fn any(self) -> bool {
        self.bits() != 0
    }
    #[inline(always)]
    fn none(self) -> bool {
        self.bits() == 0
    }
    #[inline(always)]
    fn count(self) -> u32 {
        self.bits().count_ones()
    }
    #[inline(always)]
    fn lane(self, i: usize) -> bool {
        self.bits() >> i & 1 == 1
    }
    /// Lanes of `self` not in `o`.
    fn and_not(self, o: Self) -> Self;
}

/// N lanes of i32 (primitive codes of packet hits).
pub trait IntLanes: Copy + Debug + Send + Sync {
    type Mask: LaneMask;
    /// The lanes as an array, `[i32; N]`.
    type Array: Copy + AsRef<[i32]> + AsMut<[i32]>;
    fn splat(v: i32) -> Self;
    fn from_array(a: Self::Array) -> Self;
    fn to_array(self) -> Self::Array;
    /// `t` in the lanes of `m`, `f` elsewhere.
    fn select(m: Self::Mask, t: Self, f: Self) -> Self;
    /// Lanes `>= 0`.
    fn non_negative(self) -> Self::Mask;
    #[inline(always)]
    fn lane(self, i: usize) -> i32 {
        self.to_array().as_ref()[i]
    }
}

/// N lanes of f32. The comparisons are ordered (NaN compares false); `fast_min` and
/// `fast_max` are the instructions' (the second operand when either is NaN), `min` and
/// `max` keep `self` when `o` is NaN (as `wide`'s).
pub trait Lanes:
    Copy
    + Debug
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    type Mask: LaneMask;
    type Int: IntLanes<Mask = Self::Mask>;
    /// The lanes as an array, `[f32; N]`.
    type Array: Copy + Debug + AsRef<[f32]> + AsMut<[f32]>;

    fn splat(v: f32) -> Self;
    fn from_array(a: Self::Array) -> Self;
    fn to_array(self) -> Self::Array;
    /// Lane `i`.
    #[inline(always)]
    fn lane(self, i: usize) -> f32 {
        self.to_array().as_ref()[i]
    }
    #[inline(always)]
    fn zero() -> Self {
        Self::splat(0.0)
    }

    fn abs(self) -> Self;
    fn fast_min(self, o: Self) -> Self;
    fn fast_max(self, o: Self) -> Self;
    fn min(self, o: Self) -> Self;
    fn max(self, o: Self) -> Self;
    /// `self` with its sign flipped in the lanes where `s` has its sign bit set
    /// (`self ^ (s & -0.0)`).
    fn xor_sign(self, s: Self) -> Self;

    fn lt(self, o: Self) -> Self::Mask;
    fn le(self, o: Self) -> Self::Mask;
    fn gt(self, o: Self) -> Self::Mask;
    fn ge(self, o: Self) -> Self::Mask;
    fn eq(self, o: Self) -> Self::Mask;
    /// Lanes whose sign bit is set (−0 and negative NaNs included).
    fn sign_negative(self) -> Self::Mask;

    /// `t` in the lanes of `m`, `f` elsewhere.
    fn select(m: Self::Mask, t: Self, f: Self) -> Self;
    /// `neg` where the sign bit of `d` is set (−0 included), `pos` elsewhere.
    #[inline(always)]
    fn select_by_sign(d: Self, neg: Self, pos: Self) -> Self {
        Self::select(d.sign_negative(), neg, pos)
    }

    /// The least lane (no lane NaN).
    fn reduce_min(self) -> f32;
    /// The largest lane (no lane NaN).
    fn reduce_max(self) -> f32;
}
