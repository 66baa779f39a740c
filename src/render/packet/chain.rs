//! The mirror chain of a packet, in bounded memory at any recursion level.
//!
//! The spec clamps every level: a level's colour is c = clamp(local + kr·c_deeper, 0, 1),
//! folded back from the deepest hit. The chain holds at most [`CHAIN_LEVELS`] levels;
//! when it is full they are composed into one map per lane and channel, and a map of
//! the form x ↦ min(max(a + b·x, lo), hi) (b >= 0) composed with another of that form
//! is again of that form. So a chain of a million levels takes the memory of
//! [`CHAIN_LEVELS`], and one of at most [`CHAIN_LEVELS`] levels folds exactly as
//! written above.

use wide::f32x8;

use crate::math::packet::{Mask8, Vec3x8};

/// Levels held before they are composed into the chain's prefix map.
pub const CHAIN_LEVELS: usize = 64;

/// Bound on a composed map's offset and slope (2¹⁰⁰).
const BIG: f32 = 1.267_650_6e30;

/// One level: the local colour, the weight of the next level's colour (per channel:
/// glass weights its reflection per wavelength) and the lanes that hit.
type Level = (Vec3x8, Vec3x8, Mask8);

/// x ↦ min(max(a + b·x, lo), hi) per lane and channel, b >= 0.
#[derive(Clone, Copy, Debug)]
struct ClampAffine {
    a: Vec3x8,
    b: Vec3x8,
    lo: Vec3x8,
    hi: Vec3x8,
}

impl ClampAffine {
    /// One level's map: clamp(local + kr·x, 0, 1) on the lanes that hit, 0 elsewhere.
    fn level(&(local, kr, lanes): &Level) -> ClampAffine {
        let z = Vec3x8::ZERO;
        let pick = |v: Vec3x8| Vec3x8::select(lanes, v, z);
        ClampAffine {
            a: pick(local),
            b: pick(kr),
            lo: z,
            hi: pick(Vec3x8::splat(glam::Vec3::ONE)),
        }
    }

    fn apply(&self, x: Vec3x8) -> Vec3x8 {
        let v = self.a + self.b * x;
        let f = |v: f32x8, lo: f32x8, hi: f32x8| v.max(lo).min(hi);
        Vec3x8::new(
            f(v.x, self.lo.x, self.hi.x),
            f(v.y, self.lo.y, self.hi.y),
            f(v.z, self.lo.z, self.hi.z),
        )
    }

    /// `self ∘ inner`: with b >= 0, clamping `inner`'s range through `self` bounds the
    /// composite (the clamps of two nested intervals are the clamp of the outer one
    /// applied to the inner one's ends). a and b are held within ±2¹⁰⁰: weights above 1
    /// compound without bound, while the inputs lie in [0, 1] and the outputs in
    /// [lo, hi], so a larger slope changes nothing but could overflow to ∞·0.
    fn then_inner(&self, inner: &ClampAffine) -> ClampAffine {
        let big = f32x8::splat(BIG);
        let hold = |v: Vec3x8| {
            let f = |c: f32x8| c.max(-big).min(big);
            Vec3x8::new(f(v.x), f(v.y), f(v.z))
        };
        ClampAffine {
            a: hold(self.a + self.b * inner.a),
            b: hold(self.b * inner.b),
            lo: self.apply(inner.lo),
            hi: self.apply(inner.hi),
        }
    }
}

/// A packet's mirror chain; reused from packet to packet (its buffer is allocated once).
#[derive(Default)]
pub struct Chain {
    levels: Vec<Level>,
    /// The composite of the levels before `levels`, outermost first.
    prefix: Option<ClampAffine>,
}

impl Chain {
    pub fn clear(&mut self) {
        self.levels.clear();
        self.prefix = None;
    }

    /// Appends the next (deeper) level.
    pub fn push(&mut self, level: Level) {
        if self.levels.len() == CHAIN_LEVELS {
            let mut m = self.prefix.take();
            for l in &self.levels {
                let g = ClampAffine::level(l);
                m = Some(match m {
                    Some(outer) => outer.then_inner(&g),
                    None => g,
                });
            }
            self.prefix = m;
            self.levels.clear();
        }
        self.levels.push(level);
    }

    /// The colour at the chain's first level: per-level clamping folded back from the
    /// deepest.
    pub fn fold(&self) -> Vec3x8 {
        let (zero, one) = (f32x8::ZERO, f32x8::splat(1.0));
        let clamp = |v: f32x8| v.max(zero).min(one);
        let c = self
            .levels
            .iter()
            .rev()
            .fold(Vec3x8::ZERO, |deeper, &(local, kr, lanes)| {
                let c = local + deeper * kr;
                let c = Vec3x8::new(clamp(c.x), clamp(c.y), clamp(c.z));
                Vec3x8::select(lanes, c, Vec3x8::ZERO)
            });
        match &self.prefix {
            Some(m) => m.apply(c),
            None => c,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::test_rng::Xorshift;

    /// Chains far longer than [`CHAIN_LEVELS`] fold to the f64 fold of the same levels,
    /// within f32 rounding; short ones exactly as the plain fold.
    #[test]
    fn composed_chains_fold_as_the_plain_fold() {
        let mut rng = Xorshift(0x2545_f491_4f6c_dd1d);
        let mut rnd = move || rng.f32();
        for (len, kr_max) in [
            (3, 1.0),
            (64, 1.0),
            (65, 1.0),
            (1000, 1.0),
            (5000, 0.9),
            (300, 3.0),
        ] {
            let mut chain = Chain::default();
            // per level: local colours, weights, live lanes (in f64)
            type Level = ([[f64; 3]; 8], [[f64; 3]; 8], u32);
            let mut exact: Vec<Level> = Vec::new();
            let mut alive = 0xffu32;
            for _ in 0..len {
                // local colours, weights, and lanes dropping out now and then
                if rnd() < 0.01 {
                    alive &= !(1 << (rnd() * 8.0) as u32);
                }
                let local: [[f32; 3]; 8] =
                    std::array::from_fn(|_| [rnd() * 0.3, rnd() * 0.3, rnd() * 0.3]);
                let kr: [[f32; 3]; 8] = std::array::from_fn(|_| [rnd() * kr_max; 3]);
                let v = |a: &[[f32; 3]; 8]| Vec3x8::from_lanes(&a.map(glam::Vec3::from));
                chain.push((v(&local), v(&kr), Mask8::from_bits(alive)));
                assert!(
                    chain.levels.len() <= CHAIN_LEVELS,
                    "memory bounded by the level count"
                );
                exact.push((
                    local.map(|c| c.map(f64::from)),
                    kr.map(|c| c.map(f64::from)),
                    alive,
                ));
            }
            let got = chain.fold();
            for lane in 0..8 {
                let mut c = [0.0f64; 3];
                for (local, kr, lanes) in exact.iter().rev() {
                    for ch in 0..3 {
                        c[ch] = if lanes >> lane & 1 == 1 {
                            (local[lane][ch] + kr[lane][ch] * c[ch]).clamp(0.0, 1.0)
                        } else {
                            0.0
                        };
                    }
                }
                let g = got.lane(lane).to_array();
                for ch in 0..3 {
                    let tol = if len <= CHAIN_LEVELS { 1e-6 } else { 1e-4 };
                    assert!(
                        (g[ch] as f64 - c[ch]).abs() <= tol,
                        "{len} levels, lane {lane}: {} vs {}",
                        g[ch],
                        c[ch]
                    );
                }
            }
        }
    }
}
