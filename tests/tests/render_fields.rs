//! Isosurfaces of several fields in one scene (`IsoSpec::field`): each surface is the one its own
//! field's scene draws, the nearer of two hides the farther, and what cannot be done is refused.

use std::path::{Path, PathBuf};

use amr_render::shade::IsoSpec;
use amr_render::view::CameraPlacement;
use amr_render::{render, Rendered, Scene, SceneOptions, TraceMethod, View};
use amr_synth::SynthParams;

use crate::support::synth_file::sphere_and_ramp;

/// A two-level file with fields `sphere` (refined around its zero surface) and `ramp`, a plane
/// wave across it.
fn two_fields(dir: &Path) -> PathBuf {
    let ramp = |p: [f64; 3]| p[0] + 0.5 * p[1] + 0.25 * p[2];
    sphere_and_ramp(dir, &SynthParams::unit_cube(2, 2, 16, 8), &ramp)
}

fn open(path: &Path, field: &str) -> Scene {
    let options = SceneOptions {
        field: Some(field.into()),
        ..SceneOptions::default()
    };
    Scene::open(path, &options).unwrap()
}

fn spec(value: f32, color: [f32; 3], field: Option<usize>) -> IsoSpec {
    IsoSpec {
        color: Some(color),
        field,
        ..IsoSpec::new(value)
    }
}

/// One camera for every scene, smooth normals, no shadows or ambient occlusion (which would let
/// one surface darken the other).
fn view() -> View {
    View {
        size: (160, 120),
        ao_rays: 0,
        shadows: false,
        camera: Some(CameraPlacement {
            pos: [1.6, -1.1, 1.3],
            look_at: Some([0.5, 0.5, 0.5]),
            up: Some([0.0, 0.0, 1.0]),
        }),
        ..View::default()
    }
}

const GOLD: [f32; 3] = [0.85, 0.62, 0.35];
const BLUE: [f32; 3] = [0.35, 0.55, 0.85];

/// A scene of `path`'s `sphere` field with its zero surface (gold) and the `ramp = 1` plane
/// (blue), and the index of `ramp`.
fn sphere_and_plane(path: &Path) -> (Scene, usize) {
    let mut scene = open(path, "sphere");
    let ramp = scene.file().field_index("ramp").unwrap();
    scene
        .set_isosurfaces(&[spec(0.0, GOLD, None), spec(1.0, BLUE, Some(ramp))])
        .unwrap();
    (scene, ramp)
}

#[test]
fn each_surface_is_what_its_own_fields_scene_draws() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let (both, _) = sphere_and_plane(&path);
    let mut sphere = open(&path, "sphere");
    sphere.set_isosurfaces(&[spec(0.0, GOLD, None)]).unwrap();
    let mut plane = open(&path, "ramp");
    plane.set_isosurfaces(&[spec(1.0, BLUE, None)]).unwrap();

    let (a, b) = (sphere.stats().active_octants, plane.stats().active_octants);
    assert!(a > 1000 && b > 1000, "{a} and {b} active voxels");
    assert_eq!(both.stats().active_octants, a + b);
    assert_eq!(both.surface_field_name(&both.isosurfaces()[1]), "ramp");
    assert!(!both.one_field());

    let v = view();
    let frames: Vec<Rendered> = [&both, &sphere, &plane]
        .iter()
        .map(|s| render(s, &v, &|_| ()).unwrap())
        .collect();
    let (f, s, p) = (&frames[0].frame, &frames[1].frame, &frames[2].frame);
    let (mut from_sphere, mut from_plane) = (0, 0);
    for i in 0..f.alpha.len() {
        let (zs, zp) = (s.z[i], p.z[i]);
        // The nearer surface, where one is clearly nearer (`z` is infinite on a miss).
        let nearer = match (zs < zp * 0.999, zp < zs * 0.999) {
            (true, false) => s,
            (false, true) => p,
            _ => continue,
        };
        if std::ptr::eq(nearer, s) {
            from_sphere += 1;
        } else {
            from_plane += 1;
        }
        assert_eq!(f.z[i], nearer.z[i], "pixel {i}: depth");
        for c in 0..3 {
            assert_eq!(f.rgb[c][i], nearer.rgb[c][i], "pixel {i}: colour");
            assert_eq!(f.n[c][i], nearer.n[c][i], "pixel {i}: normal");
        }
    }
    assert!(
        from_sphere > 1000 && from_plane > 1000,
        "{from_sphere} pixels of the sphere, {from_plane} of the plane"
    );
}

#[test]
fn a_surface_of_another_field_is_kept_while_its_field_and_value_stay() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let (mut scene, ramp) = sphere_and_plane(&path);
    let again = scene
        .set_isosurfaces(&[spec(0.0, BLUE, None), spec(1.0, GOLD, Some(ramp))])
        .unwrap();
    assert_eq!(again.surfaces_built, 0, "recoloured surfaces are kept");
    // The same value of the scene's own field is another surface.
    let moved = scene
        .set_isosurfaces(&[spec(0.0, GOLD, None), spec(1.0, BLUE, None)])
        .unwrap();
    assert_eq!(moved.surfaces_built, 1);
}

#[test]
fn what_a_scene_of_several_fields_cannot_do_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let mut scene = open(&path, "sphere");
    let err = scene
        .set_isosurfaces(&[spec(0.0, GOLD, Some(7))])
        .unwrap_err()
        .to_string();
    assert!(err.contains("field 7") && err.contains("two.amrk"), "{err}");
}

/// The sample method marches each surface through its own field's reconstruction (refused
/// until 2026-12-07): a scene of two fields sampled shows both surfaces where the hybrid method
/// does, each in its colour, and frames them alike.
#[test]
fn the_sample_method_traces_surfaces_of_several_fields() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let (hybrid, ramp) = sphere_and_plane(&path);
    let options = SceneOptions {
        field: Some("sphere".into()),
        method: TraceMethod::Sample,
        ..SceneOptions::default()
    };
    let mut sampled = Scene::open(&path, &options).unwrap();
    sampled
        .set_isosurfaces(&[spec(0.0, GOLD, None), spec(1.0, BLUE, Some(ramp))])
        .unwrap();
    assert_eq!(
        sampled.surface_bounds().unwrap(),
        hybrid.surface_bounds().unwrap()
    );
    let frame = |scene: &Scene| render(scene, &view(), &|_| ()).unwrap();
    let (a, b) = (frame(&hybrid), frame(&sampled));
    let f = &a.frame;
    let (mut agree, mut covered, mut gold, mut blue) = (0, 0, 0, 0);
    for i in 0..f.len() {
        if !f.z[i].is_finite() {
            continue;
        }
        covered += 1;
        let near = (f.z[i] - b.frame.z[i]).abs() < 1e-4;
        let same_colour = (0..3).all(|c| (f.rgb[c][i] - b.frame.rgb[c][i]).abs() < 0.03);
        if near && same_colour {
            agree += 1;
            // The blue surface is the one whose blue outweighs its red.
            match f.rgb[2][i] > f.rgb[0][i] {
                true => blue += 1,
                false => gold += 1,
            }
        }
    }
    assert!(
        agree * 100 >= covered * 98,
        "{agree} of {covered} pixels alike"
    );
    assert!(
        gold > 500 && blue > 500,
        "{gold} gold and {blue} blue pixels"
    );
}

/// A surface of another field painted by that field (one source traces and paints it) shows its
/// own isovalue, while the scene's surface painted by it shows other values.
#[test]
fn a_surface_painted_by_its_own_field_shows_its_isovalue() {
    use amr_render::ColorBy;
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let (mut scene, _) = sphere_and_plane(&path);
    let by = Some(ColorBy::Field("ramp".into()));
    scene.set_color_by(&[by.clone(), by]).unwrap();
    let f = render(&scene, &view(), &|_| ()).unwrap().frame;
    let mut plane = open(&path, "ramp");
    plane.set_isosurfaces(&[spec(1.0, BLUE, None)]).unwrap();
    let p = render(&plane, &view(), &|_| ()).unwrap().frame;
    let (mut on_plane, mut elsewhere) = (0, 0);
    for i in 0..f.alpha.len() {
        let v = f.color_value[i];
        if !v.is_finite() {
            continue;
        }
        if f.z[i] == p.z[i] {
            on_plane += 1;
            assert!(
                (v - 1.0).abs() < 1e-3,
                "pixel {i}: {v} on the ramp = 1 surface"
            );
        } else if (v - 1.0).abs() > 0.05 {
            elsewhere += 1;
        }
    }
    assert!(
        on_plane > 1000 && elsewhere > 100,
        "{on_plane} / {elsewhere}"
    );
}

/// A painted frame with a slice rendered in rectangles (as `mpirun`'s replicated mode renders
/// tiles) equals the whole frame, every channel bit for bit, when the rectangles are handed the
/// frame's colour ranges found once (`frame_painting`); ranges of another frame are refused.
#[test]
fn regions_of_a_painted_frame_with_the_frames_ranges_equal_the_whole_frame() {
    use amr_render::slice::Slice;
    use amr_render::{frame_painting, render_region, ColorBy, FramePainting, Rect};
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let (mut scene, _) = sphere_and_plane(&path);
    let by = Some(ColorBy::Field("ramp".into()));
    scene.set_color_by(&[by, Some(ColorBy::Level)]).unwrap();
    let slice = Slice::parse_axis("z=0.4:0.7").unwrap();
    scene
        .set_slices(&[slice], Some(ColorBy::Field("sphere".into())))
        .unwrap();
    let v = view();
    let whole = render(&scene, &v, &|_| ()).unwrap();
    let painting = frame_painting(&scene, &v).unwrap();
    assert_eq!(painting.color_ranges, whole.color_ranges);
    assert_eq!(
        painting.color_ranges.len(),
        2,
        "{:?}",
        painting.color_ranges
    );
    let f = &whole.frame;
    let (w, h) = v.size;
    let mut painted = 0;
    let mut levels = std::collections::BTreeSet::new();
    for (x0, x1) in [(0, 33), (33, 160)] {
        for (y0, y1) in [(0, 1), (1, 64), (64, 120)] {
            let rect = Rect {
                x0,
                y0,
                width: x1 - x0,
                height: y1 - y0,
            };
            let region = render_region(&scene, &v, &painting, rect).unwrap();
            levels.extend(region.painted_levels.iter().copied());
            for (k, p) in region.pixels.iter().enumerate() {
                let (x, y) = (x0 + k as u32 % rect.width, y0 + k as u32 / rect.width);
                let want = sample_bits(&f.sample((y * w + x) as usize));
                assert_eq!(want, sample_bits(p), "pixel {x},{y} of {w}x{h}");
                painted += usize::from(p.color_value.is_finite());
            }
        }
    }
    assert!(painted > 1000, "{painted} painted pixels");
    let levels: Vec<u32> = levels.into_iter().collect();
    assert_eq!(Some(levels), whole.painted_levels);
    let unpainted = FramePainting::default();
    let rect = Rect {
        x0: 0,
        y0: 0,
        width: 4,
        height: 4,
    };
    let refused = render_region(&scene, &v, &unpainted, rect);
    assert!(refused.is_err(), "{refused:?}");
}

/// Every channel of a pixel, as bits.
fn sample_bits(p: &amr_render::output::PixelSample) -> Vec<u32> {
    let mut v = p.rgb.to_vec();
    v.extend([p.alpha, p.z, p.level, p.color_value]);
    v.extend(p.n);
    v.extend(p.p);
    v.iter().map(|x| x.to_bits()).collect()
}
