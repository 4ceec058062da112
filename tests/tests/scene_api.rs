//! The library's scene: a camera change costs a frame and no extraction, an isovalue change
//! re-extracts only the surfaces that changed, and the frames equal those of a fresh scene.

use amr_render::shade::IsoSpec;
use amr_render::{render, CameraPlacement, RenderError, Scene, SceneOptions, View};
use amr_synth::Case;

use crate::support::synth_file::two_level;

/// A two-level blobs file in `dir`.
fn blobs(dir: &std::path::Path) -> std::path::PathBuf {
    two_level(dir, Case::Blobs)
}

fn view(pos: [f64; 3]) -> View {
    View {
        camera: Some(CameraPlacement {
            pos,
            look_at: None,
            up: None,
        }),
        size: (48, 36),
        ao_rays: 1,
        ..View::default()
    }
}

#[test]
fn views_and_isovalue_changes_reuse_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let path = blobs(dir.path());
    let mut scene = Scene::open(&path, &SceneOptions::default()).unwrap();
    let (a, b) = (IsoSpec::new(10.0), IsoSpec::new(5.0));
    assert_eq!(scene.set_isosurfaces(&[a, b]).unwrap().surfaces_built, 2);
    let active = scene.stats().active_octants;
    assert!(active > 0);

    let first = render(&scene, &view([2.5, -1.5, 2.0]), &|_| {}).unwrap();
    let second = render(&scene, &view([-1.5, 2.5, 1.0]), &|_| {}).unwrap();
    assert!(first.frame.covered() > 0 && second.frame.covered() > 0);
    assert_ne!(
        first.frame.z, second.frame.z,
        "a new camera gives a new frame"
    );
    assert_eq!(
        scene.stats().active_octants,
        active,
        "rendering leaves the scene alone"
    );

    // Recolouring keeps both surfaces; a new isovalue builds one.
    let recoloured = IsoSpec {
        color: Some([1.0, 0.0, 0.0]),
        ..a
    };
    assert_eq!(
        scene
            .set_isosurfaces(&[recoloured, b])
            .unwrap()
            .surfaces_built,
        0
    );
    let stats = scene.set_isosurfaces(&[a, IsoSpec::new(7.0)]).unwrap();
    assert_eq!(stats.surfaces_built, 1);

    // The kept surface renders as in a fresh scene.
    let mut fresh = Scene::open(&path, &SceneOptions::default()).unwrap();
    fresh.set_isosurfaces(&[a, IsoSpec::new(7.0)]).unwrap();
    let v = view([2.5, -1.5, 2.0]);
    let kept = render(&scene, &v, &|_| {}).unwrap();
    let new = render(&fresh, &v, &|_| {}).unwrap();
    assert_eq!(kept.frame.rgb, new.frame.rgb);
    assert_eq!(kept.frame.z, new.frame.z);
}

#[test]
fn scene_errors_name_the_file_once() {
    let dir = tempfile::tempdir().unwrap();
    let path = blobs(dir.path());
    let options = SceneOptions {
        field: Some("nope".into()),
        ..SceneOptions::default()
    };
    let e = Scene::open(&path, &options).err().expect("no such field");
    let msg = e.to_string();
    assert!(matches!(e, RenderError::InFile { .. }), "{msg}");
    assert_eq!(msg.matches("blobs.amrk").count(), 1, "{msg}");
    assert!(msg.contains("no field 'nope' (fields: blobs)"), "{msg}");

    let mut scene = Scene::open(&path, &SceneOptions::default()).unwrap();
    let e = scene
        .set_isosurfaces(&[IsoSpec::new(f32::NAN)])
        .unwrap_err();
    assert!(e.to_string().contains("not a finite number"), "{e}");
}
