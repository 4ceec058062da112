//! Cut-aways and view-limited extraction (issue 17, goal 4): a clip box opens a sphere so that
//! rays see its inner side behind the cut, shadow and occlusion rays see only the cut surface, and a scene
//! extracted inside a view's frustum (perspective or orthographic) renders that view bit for bit
//! as the whole extraction does when no shadow or ambient-occlusion ray leaves the view.

use amr_render::output::frame::FrameBuffer;
use amr_render::reconstruct::Reconstruction;
use amr_render::shade::IsoSpec;
use amr_render::trace::{ClippedTracer, GridRay, HybridTracer, Tracer};
use amr_render::{render, CameraPlacement, ClipBox, Rendered, Scene, SceneOptions, View};
use amr_synth::fields::{SPHERE_CENTRE, SPHERE_RADIUS};
use amr_synth::Case;

use crate::support::synth_file::two_level;

fn looking_from(pos: [f64; 3], look_at: [f64; 3], fov_deg: f64) -> View {
    View {
        camera: Some(CameraPlacement {
            pos,
            look_at: Some(look_at),
            up: None,
        }),
        fov_deg,
        size: (64, 48),
        shadows: false,
        ao_rays: 0,
        ..View::default()
    }
}

fn centre_pixel(r: &Rendered) -> usize {
    let (w, h) = (r.frame.width as usize, r.frame.height as usize);
    h / 2 * w + w / 2
}

#[test]
fn a_clip_box_opens_the_sphere_onto_its_inner_side() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_level(dir.path(), Case::Sphere);
    let [cx, cy, cz] = SPHERE_CENTRE;
    let eye = [cx + 3.0, cy, cz];
    let view = looking_from(eye, SPHERE_CENTRE, 30.0);
    let mut scene = Scene::open(&path, &SceneOptions::default()).unwrap();
    scene.set_isosurfaces(&[IsoSpec::new(0.0)]).unwrap();
    let whole = render(&scene, &view, &|_| {}).unwrap();
    let whole_active = scene.stats().active_octants;

    // Keep the half x <= cx: the camera, on the +x side, looks into the sphere through the cut.
    let clip = ClipBox::new([-1.0, -1.0, -1.0], [cx, 2.0, 2.0]).unwrap();
    let stats = scene.set_clip(Some(clip)).unwrap();
    assert_eq!(stats.surfaces_built, 1, "a new clip box extracts again");
    let active = scene.stats().active_octants;
    assert!(
        active < whole_active * 3 / 4 && active > whole_active / 4,
        "{active} of {whole_active} voxels kept by half the domain"
    );
    let cut = render(&scene, &view, &|_| {}).unwrap();

    let i = centre_pixel(&whole);
    let near = 3.0 - SPHERE_RADIUS;
    let far = 3.0 + SPHERE_RADIUS;
    assert!(
        (f64::from(whole.frame.z[i]) - near).abs() < 0.02,
        "{}",
        whole.frame.z[i]
    );
    assert!(
        (f64::from(cut.frame.z[i]) - far).abs() < 0.02,
        "{}",
        cut.frame.z[i]
    );
    assert!(whole.frame.n[0][i] > 0.9, "the outer side faces the camera");
    assert!(
        cut.frame.n[0][i] < -0.9,
        "the inner side faces away from it"
    );
    // Every covered pixel of the cut frame sees the inner side: nothing of the removed half
    // (x > cx) is drawn, and the silhouette is the same disc.
    let mut covered = 0;
    for k in 0..cut.frame.z.len() {
        let seen = cut.frame.z[k].is_finite();
        assert_eq!(seen, whole.frame.z[k].is_finite(), "pixel {k}: silhouette");
        if seen {
            let x = f64::from(cut.frame.p[0][k]) + cut.frame.p_origin[0];
            assert!(x <= cx + 1e-6, "pixel {k}: hit at x = {x} outside the box");
            assert!(
                cut.frame.z[k] > whole.frame.z[k],
                "pixel {k}: not behind the cut"
            );
            covered += 1;
        }
    }
    assert!(covered > 100, "{covered} pixels show the sphere");

    // A box that misses the domain is refused, and the scene keeps its clip.
    let away = ClipBox::new([2.0; 3], [3.0; 3]).unwrap();
    let e = scene.set_clip(Some(away)).unwrap_err().to_string();
    assert!(
        e.contains("does not overlap the domain") && e.contains("sphere.amrk"),
        "{e}"
    );
    assert_eq!(scene.clip(), Some(clip));

    // Removing the clip gives the whole surface back.
    scene.set_clip(None).unwrap();
    assert_eq!(scene.stats().active_octants, whole_active);
    let again = render(&scene, &view, &|_| {}).unwrap();
    assert!(same_bits(&again.frame, &whole.frame));
}

#[test]
fn shadow_and_occlusion_rays_see_only_the_cut_surface() {
    // The shader asks the same tracer for shadow and ambient-occlusion rays (`occluded`) as for
    // primary rays (`next_hit`); cut, both see nothing of the removed half.
    let dir = tempfile::tempdir().unwrap();
    let path = two_level(dir.path(), Case::Sphere);
    let mut scene = Scene::open(&path, &SceneOptions::default()).unwrap();
    scene.set_isosurfaces(&[IsoSpec::new(0.0)]).unwrap();
    let whole = HybridTracer {
        src: scene.source(),
        surfaces: scene.surfaces(),
        sources: &[],
        smooth_normals: true,
    };
    let frame = whole.frame();
    let (lo, hi) = ClipBox::new([-1.0; 3], [SPHERE_CENTRE[0], 2.0, 2.0])
        .unwrap()
        .to_grid(&frame);
    let cut = ClippedTracer {
        inner: &whole,
        lo,
        hi,
    };
    let from_centre = |d: [f64; 3]| GridRay::from_world(&frame, SPHERE_CENTRE, d);
    let (plus_x, minus_x) = (from_centre([1.0, 0.0, 0.0]), from_centre([-1.0, 0.0, 0.0]));
    let inf = f64::INFINITY;
    assert!(whole.occluded(0, &plus_x, 0.0, inf));
    assert!(
        !cut.occluded(0, &plus_x, 0.0, inf),
        "the removed half shadows"
    );
    assert!(cut.next_hit(0, &plus_x, 0.0, inf).is_none());
    assert!(whole.occluded(0, &minus_x, 0.0, inf));
    assert!(
        cut.occluded(0, &minus_x, 0.0, inf),
        "the kept half must still shadow"
    );
    let h = cut.next_hit(0, &minus_x, 0.0, inf).unwrap();
    assert!((h.t - SPHERE_RADIUS).abs() < 0.01, "{h:?}");
}

/// True when every channel of `a` and `b` holds the same bits.
fn same_bits(a: &FrameBuffer, b: &FrameBuffer) -> bool {
    let eq = |x: &[f32], y: &[f32]| {
        x.len() == y.len() && x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits())
    };
    (0..3).all(|c| eq(&a.rgb[c], &b.rgb[c]) && eq(&a.n[c], &b.n[c]) && eq(&a.p[c], &b.p[c]))
        && eq(&a.alpha, &b.alpha)
        && eq(&a.z, &b.z)
        && eq(&a.level, &b.level)
        && eq(&a.color_value, &b.color_value)
}

#[test]
fn view_limited_extraction_renders_the_view_as_the_whole_one() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_level(dir.path(), Case::Blobs);
    for reconstruction in [Reconstruction::Octant, Reconstruction::Current] {
        let options = SceneOptions {
            reconstruction,
            ..SceneOptions::default()
        };
        let isos = [
            IsoSpec::new(10.0),
            IsoSpec {
                opacity: 0.4,
                ..IsoSpec::new(5.0)
            },
        ];
        let mut whole = Scene::open(&path, &options).unwrap();
        whole.set_isosurfaces(&isos).unwrap();
        let mut limited = Scene::open(&path, &options).unwrap();
        let views = [
            looking_from([0.9, -0.3, 0.7], [0.45, 0.45, 0.45], 20.0),
            looking_from([0.2, 0.5, 1.4], [0.3, 0.5, 0.5], 15.0),
            View {
                spp: 3,
                ..looking_from([1.6, 1.5, 0.2], [0.6, 0.5, 0.5], 25.0)
            },
            View {
                orthographic: true,
                view_height: Some(0.3),
                ..looking_from([0.2, -0.4, 0.9], [0.35, 0.45, 0.5], 40.0)
            },
            View {
                orthographic: true,
                spp: 2,
                ..looking_from([0.7, 1.2, 0.3], [0.55, 0.5, 0.45], 30.0)
            },
        ];
        for (k, view) in views.iter().enumerate() {
            limited.set_extract_view(Some(view)).unwrap();
            limited.set_isosurfaces(&isos).unwrap();
            let ctx = format!("{reconstruction} view {k}");
            let (a, b) = (whole.stats().active_octants, limited.stats().active_octants);
            assert!(
                b < a,
                "{ctx}: {b} of {a} voxels: the view does not limit anything"
            );
            let want = render(&whole, view, &|_| {}).unwrap();
            let got = render(&limited, view, &|_| {}).unwrap();
            assert!(want.frame.covered() > 50, "{ctx}: the view shows little");
            assert!(same_bits(&got.frame, &want.frame), "{ctx}: frames differ");
        }
        let other = looking_from([2.0, 2.0, 2.0], [0.5; 3], 40.0);
        let e = render(&limited, &other, &|_| {}).unwrap_err().to_string();
        assert!(e.contains("another view"), "{e}");
        limited.set_extract_view(None).unwrap();
        assert_eq!(limited.stats().active_octants, whole.stats().active_octants);
    }
}

/// A point inside the sphere is enclosed by it (every ray from it meets the surface), a point
/// outside is not, nor is the centre once a clip box cuts the sphere open; a second surface
/// that does not enclose the point is passed over for the one that does.
#[test]
fn the_enclosing_surface_of_a_point_is_the_closed_one_around_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_level(dir.path(), Case::Sphere);
    let [cx, cy, cz] = SPHERE_CENTRE;
    let view = looking_from([cx + 3.0, cy, cz], SPHERE_CENTRE, 30.0);
    let mut scene = Scene::open(&path, &SceneOptions::default()).unwrap();
    scene.set_isosurfaces(&[IsoSpec::new(0.0)]).unwrap();
    let inside = [cx + 0.5 * SPHERE_RADIUS, cy, cz];
    let outside = [cx + 1.2 * SPHERE_RADIUS, cy, cz];
    assert_eq!(
        amr_render::enclosing_surface(&scene, &view, SPHERE_CENTRE).unwrap(),
        Some(0)
    );
    assert_eq!(
        amr_render::enclosing_surface(&scene, &view, inside).unwrap(),
        Some(0)
    );
    assert_eq!(
        amr_render::enclosing_surface(&scene, &view, outside).unwrap(),
        None
    );

    // The smaller sphere (distance -0.1) encloses the centre too; a larger one's (0.5) surface
    // leaves the domain, which cuts it open.
    scene
        .set_isosurfaces(&[IsoSpec::new(0.5), IsoSpec::new(-0.1)])
        .unwrap();
    let between = [cx + 0.85 * SPHERE_RADIUS, cy, cz];
    assert_eq!(
        amr_render::enclosing_surface(&scene, &view, SPHERE_CENTRE).unwrap(),
        Some(1)
    );
    assert_eq!(
        amr_render::enclosing_surface(&scene, &view, between).unwrap(),
        None
    );

    scene.set_isosurfaces(&[IsoSpec::new(0.0)]).unwrap();
    let clip = ClipBox::new([-1.0, -1.0, -1.0], [cx, 2.0, 2.0]).unwrap();
    scene.set_clip(Some(clip)).unwrap();
    assert_eq!(
        amr_render::enclosing_surface(&scene, &view, SPHERE_CENTRE).unwrap(),
        None
    );
}
