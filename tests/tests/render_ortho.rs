//! The orthographic camera: parallel rays from the camera's plane, so that a sphere looks as
//! wide from every distance and its silhouette is the disc of its radius; the sample method
//! finds the same hits; the frame does not depend on the thread count, and a view height
//! belongs to an orthographic view only.

use amr_render::camera::{CameraError, Projection};
use amr_render::shade::IsoSpec;
use amr_render::{
    render, CameraPlacement, RenderError, Rendered, Scene, SceneOptions, TraceMethod, View,
};
use amr_synth::fields::{SPHERE_CENTRE, SPHERE_RADIUS};
use amr_synth::Case;

use crate::support::render::{blobs_scene, frame_bits, on_threads};
use crate::support::synth_file::two_level;

/// An orthographic view from `pos` looking at the sphere's centre, `height` world units tall.
fn ortho(pos: [f64; 3], height: Option<f64>, size: (u32, u32)) -> View {
    View {
        camera: Some(CameraPlacement {
            pos,
            look_at: Some(SPHERE_CENTRE),
            up: None,
        }),
        orthographic: true,
        view_height: height,
        size,
        shadows: false,
        ao_rays: 0,
        ..View::default()
    }
}

fn covered(r: &Rendered) -> Vec<bool> {
    r.frame.alpha.iter().map(|&a| a > 0.0).collect()
}

/// From 1.5 and from 4.5 units away along -y, a picture one unit tall shows the sphere as the
/// same disc of its radius, 31 pixels of 0.01: the same pixels are covered, each at the same
/// point of the surface, 3 units deeper from the farther camera. A perspective camera at the
/// nearer place shows it larger than at the farther.
#[test]
fn a_sphere_looks_as_wide_from_every_distance() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_level(dir.path(), Case::Sphere);
    let mut scene = Scene::open(&path, &SceneOptions::default()).unwrap();
    scene.set_isosurfaces(&[IsoSpec::new(0.0)]).unwrap();
    let [cx, cy, cz] = SPHERE_CENTRE;
    let (near, far) = ([cx, cy - 1.5, cz], [cx, cy - 4.5, cz]);
    let size = (100, 100);
    let a = render(&scene, &ortho(near, Some(1.0), size), &|_| ()).unwrap();
    let b = render(&scene, &ortho(far, Some(1.0), size), &|_| ()).unwrap();
    assert_eq!(covered(&a), covered(&b), "the covered pixels differ");
    let n = covered(&a).iter().filter(|&&c| c).count() as f64;
    let disc = std::f64::consts::PI * (SPHERE_RADIUS / 0.01).powi(2);
    assert!(
        (n / disc - 1.0).abs() < 0.02,
        "{n} pixels, a disc of {disc}"
    );
    for i in (0..a.frame.alpha.len()).filter(|&i| a.frame.alpha[i] > 0.0) {
        for c in 0..3 {
            let (p, q) = (a.frame.p[c][i], b.frame.p[c][i]);
            assert!((p - q).abs() < 1e-5, "pixel {i}: position {p} against {q}");
        }
        let dz = b.frame.z[i] - a.frame.z[i];
        assert!((dz - 3.0).abs() < 1e-5, "pixel {i}: depths {dz} apart");
        // Every hit lies on the sphere, at the depth its ray's plane offset gives.
        let p: Vec<f64> = (0..3)
            .map(|c| f64::from(a.frame.p[c][i]) - SPHERE_CENTRE[c])
            .collect();
        let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        assert!((r - SPHERE_RADIUS).abs() < 2e-3, "pixel {i}: radius {r}");
        let (x, y) = ((i % 100) as f64 + 0.5, (i / 100) as f64 + 0.5);
        let (ox, oz) = (0.01 * (x - 50.0), 0.01 * (50.0 - y));
        assert!(
            (p[0] - ox).abs() < 1e-6 && (p[2] - oz).abs() < 1e-6,
            "pixel {i}"
        );
    }
    let perspective = |pos: [f64; 3]| {
        let view = View {
            orthographic: false,
            view_height: None,
            fov_deg: 20.0,
            ..ortho(pos, None, size)
        };
        let r = render(&scene, &view, &|_| ()).unwrap();
        covered(&r).iter().filter(|&&c| c).count()
    };
    assert!(perspective(near) > 2 * perspective(far));
}

/// The sample method marches each orthographic ray from its own start on the camera's plane:
/// its frame of the sphere covers the hybrid method's pixels at the hybrid method's depths.
#[test]
fn the_sample_method_marches_parallel_rays_to_the_same_hits() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_level(dir.path(), Case::Sphere);
    let [cx, cy, cz] = SPHERE_CENTRE;
    let view = ortho([cx + 0.4, cy - 1.5, cz + 0.3], Some(0.9), (80, 60));
    let frame = |method| {
        let options = SceneOptions {
            method,
            ..SceneOptions::default()
        };
        let mut scene = Scene::open(&path, &options).unwrap();
        scene.set_isosurfaces(&[IsoSpec::new(0.0)]).unwrap();
        render(&scene, &view, &|_| ()).unwrap()
    };
    let (hybrid, sampled) = (frame(TraceMethod::Hybrid), frame(TraceMethod::Sample));
    let (a, b) = (covered(&hybrid), covered(&sampled));
    let n = a.iter().filter(|&&c| c).count();
    let differ = a.iter().zip(&b).filter(|(x, y)| x != y).count();
    assert!(
        n > 1000 && differ * 100 <= n,
        "{differ} of {n} pixels differ"
    );
    for i in (0..a.len()).filter(|&i| a[i] && b[i]) {
        let (p, q) = (hybrid.frame.z[i], sampled.frame.z[i]);
        assert!((p - q).abs() < 1e-4, "pixel {i}: depth {p} against {q}");
    }
}

/// With shadows, filtered ambient occlusion and several samples per pixel, an orthographic
/// frame is the same on one thread and on three, bit for bit.
#[test]
fn an_orthographic_frame_does_not_depend_on_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let scene = blobs_scene(dir.path());
    for spp in [1, 2] {
        let view = View {
            shadows: true,
            ao_rays: 1,
            spp,
            ..ortho([1.4, -0.6, 1.1], None, (96, 72))
        };
        let one = on_threads(1, || render(&scene, &view, &|_| ()).unwrap());
        let three = on_threads(3, || render(&scene, &view, &|_| ()).unwrap());
        assert!(
            one.frame.covered() > 500,
            "spp {spp}: the view shows little"
        );
        assert_eq!(
            frame_bits(&one.frame),
            frame_bits(&three.frame),
            "spp {spp}"
        );
    }
}

/// The automatic orthographic camera frames the domain as the perspective one does, from the
/// same direction; a view height asks for an orthographic view, and must be a positive length.
#[test]
fn a_view_height_belongs_to_an_orthographic_view() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_level(dir.path(), Case::Sphere);
    let scene = Scene::open(&path, &SceneOptions::default()).unwrap();
    let frame = scene.grid_frame();
    let auto = View {
        orthographic: true,
        ..View::default()
    };
    let c = auto.camera(&frame).unwrap();
    let p = View::default().camera(&frame).unwrap();
    assert!(matches!(c.projection, Projection::Orthographic { .. }));
    assert!((0..3).all(|a| (c.forward()[a] - p.forward()[a]).abs() < 1e-12));
    for corner in [[0.0; 3], [1.0; 3], [1.0, 0.0, 1.0], [0.0, 1.0, 0.0]] {
        let [x, y] = c.image_point(corner, 1024, 768).unwrap();
        assert!(
            (0.0..1024.0).contains(&x) && (0.0..768.0).contains(&y),
            "{corner:?}"
        );
    }
    // A wide field of view frames as tightly, and a view framing a box keeps the automatic
    // camera's height for the frames placed from it.
    let wide = View {
        fov_deg: 170.0,
        ..auto.clone()
    };
    let (lo, hi) = frame.world_bounds();
    let framed = wide.framing((lo, hi)).unwrap();
    for view in [&wide, &framed] {
        let c = view.camera(&frame).unwrap();
        let ys: Vec<f64> = [lo, hi]
            .iter()
            .map(|&p| c.image_point(p, 1024, 768).unwrap()[1])
            .collect();
        assert!(
            (ys[0] - ys[1]).abs() > 0.5 * 768.0,
            "{ys:?}: framed loosely"
        );
    }
    assert_eq!(
        framed.view_height,
        wide.camera(&frame).unwrap().projection_height()
    );
    let fixed = View {
        view_height: Some(0.25),
        ..auto.clone()
    };
    assert_eq!(
        fixed.camera(&frame).unwrap().projection,
        Projection::Orthographic { height: 0.25 }
    );
    let perspective = View {
        view_height: Some(0.25),
        ..View::default()
    };
    let e = perspective.validate().unwrap_err().to_string();
    assert!(e.contains("orthographic") && e.contains("--ortho"), "{e}");
    for bad in [0.0, -1.0, f64::INFINITY, f64::NAN] {
        let view = View {
            view_height: Some(bad),
            ..auto.clone()
        };
        assert!(matches!(
            view.validate(),
            Err(RenderError::Camera(CameraError::BadViewHeight(_)))
        ));
    }
}
