//! Hints to the memory system for loops that wait on loads they could have asked for earlier.

/// Ask the processor to bring `value` into its caches ahead of use; a no-op but on x86-64. For a
/// loop over items in an order the hardware cannot guess (a tile's footprints by depth), asked a
/// few items ahead.
#[inline(always)]
pub(crate) fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let start = std::ptr::from_ref(value).cast::<i8>();
        // Every line the value touches: one address in each, its last byte's included.
        let last = size_of::<T>().saturating_sub(1);
        for offset in (0..last).step_by(64).chain([last]) {
            // SAFETY: a prefetch reads nothing and cannot fault; the addresses lie within `value`.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(start.add(offset)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}
