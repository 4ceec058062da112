//! Tight leaf ranges (layout version 3): the writer stores what its computation gives, readers
//! read them back, and a damaged or hostile table is an error at open, never a panic.

mod common;

use std::path::Path;

use amr_format::raw::{Footer, LeafRange};
use amr_format::{AmrkFile, AmrkWriter, FormatError, WriterOptions};
use common::*;
use zerocopy::IntoBytes;

/// A stand-in for the renderer's computation: each leaf's stored (conservative) range, a
/// little narrowed so that the stored table is told apart from it; no range for leaves
/// without data.
fn narrowed(path: &Path) -> Result<Vec<Vec<(f32, f32)>>, String> {
    let file = AmrkFile::open(std::fs::read(path).map_err(|e| e.to_string())?)
        .map_err(|e| e.to_string())?;
    assert!(
        !file.has_tight_ranges(),
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

fn one_leaf_short(path: &Path) -> Result<Vec<Vec<(f32, f32)>>, String> {
    let mut t = narrowed(path)?;
    t[0].pop();
    Ok(t)
}

fn with_nan(path: &Path) -> Result<Vec<Vec<(f32, f32)>>, String> {
    let mut t = narrowed(path)?;
    t[0][0].0 = f32::NAN;
    Ok(t)
}

fn failing(_: &Path) -> Result<Vec<Vec<(f32, f32)>>, String> {
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
    assert_eq!(a.footer().layout_version.get(), 3);
    a.verify().unwrap();
    let want = narrowed(&without).unwrap();
    for (f, ranges) in want.iter().enumerate() {
        for (l, &r) in ranges.iter().enumerate() {
            assert_eq!(a.tight_range(f, l as u32), Some(r), "field {f} leaf {l}");
            assert_eq!(b.tight_range(f, l as u32), None);
        }
    }
    let sizes = a.section_sizes();
    let bytes = sizes
        .iter()
        .find(|(n, _)| n == "tight leaf ranges")
        .unwrap()
        .1;
    assert_eq!(bytes, (8 * a.num_leaves() * a.fields().len()) as u64);
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
