//! Files of every layout version still open: a small file of each, written once by the
//! converter of that version (`amr-convert synth blobs --base 12 --brick 6 --levels 2
//! --compress`) and frozen under `tests/fixtures/`, opens, verifies, and extracts and renders
//! exactly as the others. Version 1 has no block range tables (the renderer builds them);
//! version 2 stores them; version 3 also stores each leaf's tight range (the renderer computed
//! them as it went before).

use std::path::{Path, PathBuf};

use amr_format::AmrkFile;
use amr_render::extract::Extractor;
use amr_render::shade::IsoSpec;
use amr_render::{render, CameraPlacement, Scene, SceneOptions, View};

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
