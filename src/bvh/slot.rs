//! What a slot of a tree holds, and the traversal stack.

use std::mem::MaybeUninit;

use crate::geometry::PrimKind;

/// Bits of a [`Slot`] below the kind.
const KIND_SHIFT: u32 = 28;

/// A slot of a tree, packed in 32 bits: a primitive count in bits 0..28 and, for a leaf,
/// the [`PrimKind`] of all its primitives in bits 28..31. A count of 0 is an interior
/// node (whose upper bits the binary tree uses for its split axis) or an empty slot of
/// a wide node (whose box never hits).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(transparent)]
pub struct Slot(u32);

impl Slot {
    /// An interior node of the wide tree (and an empty slot).
    pub const INTERIOR: Slot = Slot(0);
    /// The most primitives a leaf holds.
    pub const MAX_COUNT: u32 = (1 << KIND_SHIFT) - 1;

    /// A leaf of `count` (1..=[`Slot::MAX_COUNT`]) primitives of `kind`.
    #[inline]
    pub fn leaf(kind: PrimKind, count: u32) -> Slot {
        debug_assert!(count > 0 && count <= Slot::MAX_COUNT);
        Slot(count | (kind as u32) << KIND_SHIFT)
    }

    /// An interior node of the binary tree split on `axis`.
    #[inline]
    pub fn split(axis: usize) -> Slot {
        Slot((axis as u32) << KIND_SHIFT)
    }

    #[inline]
    pub fn is_interior(self) -> bool {
        self.count() == 0
    }

    /// Primitives in a leaf (0: interior).
    #[inline]
    pub fn count(self) -> u32 {
        self.0 & Slot::MAX_COUNT
    }

    /// The kind of a leaf's primitives.
    #[inline]
    pub fn kind(self) -> PrimKind {
        debug_assert!(!self.is_interior());
        self.try_kind().expect("a leaf slot names a primitive kind")
    }

    /// The kind its kind bits name, `None` when they name none (a slot not made by
    /// [`Slot::leaf`]: `Bvh::validate` reports it).
    #[inline]
    pub fn try_kind(self) -> Option<PrimKind> {
        PrimKind::from_bits(self.0 >> KIND_SHIFT)
    }

    /// Whether this is a leaf of `kind` (no decoding).
    #[inline]
    pub fn holds(self, kind: PrimKind) -> bool {
        !self.is_interior() && self.0 >> KIND_SHIFT == kind as u32
    }

    /// A binary interior node's split axis.
    #[inline]
    pub fn axis(self) -> usize {
        (self.0 >> KIND_SHIFT) as usize
    }
}

/// A child as the walks keep it: its slot and where it points (a node, a triangle
/// block or a primitive, by the slot).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlotRef {
    pub child: u32,
    pub slot: Slot,
}

impl SlotRef {
    /// The root of a wide tree.
    pub const ROOT: SlotRef = SlotRef {
        child: 0,
        slot: Slot::INTERIOR,
    };
}

/// A traversal stack of at most `N` entries, left uninitialised until pushed (zeroing
/// a walk's stack on every query cost more than the walk's own pushes). Every walk's
/// `unsafe` is here.
pub struct Stack<T: Copy, const N: usize> {
    items: [MaybeUninit<T>; N],
    len: usize,
}

impl<T: Copy, const N: usize> Stack<T, N> {
    #[inline(always)]
    pub fn new() -> Self {
        Stack {
            // SAFETY: an array of `MaybeUninit` needs no initialisation. (The repeat
            // expression `[MaybeUninit::uninit(); N]` was compiled as a loop writing
            // every entry: most of the single-ray walk's instructions.)
            items: unsafe { MaybeUninit::<[MaybeUninit<T>; N]>::uninit().assume_init() },
            len: 0,
        }
    }

    /// Pushes `v`; panics beyond `N` entries (the trees' depth keeps the walks below it).
    #[inline(always)]
    pub fn push(&mut self, v: T) {
        self.items[self.len] = MaybeUninit::new(v);
        self.len += 1;
    }

    #[inline(always)]
    pub fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: every entry below `len` was written by `push`.
        Some(unsafe { self.items[self.len].assume_init() })
    }

    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Drops every entry.
    #[inline(always)]
    pub fn clear(&mut self) {
        self.len = 0;
    }
}

impl<T: Copy, const N: usize> Default for Stack<T, N> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_round_trip_and_never_decode_interior_as_a_kind() {
        for kind in PrimKind::BVH_KINDS {
            for count in [1, 7, Slot::MAX_COUNT] {
                let s = Slot::leaf(kind, count);
                assert!(!s.is_interior());
                assert_eq!((s.kind(), s.count()), (kind, count));
                assert!(s.holds(kind));
            }
        }
        for axis in 0..3 {
            let s = Slot::split(axis);
            assert!(s.is_interior() && s.axis() == axis);
            assert!(!s.holds(PrimKind::Sphere));
        }
        assert!(Slot::INTERIOR.is_interior());
    }

    #[test]
    fn stack_pops_what_was_pushed_last_first() {
        let mut s: Stack<u32, 4> = Stack::new();
        assert_eq!(s.pop(), None);
        for v in [3, 1, 4] {
            s.push(v);
        }
        assert_eq!(
            [s.pop(), s.pop(), s.pop(), s.pop()],
            [Some(4), Some(1), Some(3), None]
        );
        assert!(s.is_empty());
    }
}
