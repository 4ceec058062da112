//! Per thread, where each surface's last query found its hit: neighbouring rays (the pixels of a
//! row) often meet the same voxel, so testing that voxel before the BVH walk gives a closest-hit
//! search its `tmax` from the start (the walk then skips what lies behind the hit).
//!
//! Where voxels are small on screen the neighbour's voxel is mostly missed, and testing it costs
//! a voxel lookup and a box clip per ray for nothing. So each memory keeps a confidence, raised
//! when a query's hit is in the remembered voxel and lowered when it is not or when there is no
//! hit (which is known whether or not the voxel was tested first); the last hit's voxel is
//! tested first only while the confidence is above zero.
//!
//! A memory is only a hint: it names a position in the surface's refs, read back through
//! [`crate::bvh::OctantBvh::refs`] with a bounds check, so a stale one (another surface at the same
//! address, another frame) costs one voxel test and nothing else.

use std::cell::Cell;

/// Memories per thread, direct-mapped by surface address and query kind.
const SLOTS: usize = 8;

/// The confidence is kept between 0 and this.
const MAX_CONFIDENCE: u32 = 3;

/// Tested first from this confidence on.
const USE_FROM: u32 = 1;

/// What a memory is of.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Query {
    /// The voxel of the last closest hit.
    Closest,
    /// The voxel that last occluded an any-hit query (unused: measured as a loss, see
    /// `docs/benchmarks-render.md`).
    #[allow(dead_code)]
    Any,
}

/// One memory: its key, the position remembered and the confidence in it.
type Memory = (usize, usize, u32);

thread_local! {
    static MEMORY: [Cell<Memory>; SLOTS] =
        const { [const { Cell::new((usize::MAX, 0, 0)) }; SLOTS] };
}

/// The key of `surface`'s memory of `query`s.
#[inline(always)]
pub fn key<T>(surface: &T, query: Query) -> usize {
    (surface as *const T as usize) ^ (query == Query::Any) as usize
}

/// The slot of `key`.
#[inline(always)]
fn slot(key: usize) -> usize {
    (key.wrapping_mul(0x9E37_79B9_7F4A_7C15_u64 as usize) >> (usize::BITS - 3)) % SLOTS
}

/// What this thread remembers for `key`: the position, and whether to test it first.
#[inline(always)]
pub fn recall(key: usize) -> Option<(usize, bool)> {
    MEMORY.with(|m| {
        let (k, at, confidence) = m[slot(key)].get();
        (k == key).then_some((at, confidence >= USE_FROM))
    })
}

/// Records that a query of `key` found its hit at position `found` (`None`: no hit): the
/// position remembered is the last hit's.
#[inline(always)]
pub fn record(key: usize, found: Option<usize>) {
    MEMORY.with(|m| {
        let s = &m[slot(key)];
        let (k, at, confidence) = s.get();
        s.set(match found {
            Some(f) if k == key && f == at => (key, at, (confidence + 1).min(MAX_CONFIDENCE)),
            Some(f) if k == key => (key, f, confidence.saturating_sub(1)),
            Some(f) => (key, f, USE_FROM),
            None if k == key => (key, at, confidence.saturating_sub(1)),
            None => (k, at, confidence),
        })
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_last_hit_is_tested_first_while_hits_repeat() {
        let (a, b) = ([0u64; 4], [0u64; 4]);
        let (ka, kb) = (key(&a, Query::Closest), key(&b, Query::Any));
        assert_eq!(recall(ka), None);
        record(ka, Some(7));
        assert_eq!(recall(ka), Some((7, true)));
        record(ka, Some(7));
        record(ka, Some(8));
        assert_eq!(recall(ka), Some((8, true)));
        record(ka, Some(9));
        assert_eq!(recall(ka), Some((9, false)));
        record(ka, Some(9));
        assert_eq!(recall(ka), Some((9, true)));
        record(ka, None);
        assert_eq!(recall(ka), Some((9, false)));
        record(kb, Some(3));
        assert!(recall(kb).is_some() || slot(ka) == slot(kb));
        assert_eq!(std::thread::spawn(move || recall(ka)).join().unwrap(), None);
    }
}
