//! Files of every layout version still open: a small file of each, written once by the
//! converter of that version (`amr-convert synth blobs --base 12 --brick 6 --levels 2
//! --compress`) and frozen under `tests/fixtures/`, opens, verifies, and extracts and renders
//! exactly as the other. Version 1 has no block range tables (the renderer builds them);
//! version 2 stores them.

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
    let (v1, v2) = (open(1), open(2));
    assert_eq!(v1.footer().layout_version.get(), 1);
    assert_eq!(v2.footer().layout_version.get(), 2);
    assert_eq!(v1.block_cells(), None, "version 1 stores no block tables");
    assert_eq!(v2.block_cells(), Some(4));
    v1.verify().unwrap();
    v2.verify().unwrap();
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
    let (v1, v2) = (open(1), open(2));
    let (a, b) = (
        Extractor::new(&v1, 0, 64 << 20).unwrap(),
        Extractor::new(&v2, 0, 64 << 20).unwrap(),
    );
    let mut active = 0;
    for iso in [3.0f32, 5.0, 10.0, 20.0, 50.0] {
        let (x, y) = (a.extract(iso).unwrap(), b.extract(iso).unwrap());
        assert_eq!(x.refs, y.refs, "iso {iso}");
        active += x.refs.len();
    }
    assert!(active > 0);
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
    let frames: Vec<_> = [1, 2]
        .map(|v| {
            let mut scene = Scene::open(&fixture(v), &SceneOptions::default()).unwrap();
            scene.set_isosurfaces(&[IsoSpec::new(10.0)]).unwrap();
            render(&scene, &view, &|_| {}).unwrap().frame
        })
        .into();
    assert!(frames[0].covered() > 0);
    assert_eq!(frames[0].z, frames[1].z);
    assert_eq!(frames[0].rgb, frames[1].rgb);
}
