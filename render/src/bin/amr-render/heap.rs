//! Keeping freed heap memory from piling up over the frames and files of a run. glibc raises its
//! mmap threshold each time a large block is freed, so that later large blocks come from the heap
//! and stay there when freed: over a time series the peak resident memory then grows by one
//! step's working set. A fixed threshold keeps large blocks (refs, BVH nodes, frame channels) in
//! their own mappings, given back as soon as they are freed.

/// Blocks from this size up get their own mapping.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const MMAP_THRESHOLD: libc::c_int = 256 << 10;

/// Fixes glibc's mmap threshold (glibc; elsewhere nothing). Call once, first thing.
pub fn keep_large_blocks_mapped() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `mallopt` only changes a tuning parameter of glibc's allocator; it is called
    // before any other thread exists, and a refused value leaves the default in place.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD);
    }
}

/// Returns the free memory of the heap and its arenas to the system (glibc; elsewhere nothing).
pub fn return_freed() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `malloc_trim` releases only free pages of the heap and of glibc's arenas; it
    // touches no allocated block, takes glibc's own locks, and may be called from any thread.
    unsafe {
        libc::malloc_trim(0);
    }
}
