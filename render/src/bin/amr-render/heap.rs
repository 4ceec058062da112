//! Keeping freed heap memory from piling up over the frames and files of a run. glibc raises its
//! mmap threshold each time a large block is freed, so that later large blocks come from the heap
//! and stay there when freed: over a time series the peak resident memory then grows by one
//! step's working set. A fixed threshold keeps large blocks (refs, BVH nodes, frame channels) in
//! their own mappings, given back as soon as they are freed.
//!
//! The frames of one file are the opposite case: each frame allocates and frees the same large
//! blocks (its planes, its rows, and the EXR writer's buffers, several megabytes per block of the
//! file), and a fresh mapping is first touched page by page, about 2.5 us a page in a VM. There
//! freed blocks are kept for the next frame ([`keep_freed_for_frames`]).

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

/// Blocks up to this size come from the heap while frames are rendered: glibc's largest mmap
/// threshold, above the 33 MB plane of a 3840x2160 frame.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const FRAMES_MMAP_THRESHOLD: libc::c_int = 32 << 20;

/// Free memory kept at the top of the heap and of each arena while frames are rendered: two
/// frames' working sets at 1024x768, a fraction of a 4K frame's.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const FRAMES_TRIM_THRESHOLD: libc::c_int = 256 << 20;

/// Keeps freed blocks for reuse instead of giving them back (glibc; elsewhere nothing): for the
/// frames of one file, whose blocks repeat from frame to frame and from one block of the EXR to
/// the next. Call once, when the file's scene is built and no other thread allocates.
pub fn keep_freed_for_frames() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `mallopt` only changes two tuning parameters of glibc's allocator, under its main
    // arena's lock; the caller's other threads are idle, and each parameter is a word that later
    // decisions read, so an allocation sees the old setting or the new one, both valid. A
    // refused value leaves the previous one in place.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, FRAMES_MMAP_THRESHOLD);
        libc::mallopt(libc::M_TRIM_THRESHOLD, FRAMES_TRIM_THRESHOLD);
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
