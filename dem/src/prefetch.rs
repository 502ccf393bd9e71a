//! A hint to the CPU to start loading a cache line before it is read.
//!
//! On several threads a body's state was often last written by the other
//! core, and a load of it waits for the line to come over; asked for early
//! enough, it is there when needed (docs/dem.md).

/// Starts loading the cache line that holds `value` (a no-op off x86-64).
/// Only a hint: nothing is read, so it can be neither wrong nor unsafe.
#[inline(always)]
pub(crate) fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch reads nothing and faults on no address.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
            (value as *const T).cast(),
        )
    };
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}
