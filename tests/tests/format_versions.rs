//! Files of every layout version still open: a small file of each, written once by the
//! converter of that version (`amr-convert synth blobs --base 12 --brick 6 --levels 2
//! --compress`) and frozen under `tests/fixtures/`, opens, verifies, and extracts and renders
//! exactly as the others. Version 1 has no block range tables (the renderer builds them);
//! version 2 stores them; version 3 also stores each leaf's tight range (the renderer computed
//! them as it went before); version 4 also stores the bounds of the parts of large leaves
//! (its fixture, `--base 16 --brick 10`, has leaves of more than one part: with bricks of 6
//! cells there are none), and extracts as the same file written today, with or without them.

use std::path::{Path, PathBuf};

use amr_format::progress::NoProgress;
use amr_format::{AmrkFile, Compression, WriterOptions};
use amr_render::extract::{writer_options, Extractor};
use amr_render::shade::IsoSpec;
use amr_render::{render, CameraPlacement, Scene, SceneOptions, View};
use amr_synth::{write_synth, Case, SynthParams};

fn fixture(version: u32) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("tests/fixtures/blobs-v{version}.amrk"))
}

fn open(version: u32) -> AmrkFile<Vec<u8>> {
    let path = fixture(version);
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    AmrkFile::open(bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn every_version_opens_and_verifies() {
    let (v1, v2, v3) = (open(1), open(2), open(3));
    assert_eq!(v1.footer().layout_version.get(), 1);
    assert_eq!(v2.footer().layout_version.get(), 2);
    assert_eq!(v3.footer().layout_version.get(), 3);
    assert_eq!(v1.block_cells(), None, "version 1 stores no block tables");
    assert_eq!(v2.block_cells(), Some(4));
    assert_eq!(v3.block_cells(), Some(4));
    assert!(!v1.has_tight_ranges() && !v2.has_tight_ranges());
    assert!(v3.has_tight_ranges());
    v1.verify().unwrap();
    v2.verify().unwrap();
    v3.verify().unwrap();
    assert_eq!(v2.levels(), v3.levels());
    assert_eq!(v2.num_leaves(), v3.num_leaves());
    for b in 0..v2.num_bricks() {
        assert_eq!(v2.brick(b), v3.brick(b));
        assert_eq!(
            v2.brick_values(0, b).unwrap(),
            v3.brick_values(0, b).unwrap()
        );
    }
    assert_eq!(v1.levels(), v2.levels());
    assert_eq!(v1.num_bricks(), v2.num_bricks());
    assert_eq!(v1.num_leaves(), v2.num_leaves());
    for b in 0..v1.num_bricks() {
        assert_eq!(v1.brick(b), v2.brick(b));
        assert_eq!(
            v1.brick_values(0, b).unwrap(),
            v2.brick_values(0, b).unwrap()
        );
        assert!(v1.block_ranges(0, b).is_none());
        let table = v2.block_ranges(0, b).unwrap();
        let want = amr_format::blocks::block_ranges(
            &v2.brick_values(0, b).unwrap(),
            &v2.brick(b).cells,
            4,
        );
        let got: Vec<(f32, f32)> = table.iter().map(|r| (r.min.get(), r.max.get())).collect();
        assert_eq!(got, want, "brick {b}");
    }
}

#[test]
fn every_version_extracts_the_same_voxels() {
    let (v1, v2, v3) = (open(1), open(2), open(3));
    let (a, b, c) = (
        Extractor::new(&v1, 0, 64 << 20).unwrap(),
        Extractor::new(&v2, 0, 64 << 20).unwrap(),
        Extractor::new(&v3, 0, 64 << 20).unwrap(),
    );
    let mut active = 0;
    for iso in [3.0f32, 5.0, 10.0, 20.0, 50.0] {
        let (x, y, z) = (
            a.extract(iso).unwrap(),
            b.extract(iso).unwrap(),
            c.extract(iso).unwrap(),
        );
        assert_eq!(x.refs, y.refs, "iso {iso}");
        assert_eq!(x.refs, z.refs, "iso {iso}");
        assert!(
            z.stats.leaves_visited < y.stats.leaves_visited,
            "iso {iso}: the stored tight ranges skip leaves before they are visited"
        );
        active += x.refs.len();
    }
    assert!(active > 0);
}

/// The version-3 fixture's stored tight ranges hold the ranges computed from its data now
/// (equal, unless the computation has become tighter since the file was written).
#[test]
fn stored_tight_ranges_hold_the_computed_ones() {
    let v3 = open(3);
    let computed = Extractor::new(&v3, 0, 64 << 20)
        .unwrap()
        .computed_tight_ranges()
        .unwrap();
    assert_eq!(computed.len(), v3.num_leaves());
    for (leaf, &(lo, hi)) in computed.iter().enumerate() {
        let (slo, shi) = v3.tight_range(0, leaf as u32).unwrap();
        assert!(
            lo > hi || (slo <= lo && hi <= shi),
            "leaf {leaf}: stored {slo}..{shi}, computed {lo}..{hi}"
        );
    }
}

/// The synth parameters of the version-1 to -3 fixtures, and of the version-4 one.
const OLD_PARAMS: (u32, u32) = (12, 6);
const V4_PARAMS: (u32, u32) = (16, 10);

/// The fixture's hierarchy written now (`amr-convert synth blobs --base B --brick R --levels 2
/// --compress`), with the tables the converter stores, or none.
fn fresh(dir: &Path, (base, brick): (u32, u32), tables: bool) -> AmrkFile<Vec<u8>> {
    let path = dir.join(format!("fresh-{base}-{brick}-{tables}.amrk"));
    let compression = Compression::Zstd { level: 3 };
    let opts = match tables {
        true => writer_options(compression),
        false => WriterOptions {
            compression,
            tight: None,
        },
    };
    let params = SynthParams::unit_cube(2, 2, base, brick);
    write_synth(&path, Case::Blobs, &params, opts, &NoProgress).unwrap();
    AmrkFile::open(std::fs::read(&path).unwrap()).unwrap()
}

/// Each isovalue's refs and skipped parts.
fn extract_all(file: &AmrkFile<Vec<u8>>) -> Vec<(Vec<u64>, u64)> {
    let ex = Extractor::new(file, 0, 64 << 20).unwrap();
    [3.0f32, 5.0, 10.0, 20.0, 50.0]
        .map(|iso| {
            let e = ex.extract(iso).unwrap();
            (e.refs, e.stats.parts_skipped)
        })
        .into()
}

#[test]
fn frozen_files_extract_as_a_fresh_conversion() {
    let dir = tempfile::tempdir().unwrap();
    let now = fresh(dir.path(), OLD_PARAMS, true);
    assert_eq!(now.footer().layout_version.get(), 4);
    let v3 = extract_all(&open(3));
    assert_eq!(v3, extract_all(&now));
    assert!(v3.iter().any(|(refs, _)| !refs.is_empty()));

    let v4 = open(4);
    assert_eq!(v4.footer().layout_version.get(), 4);
    v4.verify().unwrap();
    assert_eq!(v4.part_cells(), Some(8));
    let ex = Extractor::new(&v4, 0, 64 << 20).unwrap();
    assert!(ex.stored_part_ranges());
    let stored = extract_all(&v4);
    // The same hierarchy written today, with its tables and without (the parts' bounds then
    // computed as the extraction goes): the same voxels, the same parts skipped.
    let with = fresh(dir.path(), V4_PARAMS, true);
    let without = fresh(dir.path(), V4_PARAMS, false);
    assert!(!Extractor::new(&without, 0, 64 << 20)
        .unwrap()
        .stored_part_ranges());
    assert_eq!(stored, extract_all(&with));
    assert_eq!(stored, extract_all(&without));
    assert!(stored.iter().map(|(_, skipped)| skipped).sum::<u64>() > 0);
}

/// The version-4 fixture's stored part bounds hold the ones computed from its data now (equal,
/// unless the computation has become tighter since the file was written).
#[test]
fn stored_part_bounds_hold_the_computed_ones() {
    let v4 = open(4);
    let mut parts = 0;
    Extractor::new(&v4, 0, 64 << 20)
        .unwrap()
        .computed_tables(|leaf, _, computed| {
            let stored = v4.part_ranges(0, leaf).unwrap();
            assert_eq!(stored.len(), computed.len(), "leaf {leaf}");
            for (p, (s, &(lo, hi))) in stored.iter().zip(computed).enumerate() {
                let (slo, shi) = (s.min.get(), s.max.get());
                assert!(
                    lo > hi || (slo <= lo && hi <= shi),
                    "leaf {leaf} part {p}: stored {slo}..{shi}, computed {lo}..{hi}"
                );
            }
            parts += computed.len();
            Ok(())
        })
        .unwrap();
    assert!(parts > 0);
}

#[test]
fn every_version_renders_the_same_frame() {
    let view = View {
        camera: Some(CameraPlacement {
            pos: [2.5, -1.5, 2.0],
            look_at: None,
            up: None,
        }),
        size: (48, 36),
        ao_rays: 1,
        ..View::default()
    };
    let frames: Vec<_> = [1, 2, 3]
        .map(|v| {
            let mut scene = Scene::open(&fixture(v), &SceneOptions::default()).unwrap();
            scene.set_isosurfaces(&[IsoSpec::new(10.0)]).unwrap();
            render(&scene, &view, &|_| {}).unwrap().frame
        })
        .into();
    assert!(frames[0].covered() > 0);
    for other in &frames[1..] {
        assert_eq!(frames[0].z, other.z);
        assert_eq!(frames[0].rgb, other.rgb);
    }
}

/// A stand-in for the converter's tables that stores one part bound per leaf, in the renderer's
/// part size: valid to the format, but no leaf of the version-4 fixture's hierarchy has exactly
/// one part (a leaf has none, or at least two).
fn one_part_per_leaf(path: &Path, sink: &mut amr_format::TightSink<'_, '_>) -> Result<(), String> {
    let file = AmrkFile::open(std::fs::read(path).map_err(|e| e.to_string())?)
        .map_err(|e| e.to_string())?;
    let k = file
        .block_cells()
        .and_then(amr_render::extract::parts::part_cells);
    sink.set_part_cells(k.ok_or("no block tables")?)?;
    for field in 0..file.fields().len() {
        for leaf in 0..file.num_leaves() as u32 {
            let range = file.leaf_range(field, leaf);
            sink.push(range, &[range])?;
        }
    }
    Ok(())
}

#[test]
fn stored_part_counts_unlike_the_leaves_layout_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("counts.amrk");
    let opts = WriterOptions {
        compression: Compression::None,
        tight: Some(one_part_per_leaf),
    };
    let (base, brick) = V4_PARAMS;
    let params = SynthParams::unit_cube(2, 2, base, brick);
    write_synth(&path, Case::Blobs, &params, opts, &NoProgress).unwrap();
    let file = AmrkFile::open(std::fs::read(&path).unwrap()).unwrap();
    let err = Extractor::new(&file, 0, 64 << 20).err().expect("refused");
    assert!(err.to_string().contains("part bounds"), "{err}");
}
