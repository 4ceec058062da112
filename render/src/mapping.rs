//! Memory-mapping an `.amrk` file: the one place this crate calls `Mmap::map` and drops mapped
//! pages from the resident set ([`PageRelease`]).

use std::fs::File;
use std::ops::Deref;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use amr_format::{AmrkFile, FormatError, Result};
use memmap2::{Advice, Mmap, UncheckedAdvice};

use crate::dump_hint;
use crate::sigbus::{self, Watch};

/// An `.amrk` file opened from a read-only memory map.
pub type MappedFile = AmrkFile<WatchedMap>;

/// A read-only map of a file whose SIGBUS (the file truncated under it) ends the process with
/// an error naming the file ([`sigbus::watch`]).
pub struct WatchedMap {
    // Declared first so that it is dropped, and the range unwatched, before the map is unmapped.
    _watch: Watch,
    map: Mmap,
}

impl Deref for WatchedMap {
    type Target = Mmap;
    fn deref(&self) -> &Mmap {
        &self.map
    }
}

impl AsRef<[u8]> for WatchedMap {
    fn as_ref(&self) -> &[u8] {
        &self.map
    }
}

/// Asks the kernel to start reading the byte ranges `ranges` (offset, length) of `file`'s map
/// into the page cache (`madvise(MADV_WILLNEED)`) and returns without waiting for the reads.
/// Ranges are clipped to the map.
pub fn read_ahead(file: &MappedFile, ranges: impl IntoIterator<Item = (u64, u64)>) {
    let map = file.data();
    let size = map.len() as u64;
    for (offset, len) in ranges {
        let end = offset.saturating_add(len).min(size);
        if offset < end {
            // A refused hint changes nothing but speed.
            let _ = map.advise_range(Advice::WillNeed, offset as usize, (end - offset) as usize);
        }
    }
}

/// Opens and maps `path`, then validates it with [`AmrkFile::open`]. Errors name the file.
pub fn open_mapped(path: &Path) -> Result<MappedFile> {
    let fail = |e: FormatError| e.in_file(path);
    // Looked at before it is opened: opening a FIFO would wait for a writer.
    let meta = std::fs::metadata(path).map_err(|e| fail(FormatError::io("cannot open", e)))?;
    if meta.is_dir() {
        return Err(fail(FormatError::NotAmrk(dump_hint::not_amrk(path))));
    }
    if !meta.is_file() {
        return Err(fail(FormatError::NotAmrk(
            "not an .amrk file (not a regular file: a device, pipe or socket)".into(),
        )));
    }
    let file = File::open(path).map_err(|e| fail(FormatError::io("cannot open", e)))?;
    let meta = file
        .metadata()
        .map_err(|e| fail(FormatError::io("cannot stat", e)))?;
    if meta.len() == 0 {
        return Err(fail(FormatError::Truncated("the file is empty".into())));
    }
    // SAFETY: the map is read-only. Another process may still truncate or rewrite the file
    // while it is mapped (the converter never does: it writes a new file and renames it):
    // - rewritten bytes: `AmrkFile::open` copies the metadata it validates and reads only the
    //   copy afterwards, so indexing never sees other values; brick bytes that change are data
    //   (checked by CRC in `verify`, decoded with bounds-checked lengths elsewhere);
    // - truncation: touching a page past the new end raises SIGBUS, which the watch below turns
    //   into an error naming the file and exit status 1.
    let map =
        unsafe { Mmap::map(&file) }.map_err(|e| fail(FormatError::io("cannot memory-map", e)))?;
    let watched = WatchedMap {
        _watch: sigbus::watch(path, &map),
        map,
    };
    AmrkFile::open(watched)
        .map(|f| f.with_path(path))
        .map_err(|e| match e {
            FormatError::BadMagic { .. } => FormatError::NotAmrk(dump_hint::not_amrk(path)),
            other => other,
        })
        .map_err(fail)
}

/// Bytes of `map`'s pages this process has touched (its resident set in the mapping), from
/// `/proc/self/pagemap` (the map's own page-table entries) for a map of at most
/// [`PAGEMAP_MAX_BYTES`], else (or where that fails) `/proc/self/smaps`; `None` where neither
/// file is available.
pub fn mapped_resident_bytes(map: &[u8]) -> Option<u64> {
    let small = map.len() as u64 <= PAGEMAP_MAX_BYTES;
    small
        .then(|| present_bytes(map))
        .flatten()
        .or_else(|| smaps_rss(map))
}

/// Largest map measured through `/proc/self/pagemap`. Its 8 bytes per page cost follows the
/// map's size, where `/proc/self/smaps` skips the unpopulated page tables of a large, sparsely
/// touched map: at 4.2 GB (1e9 cells) pagemap took about 2.7 ms more than smaps, and at 11.5 MB
/// (`tiny`) about 0.8 ms less (`docs/benchmarks.md`, early hours of 2026-12-06).
pub const PAGEMAP_MAX_BYTES: u64 = 256 << 20;

/// Bytes of the pages of `map` present in this process's page tables, from
/// `/proc/self/pagemap`: 8 bytes read a page of the map, so its cost follows the map's size,
/// not the process's other mappings (as `/proc/self/smaps` does, formatted as text).
fn present_bytes(map: &[u8]) -> Option<u64> {
    use std::os::unix::fs::FileExt;
    /// Entries read at once.
    const BATCH: u64 = 4096;
    /// Bit 63 of an entry: the page is present.
    const PRESENT: u64 = 1 << 63;
    let page = page_bytes()?;
    let first = map.as_ptr() as u64 / page;
    let end = (map.as_ptr() as u64 + map.len() as u64).div_ceil(page);
    let pagemap = File::open("/proc/self/pagemap").ok()?;
    let mut buf = vec![0u8; (BATCH * 8) as usize];
    let mut present = 0u64;
    let mut p = first;
    while p < end {
        let entries = &mut buf[..((end - p).min(BATCH) * 8) as usize];
        pagemap.read_exact_at(entries, p * 8).ok()?;
        present += entries
            .chunks_exact(8)
            .filter(|e| {
                u64::from_ne_bytes([e[0], e[1], e[2], e[3], e[4], e[5], e[6], e[7]]) & PRESENT != 0
            })
            .count() as u64;
        p += (entries.len() / 8) as u64;
    }
    Some(present * page)
}

/// The `Rss` of the mapping holding `map` in `/proc/self/smaps`.
fn smaps_rss(map: &[u8]) -> Option<u64> {
    let start = map.as_ptr() as usize;
    let smaps = std::fs::read_to_string("/proc/self/smaps").ok()?;
    let mut in_region = false;
    for line in smaps.lines() {
        if let Some((range, _)) = line.split_once(' ') {
            if let Some((a, b)) = range.split_once('-') {
                if let (Ok(a), Ok(b)) = (usize::from_str_radix(a, 16), usize::from_str_radix(b, 16))
                {
                    in_region = a <= start && start < b;
                    continue;
                }
            }
        }
        if in_region && line.starts_with("Rss:") {
            return crate::system_memory::kib_field(line, "Rss:");
        }
    }
    None
}

/// Bytes of file-backed pages (and shared memory) in this process's resident set, from
/// `/proc/self/statm` (one counter, no page-table walk); `None` where that file is not available.
fn file_resident_bytes() -> Option<u64> {
    let statm = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: u64 = statm.split_whitespace().nth(2)?.parse().ok()?;
    pages.checked_mul(page_bytes()?)
}

/// The page size.
fn page_bytes() -> Option<u64> {
    // SAFETY: sysconf has no preconditions.
    let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    u64::try_from(page).ok().filter(|&p| p > 0)
}

/// Map bytes a release leaves resident when it finds fewer: unmapping them and faulting them
/// back in would cost more than they weigh (a frame of a small file touches the same pages
/// after every band), and the map's share of the peak RSS stays at most this or one stage.
pub const RELEASE_FLOOR_BYTES: u64 = 64 << 20;

/// Drops the pages of a file's map from this process's resident set on request, so that the
/// map's share of the peak RSS is what one stage touches between two requests, not the file; and
/// asks the kernel to read ahead the pages a stage is about to touch.
///
/// The pages stay in the kernel's page cache while memory allows: touching them again costs a
/// minor fault, not a read. Each request first measures the map's resident bytes; the largest
/// measurement is kept as [`PageRelease::peak_bytes`].
///
/// A request runs between two stages, while the worker threads wait, so it must be cheap: the
/// map's resident bytes are measured as the growth of the process's file-backed resident set
/// (`/proc/self/statm`, a counter) since the last release, not by walking the map's page tables
/// ([`mapped_resident_bytes`]); file pages of other mappings faulted in meanwhile (program code)
/// count too. The first release measures the map exactly instead ([`mapped_resident_bytes`], once),
/// because the first stage also faults in the program's own code for it; no measurement exceeds
/// the map's size. The unmapping is one `madvise` call over the whole map, made by the
/// requesting thread (see `docs/rendering.md`, "Map pages").
pub struct PageRelease<'f> {
    file: &'f MappedFile,
    peak: AtomicU64,
    /// File-backed resident bytes of the process outside the map, as of the last release.
    others: AtomicU64,
    /// Whether the next release measures the map's resident bytes exactly.
    exact_next: AtomicBool,
    /// Resident map bytes below which a release leaves the pages.
    floor: u64,
}

impl<'f> PageRelease<'f> {
    /// Releases pages of `file`'s map when at least [`RELEASE_FLOOR_BYTES`] are resident.
    pub fn new(file: &'f MappedFile) -> Self {
        Self::with_floor(file, RELEASE_FLOOR_BYTES)
    }

    /// Releases pages of `file`'s map when at least `floor` bytes are resident.
    pub fn with_floor(file: &'f MappedFile, floor: u64) -> Self {
        let in_map = mapped_resident_bytes(file.bytes()).unwrap_or(0);
        let others = file_resident_bytes().map_or(u64::MAX, |b| b.saturating_sub(in_map));
        Self {
            file,
            peak: AtomicU64::new(0),
            others: AtomicU64::new(others),
            exact_next: AtomicBool::new(true),
            floor,
        }
    }

    /// Whether a release may drop pages: the map is not smaller than the floor.
    pub fn may_drop(&self) -> bool {
        self.file.bytes().len() as u64 >= self.floor
    }

    /// Drops every page of the map from the resident set, unless fewer than the floor
    /// ([`PageRelease::with_floor`]) are resident; returns the bytes that were resident just before,
    /// when `/proc/self/statm` tells.
    pub fn release(&self) -> Option<u64> {
        let map_len = self.file.bytes().len() as u64;
        let exact = self.exact_next.swap(false, Ordering::Relaxed);
        let resident = if exact {
            mapped_resident_bytes(self.file.bytes())
        } else {
            let others = self.others.load(Ordering::Relaxed);
            file_resident_bytes()
                .filter(|_| others != u64::MAX)
                .map(|b| b.saturating_sub(others))
        }
        .map(|b| b.min(map_len));
        if let Some(b) = resident {
            self.peak.fetch_max(b, Ordering::Relaxed);
            if b < self.floor {
                // Kept until a release finds more: the next measurement counts them too, from
                // the file-backed pages outside the map as of the last unmapping, or as of this
                // exact measurement.
                if exact {
                    if let Some(all) = file_resident_bytes() {
                        self.others.store(all.saturating_sub(b), Ordering::Relaxed);
                    }
                }
                return resident;
            }
        }
        // One call over the whole map, from this thread: each call that unmaps pages ends in a
        // TLB flush that interrupts the other cores running this process, so calls from the
        // thread pool would interrupt each other; stretches with nothing resident cost little.
        //
        // SAFETY: memmap2 calls MADV_DONTNEED unsafe because on a private writable map it throws
        // away what was written. This map is read-only and shared with the page cache (that is
        // how `Mmap::map` maps), so nothing was written through it: the kernel only unmaps the
        // pages, and the next access through any slice borrowed from the map faults in the same
        // file bytes again. Those bytes stay the same under the contract `open_mapped` states (no
        // one rewrites a finished file in place).
        let dropped = unsafe { self.file.data().unchecked_advise(UncheckedAdvice::DontNeed) };
        // A refused hint leaves the pages resident, which costs memory but changes no result.
        drop(dropped);
        if let Some(b) = file_resident_bytes() {
            self.others.store(b, Ordering::Relaxed);
        }
        resident
    }

    /// Asks the kernel to start reading the byte ranges `ranges` (offset, length) of the map
    /// into the page cache (`madvise(MADV_WILLNEED)`) and returns without waiting for the reads,
    /// so that a stage about to fault them in finds them read, or being read with a deep queue.
    /// Ranges are clipped to the map.
    pub fn read_ahead(&self, ranges: impl IntoIterator<Item = (u64, u64)>) {
        read_ahead(self.file, ranges);
    }

    /// The most map bytes measured resident at once: the largest of the measurements taken by
    /// [`PageRelease::release`] and one taken now.
    pub fn peak_bytes(&self) -> u64 {
        let now = mapped_resident_bytes(self.file.bytes()).unwrap_or(0);
        self.peak.load(Ordering::Relaxed).max(now)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use amr_format::progress::NoProgress;
    use amr_format::WriterOptions;
    use amr_synth::{write_synth, Case, SynthParams};

    #[test]
    fn released_pages_read_back_the_same_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let file = small_blobs_file(dir.path());
        let before = weighted_sum(file.bytes());
        let pages = PageRelease::with_floor(&file, 0);
        let touched = pages.release();
        let after = mapped_resident_bytes(file.bytes());
        if let (Some(touched), Some(after)) = (touched, after) {
            assert!(
                touched >= file.bytes().len() as u64 / 2,
                "{touched} bytes resident"
            );
            assert_eq!(after, 0, "pages still resident after the release");
        }
        assert_eq!(weighted_sum(file.bytes()), before);
        assert!(pages.peak_bytes() >= touched.unwrap_or(0));
    }

    #[test]
    fn a_release_below_the_floor_leaves_the_pages() {
        let dir = tempfile::tempdir().unwrap();
        let file = small_blobs_file(dir.path());
        let len = file.bytes().len() as u64;
        let before = weighted_sum(file.bytes());
        let pages = PageRelease::with_floor(&file, len + 1);
        let first = pages.release();
        let (Some(first), Some(after)) = (first, mapped_resident_bytes(file.bytes())) else {
            return;
        };
        assert!(first >= len / 2, "{first} bytes resident");
        // (`first` is capped at the map's length; `after` counts whole pages.)
        assert!(
            after >= first,
            "a release below the floor unmapped pages: {after} < {first}"
        );
        assert_eq!(weighted_sum(file.bytes()), before);
    }

    #[test]
    fn page_table_entries_count_what_smaps_counts() {
        let dir = tempfile::tempdir().unwrap();
        let file = small_blobs_file(dir.path());
        let bytes = file.bytes();
        let half = weighted_sum(&bytes[..bytes.len() / 2]);
        assert!(half > 0);
        let (Some(present), Some(rss)) = (present_bytes(bytes), smaps_rss(bytes)) else {
            return;
        };
        assert_eq!(present, rss);
    }

    /// A small two-level `blobs` file written in `dir`, mapped.
    fn small_blobs_file(dir: &std::path::Path) -> MappedFile {
        let path = dir.join("blobs.amrk");
        let params = SynthParams::unit_cube(2, 2, 32, 16);
        let opts = WriterOptions::default();
        write_synth(&path, Case::Blobs, &params, opts, &NoProgress).unwrap();
        open_mapped(&path).unwrap()
    }

    /// A position-weighted byte sum, enough to see bytes change.
    fn weighted_sum(b: &[u8]) -> u64 {
        b.iter().enumerate().fold(0u64, |s, (i, &x)| {
            s.wrapping_add((i as u64 + 1).wrapping_mul(u64::from(x)))
        })
    }
}
