//! Memory placement of the trees: huge pages and prefetches.

/// An empty vector with room for `cap` elements whose 2 MiB-aligned part Linux is
/// asked to back with transparent huge pages (`madvise(MADV_HUGEPAGE)`, before the
/// pages are touched), so incoherent rays walking megabytes of nodes and blocks miss
/// the TLB less. Embree does the same by default on Linux. Small arrays, other
/// systems: an ordinary vector. Filled in place, so the build copies nothing.
pub(crate) fn huge_vec<T: Copy>(cap: usize) -> Vec<T> {
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        const MADV_HUGEPAGE: i32 = 14;
        unsafe extern "C" {
            fn madvise(addr: *mut std::ffi::c_void, len: usize, advice: i32) -> i32;
        }
        let size = std::mem::size_of::<T>().max(1);
        if cap * size >= 2 * HUGE {
            let mut out: Vec<T> = Vec::with_capacity(cap + HUGE / size);
            let start = out.as_mut_ptr() as usize;
            let end = start + out.capacity() * size;
            let lo = start.next_multiple_of(HUGE);
            let hi = end / HUGE * HUGE;
            if hi > lo {
                // SAFETY: [lo, hi) lies inside `out`'s allocation; MADV_HUGEPAGE only
                // advises the kernel about it and changes no contents. A failure (THP
                // off) leaves ordinary pages.
                unsafe { madvise(lo as *mut std::ffi::c_void, hi - lo, MADV_HUGEPAGE) };
            }
            return out;
        }
    }
    Vec::with_capacity(cap)
}

/// Prefetches every cache line of `*p` (no-op off x86-64).
#[inline(always)]
pub(super) fn prefetch_lines<T>(p: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let base = (p as *const T).cast::<i8>();
        for off in (0..std::mem::size_of::<T>()).step_by(64) {
            // SAFETY: SSE is part of x86-64; a prefetch never faults or writes.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(base.wrapping_add(off)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}
