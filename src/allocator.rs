//! Tuning of glibc's malloc for tensor work, called once at the start of `rtr` and the examples.
//!
//! burn-ndarray allocates a fresh buffer for nearly every op and frees it soon after. By
//! default glibc serves blocks above its mmap threshold (at most 32 MiB) with `mmap` and gives
//! freed heap tops back to the kernel, so the next step page-faults and zeroes the same memory
//! again, and with several worker threads the faults contend on the process's memory-map lock.
//! Keeping freed memory in the heap avoids that, for a few percent more peak memory (the
//! speed-up: `docs/backends-and-speed.md`). No crate sets these options; mimalloc as the
//! global allocator was slower here.

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

/// Gives the heap's free pages back to the kernel (glibc only; a no-op elsewhere). Called once
/// per training iteration. With the tuning above, freed tensor buffers stay in each worker
/// thread's arena, so a run's resident memory stays at its largest step's: RTR runs sat at
/// 14-21 GB for their whole length, and two of them side by side on this 23 GB machine were
/// killed for memory. With a trim per iteration, a resumed RTR run's resident memory fell back
/// to 0.7-3.5 GB between steps, so two runs only collide when both peak at once (one still
/// did: a single step can need 20 GB, to be reduced at its source). One trim per iteration
/// costs page faults once per step, not per op.
pub fn release_free_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns unused heap memory to the kernel; it takes the
    // allocator's own locks.
    unsafe {
        libc::malloc_trim(0);
    }
}
