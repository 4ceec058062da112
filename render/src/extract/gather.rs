//! The refs and counts of a chunk's runs of leaves appended to the result, in order.
//!
//! The workers hand back one refs vector per run of leaves. The first run's vector becomes the
//! result when that is still empty (copying it would touch as many fresh pages); the others are
//! copied after it, each into its own place of the room reserved for all, so that the copies,
//! and the first touches of the result's fresh pages they make, can be shared by the thread pool
//! once the workers are done: at two threads on small boxes the runs are many and the first is
//! small, and a copy on one thread was most of the serial time after the workers.

use std::mem::MaybeUninit;

use rayon::prelude::*;

use super::leaf::LeafCounts;
use super::spare_refs::SpareRefs;
use super::DUAL_BASE;
use crate::error::Result;

/// Refs copied or counted by one task, at most: pieces of a few pages, so that a large run is
/// shared between threads too.
const PIECE: usize = 1 << 14;

/// The refs and summed counts of one run of leaves, or the error that ended it.
pub type Run = Result<(Vec<u64>, LeafCounts)>;

/// Appends the refs of `runs` (one entry per run of leaves, in order) to `refs`, adds their
/// counts to `totals` and their merged dual cells to `duals`, and gives the runs' emptied
/// vectors to `spare` (but the first, taken whole when `refs` is empty). With `parallel`, the
/// copies and counts are made by the current thread pool, else on this thread. The first error
/// stops it before anything is appended.
pub fn append(
    runs: Vec<Run>,
    refs: &mut Vec<u64>,
    (totals, duals): (&mut LeafCounts, &mut u64),
    spare: &SpareRefs,
    parallel: bool,
) -> Result<()> {
    let mut runs = runs.into_iter().collect::<Result<Vec<_>>>()?.into_iter();
    let before = refs.len();
    let mut whole = 0;
    if refs.capacity() == 0 {
        if let Some((first, n)) = runs.next() {
            totals.add(&n);
            *refs = first;
            whole = refs.len();
        }
    }
    let rest: Vec<Vec<u64>> = runs
        .map(|(part, n)| {
            totals.add(&n);
            part
        })
        .collect();
    refs.reserve(rest.iter().map(Vec::len).sum());
    let mut room = refs.spare_capacity_mut();
    let mut copies = Vec::new();
    for part in &rest {
        let (place, after) = room.split_at_mut(part.len());
        room = after;
        copies.extend(place.chunks_mut(PIECE).zip(part.chunks(PIECE)));
    }
    let copy = |(place, part): (&mut [MaybeUninit<u64>], &[u64])| {
        for (slot, &r) in place.iter_mut().zip(part) {
            slot.write(r);
        }
        dual_cells(part)
    };
    let copied: u64 = match parallel {
        true => copies.into_par_iter().map(copy).sum(),
        false => copies.into_iter().map(copy).sum(),
    };
    let appended = rest.iter().map(Vec::len).sum::<usize>();
    // SAFETY: the places split the first `appended` slots of the spare capacity in order, without
    // gap or overlap, each as long as its run, and every slot of each was written by `copy`.
    unsafe { refs.set_len(before + whole + appended) };
    let taken = &refs[before..before + whole];
    *duals += copied
        + match parallel {
            true => taken.par_chunks(PIECE).map(dual_cells).sum::<u64>(),
            false => dual_cells(taken),
        };
    for part in rest {
        spare.give(part);
    }
    Ok(())
}

/// The merged dual cells among `refs`.
fn dual_cells(refs: &[u64]) -> u64 {
    refs.iter().filter(|&&r| r as u32 >= DUAL_BASE).count() as u64
}
