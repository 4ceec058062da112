//! Memory-mapping an `.amrk` file: the one place this crate calls `Mmap::map`.

use std::fs::File;
use std::path::Path;

use amr_format::{AmrkFile, FormatError, Result};
use memmap2::Mmap;

/// An `.amrk` file opened from a read-only memory map.
pub type MappedFile = AmrkFile<Mmap>;

/// Opens and maps `path`, then validates it with [`AmrkFile::open`]. Errors name the file.
pub fn open_mapped(path: &Path) -> Result<MappedFile> {
    let fail = |e: FormatError| e.in_file(path);
    let file = File::open(path).map_err(|e| {
        fail(FormatError::Io {
            context: "cannot open".into(),
            source: e,
        })
    })?;
    let meta = file.metadata().map_err(|e| {
        fail(FormatError::Io {
            context: "cannot stat".into(),
            source: e,
        })
    })?;
    if meta.is_dir() {
        return Err(fail(FormatError::Corrupt(
            "is a directory, not an .amrk file".into(),
        )));
    }
    if meta.len() == 0 {
        return Err(fail(FormatError::Truncated("the file is empty".into())));
    }
    // SAFETY: the map is read-only and private to this process. Another process truncating or
    // rewriting the file while it is mapped could change the bytes under us (or raise SIGBUS);
    // the converter never rewrites a finished file in place (it writes a new file and renames
    // it), which is the contract this program relies on, as every mmap-based reader does.
    let map = unsafe { Mmap::map(&file) }.map_err(|e| {
        fail(FormatError::Io {
            context: "cannot memory-map".into(),
            source: e,
        })
    })?;
    AmrkFile::open(map).map_err(fail)
}

/// Bytes of `map`'s pages this process has touched (its resident set in the mapping), from
/// `/proc/self/smaps`; `None` where that file is not available.
pub fn mapped_resident_bytes(map: &[u8]) -> Option<u64> {
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
        if in_region {
            if let Some(rest) = line.strip_prefix("Rss:") {
                let kb: u64 = rest.trim().trim_end_matches("kB").trim().parse().ok()?;
                return Some(kb * 1024);
            }
        }
    }
    None
}
