//! How the process's allocator keeps freed memory.
//!
//! glibc's `malloc` gives a freed block back to the kernel when it was
//! allocated with `mmap` (from 128 KiB up, a threshold glibc moves at run
//! time) or when it lies at the top of the heap (more than 128 KiB free
//! there); the next allocation of that size then takes fresh pages, which
//! the kernel faults in and zeroes one at a time. A training step allocates
//! and frees the same activations and gradients (up to tens of MiB each)
//! every step: in `perf` the step spent 8 % of its time in page faults and
//! zeroing. Here blocks up to 32 MiB (the ceiling glibc itself gives its
//! moving threshold on 64-bit; 256 MiB and 1 GiB measured no better) come
//! from the heap, and the heap is never trimmed, so they are reused; the
//! process's peak memory is what it was, but it is not handed back before
//! the process ends.
//!
//! Measured with `mrdrive bench policy --quick` on the 2-core AMD EPYC, the
//! build without and with this, six interleaved rounds, medians
//! (docs/bench.md, "Training"): the multi-resolution step 22.4 -> 27.5
//! samples/s with segmentation (the Original's recipe), 37.0 -> 35.2 without
//! (within the machine's noise). No number changes: the allocator decides
//! where a buffer lives, never what is computed in it. Other allocators
//! measured worse (jemalloc and mimalloc by `LD_PRELOAD`: 0.6-0.8x of
//! glibc's default).

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

    /// Free bytes the allocator holds, over all its arenas (glibc's `mallinfo2`).
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    fn free_bytes_held() -> usize {
        // SAFETY: mallinfo2 only reads the allocator's counters.
        unsafe { libc::mallinfo2().fordblks }
    }

    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    #[test]
    fn a_freed_block_stays_in_the_process() {
        assert!(keep_freed_memory(), "glibc refused a setting");
        // 16 MiB: above glibc's default threshold (128 KiB, growing to a freed
        // block's size), so by default it would be mapped for itself and
        // unmapped when freed, and the allocator would hold none of it.
        let size = 16 << 20;
        let before = free_bytes_held();
        let block = vec![1u8; size];
        std::hint::black_box(&block);
        drop(block);
        let after = free_bytes_held();
        // The block joins the heap's free top (which lent part of it): the
        // allocator now holds at least its 16 MiB free.
        assert!(
            after >= size,
            "the freed 16 MiB went back to the kernel: {before} -> {after} free bytes held"
        );
    }
}
