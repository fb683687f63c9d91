//! How the process's allocator keeps freed memory.
//!
//! glibc's `malloc` gives a freed block back to the kernel when it was
//! allocated with `mmap` (from 128 KiB up, a threshold glibc moves at run
//! time) or when it lies at the top of the heap (more than 128 KiB free
//! there); the next allocation of that size then takes fresh pages, which
//! the kernel faults in and zeroes one at a time. A training step allocates
//! and frees the same activations and gradients (up to tens of MiB each)
//! every step: in `perf` the step spent 8 % of its time in page faults and
//! zeroing. Here blocks up to 32 MiB (the most glibc allows for this
//! threshold on 64-bit) come from the heap, and the heap is never trimmed,
//! so they are reused; the process's peak memory is what it was, but it is
//! not handed back before the process ends.
//!
//! Measured with `mrdrive bench policy --quick --repeats 1 --train-steps 6`
//! on the 2-core AMD EPYC, the same settings given as `GLIBC_TUNABLES` to the
//! same binary, three interleaved rounds, medians (docs/bench.md): the
//! multi-resolution step 22.8 -> 27.3 samples/s with segmentation, 34.3 ->
//! 36.8 without. No number changes: the allocator decides where a buffer
//! lives, never what is computed in it. Other allocators measured worse
//! (jemalloc and mimalloc by `LD_PRELOAD`: 0.6-0.8x of glibc's default).

/// The size up to which blocks come from the heap and are reused (bytes).
pub const MMAP_THRESHOLD_BYTES: i32 = 32 << 20;

/// Keeps freed memory in the process (module docs). Returns whether the
/// allocator took both settings (always `true` with glibc; other C
/// libraries keep their own behaviour and `false` is returned).
pub fn keep_freed_memory() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: mallopt only changes two of malloc's parameters; it is
        // called before any allocation-heavy work and is thread-safe.
        unsafe {
            libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES) == 1
                && libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX) == 1
        }
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    #[test]
    fn glibc_takes_both_settings() {
        // mallopt refuses (returns 0) a threshold above its limit, so a
        // larger setting would silently keep the default behaviour.
        assert!(keep_freed_memory());
    }
}
