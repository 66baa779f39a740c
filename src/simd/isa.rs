//! The instruction set of the fast path's packet kernels, chosen per renderer and per
//! `bench-trace` run (the command line's `--isa`, else `OCTARAY_ISA`, else the widest
//! the CPU runs).
//!
//! One binary holds the packet walks twice: at 8 lanes compiled for the build's target
//! (`avx2`; x86-64-v3 by default) and at 16 lanes over `__m512` in functions compiled
//! with AVX-512 enabled (`avx512`, which adds them; the 8-lane and single-ray code is
//! the same under both). The CPU is asked once (`is_x86_feature_detected!`);
//! `--isa auto|avx2|avx512` or `OCTARAY_ISA` force a choice, and `avx512` on a CPU
//! without it is refused. An [`Isa`] value is the proof that its kernels can run: an
//! `avx512` one is made only by [`Isa::avx512`] (and the functions that call it) on a
//! CPU that has every feature the AVX-512 functions are compiled with.

use std::fmt;

/// The environment variable that forces a choice (`auto`, `avx2`, `avx512`).
pub const ENV: &str = "OCTARAY_ISA";

/// Which compiled kernels run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum IsaKind {
    /// 8 lanes, the build's own instructions.
    Avx2,
    /// Adds the 16-lane packets, compiled with AVX-512 F, VL, BW and DQ.
    Avx512,
}

/// Proof that this CPU runs the AVX-512 kernels (F, VL, BW, DQ): made only from an
/// [`Isa`] of kind `Avx512`, which only a CPU that has them gets. The functions compiled
/// with AVX-512 enabled are called only where one is at hand.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Avx512(());

/// The kernels a process runs, on a CPU that can run them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Isa(IsaKind);

/// A choice that cannot be honoured: an unknown name, or `avx512` on a CPU without it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum IsaError {
    Unknown(String),
    Unsupported(&'static str),
}

impl fmt::Display for IsaError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            IsaError::Unknown(s) => write!(
                f,
                "unknown instruction set {s:?} (expected auto, avx2 or avx512)"
            ),
            IsaError::Unsupported(name) => write!(
                f,
                "this CPU cannot run the {name} kernels (it lacks AVX-512 F, VL, BW or DQ); use auto or avx2"
            ),
        }
    }
}

impl std::error::Error for IsaError {}

impl Isa {
    /// The build's own 8-lane kernels: they run wherever the binary runs.
    pub const AVX2: Isa = Isa(IsaKind::Avx2);

    /// The AVX-512 kernels, if this CPU has AVX-512 F, VL, BW and DQ (and AVX2, FMA).
    pub fn avx512() -> Option<Isa> {
        #[cfg(target_arch = "x86_64")]
        {
            // every feature the AVX-512 functions are compiled with
            let has = std::is_x86_feature_detected!("avx2")
                && std::is_x86_feature_detected!("fma")
                && std::is_x86_feature_detected!("avx512f")
                && std::is_x86_feature_detected!("avx512vl")
                && std::is_x86_feature_detected!("avx512bw")
                && std::is_x86_feature_detected!("avx512dq");
            if has {
                return Some(Isa(IsaKind::Avx512));
            }
        }
        None
    }

    /// The widest kernels this CPU runs.
    pub fn detect() -> Isa {
        Isa::avx512().unwrap_or(Isa::AVX2)
    }

    /// `auto` (detect), `avx2` or `avx512` (refused on a CPU without it).
    pub fn parse(name: &str) -> Result<Isa, IsaError> {
        match name.trim() {
            "auto" => Ok(Isa::detect()),
            "avx2" => Ok(Isa::AVX2),
            "avx512" => Isa::avx512().ok_or(IsaError::Unsupported("avx512")),
            other => Err(IsaError::Unknown(other.to_string())),
        }
    }

    /// The choice forced by [`ENV`], if it is set (and not empty).
    pub fn from_env() -> Result<Option<Isa>, IsaError> {
        match std::env::var(ENV) {
            Ok(s) if !s.trim().is_empty() => Isa::parse(&s).map(Some),
            _ => Ok(None),
        }
    }

    /// The process's choice: [`ENV`]'s when it is set and usable, else the widest the
    /// CPU runs (the command line refuses an unusable [`ENV`] before anything reads
    /// this, and passes `--isa` explicitly).
    pub fn process() -> Isa {
        Isa::from_env().ok().flatten().unwrap_or_else(Isa::detect)
    }

    pub fn kind(self) -> IsaKind {
        self.0
    }

    /// `avx2` or `avx512`.
    pub fn name(self) -> &'static str {
        match self.0 {
            IsaKind::Avx2 => "avx2",
            IsaKind::Avx512 => "avx512",
        }
    }

    /// The proof that the AVX-512 kernels may run, when this is `avx512`.
    pub fn avx512_kernels(self) -> Option<Avx512> {
        (self.0 == IsaKind::Avx512).then_some(Avx512(()))
    }

    /// Lanes of the widest packets its kernels trace.
    pub fn lanes(self) -> usize {
        match self.0 {
            IsaKind::Avx2 => 8,
            IsaKind::Avx512 => 16,
        }
    }
}

impl fmt::Display for Isa {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_and_unknown_ones_are_refused() {
        assert_eq!(Isa::parse("avx2"), Ok(Isa::AVX2));
        assert_eq!(Isa::parse(" auto "), Ok(Isa::detect()));
        assert_eq!(Isa::parse("avx512").ok(), Isa::avx512());
        assert!(matches!(Isa::parse("sse9"), Err(IsaError::Unknown(s)) if s == "sse9"));
        assert_eq!(Isa::AVX2.lanes(), 8);
        assert_eq!(Isa::AVX2.to_string(), "avx2");
        if let Some(i) = Isa::avx512() {
            assert_eq!((i.name(), i.lanes()), ("avx512", 16));
        } else {
            assert_eq!(Isa::parse("avx512"), Err(IsaError::Unsupported("avx512")));
        }
    }
}
