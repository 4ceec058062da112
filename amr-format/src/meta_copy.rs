//! The reader's private copy of a file's metadata region, and its checksum.
//!
//! A large copy lives in an anonymous map advised for transparent huge pages: a file of
//! thousands of small boxes has megabytes of metadata, and as fresh 4 KiB heap pages each page of
//! the copy costs a page fault (about 5 us on a VM), more than copying it. Where the kernel does
//! not grant huge pages the map is faulted in 4 KiB pages as before; where no map can be made
//! the copy is a heap vector.

use std::ops::Deref;

#[cfg(target_os = "linux")]
use memmap2::Advice;
use memmap2::MmapMut;

/// A huge page, and the smallest copy worth a map of its own.
const HUGE: usize = 2 << 20;

/// A copy of some bytes, read as a slice.
pub(crate) enum MetaCopy {
    /// A small copy.
    Heap(Vec<u8>),
    /// A large copy in the first `len` bytes of an anonymous map.
    Mapped { map: MmapMut, len: usize },
}

impl MetaCopy {
    /// A copy of `src` and the CRC-32 of the copy (of the bytes copied, not of `src` read a
    /// second time).
    pub(crate) fn of(src: &[u8]) -> (Self, u32) {
        // One copy and then one checksum: a copy a chunk at a time, each checksummed while in
        // the cache, took glibc's `memcpy` from its streaming path to a loop of 8 M more
        // instructions on a 7 MB region.
        let copy = match huge_map(src.len()) {
            Some(mut map) => {
                map[..src.len()].copy_from_slice(src);
                MetaCopy::Mapped {
                    map,
                    len: src.len(),
                }
            }
            None => MetaCopy::Heap(src.to_vec()),
        };
        let crc = crc32fast::hash(&copy);
        (copy, crc)
    }
}

impl Deref for MetaCopy {
    type Target = [u8];

    fn deref(&self) -> &[u8] {
        match self {
            MetaCopy::Heap(v) => v,
            MetaCopy::Mapped { map, len } => &map[..*len],
        }
    }
}

/// An anonymous map of at least `len` bytes advised for huge pages, for a `len` of a huge page
/// or more; `None` otherwise or where it cannot be made. Its length is rounded up to whole huge
/// pages, so that the kernel places it on a huge page boundary. The last, partly used huge page
/// is advised only when at least half of it is used (its unused part is resident too); else the
/// copy's end is faulted in small pages.
fn huge_map(len: usize) -> Option<MmapMut> {
    if len < HUGE {
        return None;
    }
    let whole = len.checked_next_multiple_of(HUGE)?;
    let map = MmapMut::map_anon(whole).ok()?;
    let advised = if whole - len <= HUGE / 2 {
        whole
    } else {
        len - len % HUGE
    };
    // Refused by kernels without transparent huge pages: the map still works in small pages.
    #[cfg(target_os = "linux")]
    let _ = map.advise_range(Advice::HugePage, 0, advised);
    #[cfg(not(target_os = "linux"))]
    let _ = advised;
    Some(map)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn copies_and_checksums_small_and_large() {
        for len in [0, 1, 4099, HUGE, HUGE + 70_003, 3 * HUGE - 5] {
            let src: Vec<u8> = (0..len).map(|i| (i * 7 + i / 251) as u8).collect();
            let (copy, crc) = MetaCopy::of(&src);
            assert_eq!(&*copy, &src[..], "length {len}");
            assert_eq!(crc, crc32fast::hash(&src), "length {len}");
            assert_eq!(matches!(copy, MetaCopy::Mapped { .. }), len >= HUGE);
        }
    }
}
