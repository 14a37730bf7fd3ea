//! A hint to start loading memory that will be read soon, for gathers whose next addresses are
//! known ahead (the BVH build reading triangles in leaf order). It changes no value, only when
//! memory arrives; on targets without a stable prefetch instruction it does nothing.

/// Asks the CPU to bring the cache line holding the start of `x` into its caches.
#[inline(always)]
#[allow(unsafe_code)]
pub(crate) fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE, which `_mm_prefetch` needs, is part of every x86-64 CPU; a prefetch neither
    // reads nor writes memory as the program sees it and cannot fault.
    unsafe {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        _mm_prefetch::<_MM_HINT_T0>((x as *const T).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}
