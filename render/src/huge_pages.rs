//! Large growing buffers backed by transparent huge pages: written for the first time, such a
//! buffer takes one page fault per 2 MiB instead of one per 4 KiB page.
//!
//! A buffer that takes a new surface's refs or BVH nodes (tens of megabytes, written once and
//! then read by every frame) is fresh memory on every isovalue: the allocator maps allocations
//! this large anew and unmaps them when they are freed. [`reserve`] grows a `Vec` as `Vec` does
//! (at least doubling; past 4 MiB, to at least 34 MiB, an allocation of its own) and asks the
//! kernel (`madvise(MADV_HUGEPAGE)`) to back the whole 2 MiB pages inside its new capacity with
//! huge pages. The contents never change; where the kernel
//! has no huge pages (or the advice is not supported) the buffer is backed by small pages as
//! before. Only pages that are written become resident, as before, to within one huge page
//! past the buffer's length.

/// Bytes of a transparent huge page (x86-64 and most Linux targets).
const HUGE_PAGE: usize = 2 << 20;

/// Capacities below this many bytes are not advised: they hold at most one whole huge page.
const ADVISE_BYTES: usize = 2 * HUGE_PAGE;

/// Bytes an advised allocation takes at least: above the largest threshold (32 MiB) past which
/// glibc's allocator maps every allocation on its own, so that the advice ends with the buffer
/// and never reaches memory the allocator keeps and hands out again (its heaps, which it trims
/// and refills while the extraction churns through small vectors). Capacity past the length is
/// address space only: its pages are never written.
const ADVISED_MIN_BYTES: usize = 34 << 20;

/// Makes room for `additional` more elements in `v`, growing its capacity to at least twice the
/// old one when it must grow. A large new capacity is a new allocation advised for huge pages
/// before the elements are moved into it (a reallocation would have copied them into small
/// pages first).
pub fn reserve<T>(v: &mut Vec<T>, additional: usize) {
    if v.capacity() - v.len() >= additional {
        return;
    }
    let want = v
        .len()
        .saturating_add(additional)
        .max(v.capacity().saturating_mul(2));
    let size = size_of::<T>().max(1);
    if want.saturating_mul(size) < ADVISE_BYTES {
        v.reserve_exact(want - v.len());
        return;
    }
    let want = want.max(ADVISED_MIN_BYTES / size);
    let mut grown = Vec::with_capacity(want);
    advise(&grown);
    grown.append(v);
    *v = grown;
}

/// Advises huge pages for the whole 2 MiB pages inside `v`'s capacity, when it spans at least
/// [`ADVISED_MIN_BYTES`] (an allocation of its own). A hint: errors are ignored.
fn advise<T>(v: &Vec<T>) {
    let bytes = v.capacity().saturating_mul(size_of::<T>());
    if bytes < ADVISED_MIN_BYTES {
        return;
    }
    let start = v.as_ptr() as usize;
    let (Some(first), Some(end)) = (
        start.checked_next_multiple_of(HUGE_PAGE),
        start.checked_add(bytes),
    ) else {
        return;
    };
    let last = end / HUGE_PAGE * HUGE_PAGE;
    if last <= first {
        return;
    }
    advise_range(first, last - first);
}

/// `madvise(MADV_HUGEPAGE)` over `len` bytes from the page-aligned address `at`.
#[cfg(target_os = "linux")]
fn advise_range(at: usize, len: usize) {
    // SAFETY: the range lies inside one live allocation this process owns (a `Vec`'s capacity),
    // aligned to pages; MADV_HUGEPAGE changes only how the kernel backs the range's pages from
    // now on, never their contents, their addresses or whether they are mapped.
    unsafe {
        libc::madvise(at as *mut libc::c_void, len, libc::MADV_HUGEPAGE);
    }
}

/// Elsewhere there is no advice to give.
#[cfg(not(target_os = "linux"))]
fn advise_range(_at: usize, _len: usize) {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reserve_grows_as_vec_does_and_keeps_the_contents() {
        let mut v: Vec<u64> = Vec::new();
        let mut caps = Vec::new();
        for k in 0..2_000_000u64 {
            reserve(&mut v, 1);
            v.push(k);
            if caps.last() != Some(&v.capacity()) {
                caps.push(v.capacity());
            }
        }
        assert!(v.iter().enumerate().all(|(i, &k)| i as u64 == k));
        // At least doubling: a few dozen reallocations for two million pushes.
        assert!(caps.len() < 24, "{} capacities", caps.len());
        assert!(caps.windows(2).all(|w| w[1] >= 2 * w[0]));
        reserve(&mut v, 10_000_000);
        assert!(v.capacity() >= 12_000_000);
        assert_eq!(v.len(), 2_000_000);
        assert_eq!(v[1_999_999], 1_999_999);
    }

    #[test]
    fn small_and_empty_buffers_are_left_alone() {
        let mut v: Vec<u8> = Vec::new();
        advise(&v);
        reserve(&mut v, 0);
        assert_eq!(v.capacity(), 0);
        reserve(&mut v, 100);
        assert!(v.capacity() >= 100);
        let z: Vec<()> = Vec::with_capacity(10);
        advise(&z);
    }
}
