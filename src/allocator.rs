//! Tuning of glibc's malloc for tensor work, called once at the start of `rtr` and the examples.
//!
//! burn-ndarray allocates a fresh buffer for nearly every op and frees it soon after. By
//! default glibc serves blocks above its mmap threshold (at most 32 MiB) with `mmap` and gives
//! freed heap tops back to the kernel, so the next step page-faults and zeroes the same memory
//! again, and with several worker threads the faults contend on the process's memory-map lock.
//! Keeping freed memory in the heap removed much of that. Measured side by side (`cargo bench
//! --bench side_by_side`, 5 interleaved runs, `rtr bench model` at the paper's size, 2 cores):
//! forward + backward 2867 -> 2429 ms with 2 workers, 3861 -> 3365 ms with one, forward
//! 1.12-1.20x faster, peak memory +5 %. No crate sets these; mimalloc as the global allocator
//! was tried instead and was slower here.

/// Largest mmap threshold glibc accepts on 64-bit targets (`DEFAULT_MMAP_THRESHOLD_MAX`).
const MMAP_THRESHOLD: i32 = 32 << 20;
/// Free heap top kept before trimming, and extra obtained per heap growth.
const TRIM_THRESHOLD: i32 = 1 << 30;
const TOP_PAD: i32 = 256 << 20;

/// Keeps freed tensor buffers in the heap for reuse (glibc only; a no-op elsewhere).
pub fn tune_for_tensors() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes allocator parameters; it is called before any other
    // thread exists and takes plain integers.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD);
        libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD);
        libc::mallopt(libc::M_TOP_PAD, TOP_PAD);
    }
}
