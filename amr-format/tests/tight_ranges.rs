//! Tight leaf ranges (layout version 3) and part bounds (version 4): the writer stores what its
//! computation gives, readers read them back, and a damaged or hostile table is an error at
//! open, never a panic.

mod common;

use std::path::Path;

use amr_format::raw::{Footer, LeafRange, PartTable};
use amr_format::{AmrkFile, AmrkWriter, FormatError, TightSink, WriterOptions};
use common::*;
use zerocopy::{FromBytes, IntoBytes};

/// Ranges a stand-in computation gives: each leaf's stored (conservative) range, a little
/// narrowed so that the stored table is told apart from it; no range for leaves without data.
fn narrowed_ranges(path: &Path) -> Result<Vec<Vec<(f32, f32)>>, String> {
    let file = AmrkFile::open(std::fs::read(path).map_err(|e| e.to_string())?)
        .map_err(|e| e.to_string())?;
    assert!(
        !file.has_tight_ranges() && file.part_cells().is_none(),
        "computed over a file without them"
    );
    Ok((0..file.fields().len())
        .map(|f| {
            (0..file.num_leaves() as u32)
                .map(|l| match file.leaf(l).bricks.is_empty() {
                    true => (f32::INFINITY, f32::NEG_INFINITY),
                    false => {
                        let (lo, hi) = file.leaf_range(f, l);
                        (lo + (hi - lo) / 8.0, hi)
                    }
                })
                .collect()
        })
        .collect())
}

/// The stand-in's bounds of the parts of leaf `leaf` of range `r`: `leaf % 3` parts, the
/// `p`-th narrowed `p` times more.
fn stand_in_parts(leaf: usize, (lo, hi): (f32, f32)) -> Vec<(f32, f32)> {
    (0..leaf % 3)
        .map(|p| match lo <= hi {
            true => (lo + (hi - lo) * p as f32 / 16.0, hi),
            false => (lo, hi),
        })
        .collect()
}

/// A stand-in for the renderer's computation: [`narrowed_ranges`] and [`stand_in_parts`] of
/// parts of 2 cells, passed through `edit` (field, leaf, range, parts) first.
fn stand_in(
    path: &Path,
    sink: &mut TightSink<'_, '_>,
    edit: impl Fn(usize, usize, &mut (f32, f32), &mut Vec<(f32, f32)>),
) -> Result<(), String> {
    sink.set_part_cells(2)?;
    for (f, ranges) in narrowed_ranges(path)?.into_iter().enumerate() {
        for (l, mut r) in ranges.into_iter().enumerate() {
            let mut parts = stand_in_parts(l, r);
            edit(f, l, &mut r, &mut parts);
            sink.push(r, &parts)?;
        }
    }
    Ok(())
}

fn narrowed(path: &Path, sink: &mut TightSink<'_, '_>) -> Result<(), String> {
    stand_in(path, sink, |_, _, _, _| {})
}

fn one_leaf_short(path: &Path, sink: &mut TightSink<'_, '_>) -> Result<(), String> {
    let ranges = narrowed_ranges(path)?;
    sink.set_part_cells(2)?;
    let (fields, leaves) = (ranges.len(), ranges[0].len());
    for (f, ranges) in ranges.into_iter().enumerate() {
        for (l, r) in ranges.into_iter().enumerate() {
            if (f, l) != (fields - 1, leaves - 1) {
                sink.push(r, &stand_in_parts(l, r))?;
            }
        }
    }
    Ok(())
}

fn with_nan(path: &Path, sink: &mut TightSink<'_, '_>) -> Result<(), String> {
    stand_in(path, sink, |f, l, r, _| {
        if (f, l) == (0, 0) {
            r.0 = f32::NAN;
        }
    })
}

fn with_nan_part(path: &Path, sink: &mut TightSink<'_, '_>) -> Result<(), String> {
    stand_in(path, sink, |_, l, _, parts| {
        if l == 2 {
            parts[1].1 = f32::NAN;
        }
    })
}

fn part_short(path: &Path, sink: &mut TightSink<'_, '_>) -> Result<(), String> {
    stand_in(path, sink, |f, l, _, parts| {
        if f == 1 && l == 1 {
            parts.pop();
        }
    })
}

fn failing(_: &Path, _: &mut TightSink<'_, '_>) -> Result<(), String> {
    Err("no luck".into())
}

/// Writes the test hierarchy of `seed` to `path` with `opts`.
fn write(seed: u64, path: &Path, opts: WriterOptions) -> amr_format::Result<()> {
    let spec = random_hierarchy(&mut Rng(seed), 3, 2, 3);
    let mut w = AmrkWriter::create(path, spec.clone(), opts)?;
    for (i, b) in spec.bricks.iter().enumerate() {
        for f in 0..spec.fields.len() {
            w.write_brick(i, f, &brick_values(&spec, f, b))?;
        }
    }
    w.finish().map(|_| ())
}

fn tight(f: amr_format::writer::TightFn) -> WriterOptions {
    WriterOptions {
        tight: Some(f),
        ..Default::default()
    }
}

/// A valid file storing [`narrowed`] ranges, and where its table lies.
fn file_with_ranges(seed: u64) -> (Vec<u8>, Footer) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.amrk");
    write(seed, &path, tight(narrowed)).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let footer = footer_of(&bytes);
    (bytes, footer)
}

#[test]
fn stored_ranges_read_back() {
    let dir = tempfile::tempdir().unwrap();
    let (with, without) = (dir.path().join("a.amrk"), dir.path().join("b.amrk"));
    write(1, &with, tight(narrowed)).unwrap();
    write(1, &without, WriterOptions::default()).unwrap();
    let a = AmrkFile::open(std::fs::read(&with).unwrap()).unwrap();
    let b = AmrkFile::open(std::fs::read(&without).unwrap()).unwrap();
    assert!(a.has_tight_ranges() && !b.has_tight_ranges());
    assert_eq!(a.footer().layout_version.get(), 4);
    assert_eq!((a.part_cells(), b.part_cells()), (Some(2), None));
    a.verify().unwrap();
    let want = narrowed_ranges(&without).unwrap();
    assert!(want.len() > 1, "several fields");
    let mut parts = 0;
    for (f, ranges) in want.iter().enumerate() {
        for (l, &r) in ranges.iter().enumerate() {
            assert_eq!(a.tight_range(f, l as u32), Some(r), "field {f} leaf {l}");
            assert_eq!(b.tight_range(f, l as u32), None);
            let stored: Vec<(f32, f32)> = a
                .part_ranges(f, l as u32)
                .unwrap()
                .iter()
                .map(|r| (r.min.get(), r.max.get()))
                .collect();
            assert_eq!(stored, stand_in_parts(l, r), "field {f} leaf {l}");
            assert!(b.part_ranges(f, l as u32).is_none());
            parts += stored.len();
        }
    }
    assert!(parts > 0);
    let sizes = a.section_sizes();
    let bytes = sizes
        .iter()
        .find(|(n, _)| n == "tight leaf ranges")
        .unwrap()
        .1;
    assert_eq!(bytes, (8 * a.num_leaves() * a.fields().len()) as u64);
    let bytes = sizes.iter().find(|(n, _)| n == "part bounds").unwrap().1;
    assert_eq!(bytes, (64 + 8 * (a.num_leaves() + 1) + 8 * parts) as u64);
}

#[test]
fn writer_rejects_bad_ranges_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    for (f, want) in [
        (
            one_leaf_short as amr_format::writer::TightFn,
            "leaves given",
        ),
        (with_nan, "range NaN"),
        (with_nan_part, "part 1: bound"),
        (part_short, "field 0 gave"),
        (failing, "no luck"),
    ] {
        let path = dir.path().join("bad.amrk");
        let e = write(2, &path, tight(f)).err().unwrap();
        assert!(matches!(e, FormatError::TightRanges(_)), "{e}");
        assert!(e.to_string().contains(want), "{e}");
        assert!(!path.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}

/// Replaces entry `i` of the table and reseals the checksums.
fn with_entry(bytes: &[u8], footer: &Footer, i: usize, lo: f32, hi: f32) -> Vec<u8> {
    let mut c = bytes.to_vec();
    let at = footer.tight_ranges.offset.get() as usize + 8 * i;
    let r = LeafRange {
        min: lo.into(),
        max: hi.into(),
    };
    c[at..at + 8].copy_from_slice(r.as_bytes());
    assert!(amr_format::reader::recompute_checksums(&mut c));
    c
}

#[test]
fn damaged_tables_are_errors() {
    let (b, f) = file_with_ranges(3);
    AmrkFile::open(b.clone()).unwrap();
    // A flipped bit without resealing: the metadata checksum.
    let mut c = b.clone();
    c[f.tight_ranges.offset.get() as usize] ^= 1;
    assert!(open_err(c).contains("checksum"));
    for (lo, hi) in [
        (f32::NAN, 1.0),
        (0.0, f32::NAN),
        (2.0, 1.0),
        (f32::INFINITY, 0.0),
    ] {
        let e = open_err(with_entry(&b, &f, 1, lo, hi));
        assert!(e.contains("tight range"), "{lo}..{hi}: {e}");
    }
    // The empty range of a leaf without data is allowed, as are infinite ends.
    AmrkFile::open(with_entry(&b, &f, 1, f32::INFINITY, f32::NEG_INFINITY)).unwrap();
    AmrkFile::open(with_entry(&b, &f, 1, f32::NEG_INFINITY, f32::INFINITY)).unwrap();
    // Wrong lengths and places.
    let meta = f.metadata;
    for (offset, len, want) in [
        (
            f.tight_ranges.offset.get(),
            f.tight_ranges.len.get() - 8,
            "entries need",
        ),
        (
            f.tight_ranges.offset.get(),
            f.tight_ranges.len.get() + 8,
            "entries need",
        ),
        (
            meta.offset.get() + meta.len.get(),
            8,
            "outside the metadata",
        ),
        (u64::MAX - 4, 8, "overflows"),
    ] {
        let mut c = b.clone();
        let mut g = footer_of(&c);
        g.tight_ranges.offset = offset.into();
        g.tight_ranges.len = len.into();
        let fb = g.as_bytes().to_vec();
        let at = c.len() - size_of::<Footer>();
        c[at..].copy_from_slice(&fb);
        assert!(amr_format::reader::recompute_checksums(&mut c));
        let e = open_err(c);
        assert!(e.contains(want), "{offset}+{len}: {e}");
    }
}

/// The valid file's part table record.
fn part_table(bytes: &[u8], footer: &Footer) -> PartTable {
    let at = footer.part_table.get() as usize;
    PartTable::read_from_prefix(&bytes[at..]).unwrap().0
}

/// `bytes` with `len` bytes at `at` replaced by `new`, checksums resealed.
fn patched(bytes: &[u8], at: u64, new: &[u8]) -> Vec<u8> {
    let mut c = bytes.to_vec();
    let at = at as usize;
    c[at..at + new.len()].copy_from_slice(new);
    assert!(amr_format::reader::recompute_checksums(&mut c));
    c
}

#[test]
fn damaged_part_tables_are_errors() {
    let (b, f) = file_with_ranges(5);
    let t = part_table(&b, &f);
    let file = AmrkFile::open(b.clone()).unwrap();
    let (starts, ranges) = (t.starts.offset.get(), t.ranges.offset.get());
    // A bound with a NaN, reversed, or (+inf, 0); the empty range is allowed.
    for (lo, hi, ok) in [
        (f32::NAN, 1.0, false),
        (2.0, 1.0, false),
        (f32::INFINITY, 0.0, false),
        (f32::INFINITY, f32::NEG_INFINITY, true),
    ] {
        let r = LeafRange {
            min: lo.into(),
            max: hi.into(),
        };
        let c = patched(&b, ranges + 8, r.as_bytes());
        match ok {
            true => drop(AmrkFile::open(c).unwrap()),
            false => assert!(open_err(c).contains("bound"), "{lo}..{hi}"),
        }
    }
    // Leaf starts: not from zero, decreasing, or past the ranges.
    let n = file.num_leaves() as u64;
    let e = open_err(patched(&b, starts, &1u64.to_le_bytes()));
    assert!(e.contains("start at 1"), "{e}");
    let e = open_err(patched(&b, starts + 8 * n, &0u64.to_le_bytes()));
    assert!(e.contains("end before they start"), "{e}");
    let e = open_err(patched(&b, starts + 8 * n, &u64::MAX.to_le_bytes()));
    assert!(e.contains("overflow"), "{e}");
    let total = file.part_ranges(0, n as u32 - 1).unwrap().len() as u64
        + (0..n as u32 - 1)
            .map(|l| file.part_ranges(0, l).unwrap().len() as u64)
            .sum::<u64>();
    let e = open_err(patched(&b, starts + 8 * n, &(total + 1).to_le_bytes()));
    assert!(e.contains("need"), "{e}");
    // The record: parts of 0 cells, sections of the wrong length or outside the metadata, or
    // the record itself past the metadata.
    let record = f.part_table.get();
    let e = open_err(patched(&b, record, &0u32.to_le_bytes()));
    assert!(e.contains("0 cells"), "{e}");
    let mut u = t;
    u.starts.len = (t.starts.len.get() - 8).into();
    let e = open_err(patched(&b, record, u.as_bytes()));
    assert!(e.contains("entries need"), "{e}");
    let mut u = t;
    u.ranges.offset = (u64::MAX - 4).into();
    let e = open_err(patched(&b, record, u.as_bytes()));
    assert!(e.contains("overflows"), "{e}");
    let mut g = f;
    g.part_table = (f.metadata.offset.get() + f.metadata.len.get() - 8).into();
    let mut c = b.clone();
    let at = c.len() - size_of::<Footer>();
    c[at..].copy_from_slice(g.as_bytes());
    assert!(amr_format::reader::recompute_checksums(&mut c));
    let e = open_err(c);
    assert!(e.contains("outside the metadata"), "{e}");
}
