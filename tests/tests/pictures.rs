//! Pictures (issue 18) checked against the analytic fields they show, on a two-field file
//! (`sphere`: the signed distance to a sphere; `ramp = x + 2y`, linear, so that every
//! reconstruction reproduces it exactly): a surface painted by a second field has that field's
//! colour at each hit, a slice shows the field at each of its points, outlines are drawn where the
//! domain's edges project and nowhere else, and the default field skips round-off.

use std::path::{Path, PathBuf};

use amr_format::WriterOptions;
use amr_render::camera::Camera;
use amr_render::colormap::{level_srgb8, oklab_distance};
use amr_render::outline::LevelColors;
use amr_render::output::legend::{Legend, Swatch};
use amr_render::output::png_preview::{display_srgb8, preview_rgb8};
use amr_render::output::Background;
use amr_render::shade::IsoSpec;
use amr_render::{
    render, CameraPlacement, ColorBy, ColorScale, Colormap, Outline, Rendered, Scene, SceneOptions,
    Slice, View,
};
use amr_synth::{build_hierarchy, write_fields, AnalyticField, Case, SynthParams};

use crate::support::golden::assert_matches_golden;
use crate::support::synth_file::sphere_and_ramp;

/// Size of a coarse cell of the fixture.
const COARSE: f64 = 1.0 / 16.0;

fn ramp(p: [f64; 3]) -> f64 {
    p[0] + 2.0 * p[1]
}

/// A two-level file of fields `sphere`, refined around the sphere, and `ramp`.
fn two_fields(dir: &Path) -> PathBuf {
    sphere_and_ramp(dir, &SynthParams::unit_cube(2, 2, 16, 8), &ramp)
}

fn scene(path: &Path) -> Scene {
    let options = SceneOptions {
        field: Some("sphere".into()),
        ..SceneOptions::default()
    };
    Scene::open(path, &options).unwrap()
}

/// [`scene`] of `path` with the sphere's zero surface painted by `ramp`.
fn painted_by_ramp(path: &Path) -> Scene {
    let mut scene = scene(path);
    scene.set_isosurfaces(&[IsoSpec::new(0.0)]).unwrap();
    scene
        .set_color_by(&[Some(ColorBy::Field("ramp".into()))])
        .unwrap();
    scene
}

fn view() -> View {
    View {
        size: (96, 72),
        ao_rays: 0,
        shadows: false,
        color_scale: ColorScale {
            colormap: Colormap::Viridis,
            range: Some((0.0, 3.0)),
            log: false,
        },
        ..View::default()
    }
}

/// World position of pixel `i`'s first hit.
fn hit(r: &Rendered, i: usize) -> [f64; 3] {
    [0, 1, 2].map(|a| f64::from(r.frame.p[a][i]) + r.frame.p_origin[a])
}

fn rgb(r: &Rendered, i: usize) -> [f64; 3] {
    [0, 1, 2].map(|c| f64::from(r.frame.rgb[c][i]))
}

#[test]
fn a_surface_painted_by_a_second_field_has_its_colormap_colour_at_each_hit() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let mut scene = scene(&path);
    // Black: the unpainted frame is the specular highlight alone, the same in both frames.
    let black = IsoSpec {
        color: Some([0.0; 3]),
        ..IsoSpec::new(0.0)
    };
    scene.set_isosurfaces(&[black]).unwrap();
    let plain = render(&scene, &view(), &|_| {}).unwrap();
    scene
        .set_color_by(&[Some(ColorBy::Field("ramp".into()))])
        .unwrap();
    let painted = render(&scene, &view(), &|_| {}).unwrap();
    let ranges: Vec<(&str, (f64, f64))> = painted
        .color_ranges
        .iter()
        .map(|r| (r.field.as_str(), r.range))
        .collect();
    assert_eq!(ranges, [("ramp", (0.0, 3.0))]);
    let scale = view().color_scale;
    let mut checked = 0;
    for i in 0..painted.frame.len() {
        if painted.frame.alpha[i] == 0.0 {
            assert!(painted.frame.color_value[i].is_nan());
            continue;
        }
        let p = hit(&painted, i);
        let value = f64::from(painted.frame.color_value[i]);
        assert!(
            (value - ramp(p)).abs() < 2e-3,
            "pixel {i} at {p:?}: value {value}, ramp {}",
            ramp(p)
        );
        // painted = base * diffuse + specular, plain = specular: the difference is the
        // colormap's colour at the hit times one shading factor.
        let (a, b) = (rgb(&painted, i), rgb(&plain, i));
        let diff = [0, 1, 2].map(|c| a[c] - b[c]);
        let want = scale.linear(ramp(p), (0.0, 3.0)).map(f64::from);
        let d = (0..3).map(|c| diff[c] * want[c]).sum::<f64>()
            / (0..3).map(|c| want[c] * want[c]).sum::<f64>();
        if d < 0.05 {
            continue; // too dark to tell colours apart
        }
        for c in 0..3 {
            assert!(
                (diff[c] - d * want[c]).abs() < 0.01 * d + 1e-3,
                "pixel {i}: painted - plain {diff:?} is not {d} x colormap {want:?}"
            );
        }
        checked += 1;
    }
    assert!(checked > 200, "only {checked} pixels checked");
}

#[test]
fn a_slice_shows_the_field_at_each_of_its_points() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let mut scene = scene(&path);
    scene.set_isosurfaces(&[]).unwrap();
    let slice = Slice::parse_axis("z=0.4").unwrap();
    scene
        .set_slices(&[slice], Some(ColorBy::Field("ramp".into())))
        .unwrap();
    let v = View {
        camera: Some(CameraPlacement {
            pos: [0.3, 0.2, 3.0],
            look_at: Some([0.5, 0.5, 0.4]),
            up: Some([0.0, 1.0, 0.0]),
        }),
        ..view()
    };
    let r = render(&scene, &v, &|_| {}).unwrap();
    let mut covered = 0;
    for i in 0..r.frame.len() {
        if r.frame.alpha[i] == 0.0 {
            continue;
        }
        covered += 1;
        let p = hit(&r, i);
        assert!(
            (p[2] - 0.4).abs() < 1e-6,
            "pixel {i} hit {p:?} off the plane"
        );
        // Within half a cell of the domain's faces the reconstruction holds the nearest cell
        // centres' values: the ramp is reproduced from a coarse cell inwards.
        if p.iter().any(|&x| !(COARSE..=1.0 - COARSE).contains(&x)) {
            continue;
        }
        assert!(
            (f64::from(r.frame.color_value[i]) - ramp(p)).abs() < 2e-3,
            "pixel {i} at {p:?}"
        );
        // Slices are unlit: the pixel is the colormap's colour of the value there.
        let want = v
            .color_scale
            .linear(f64::from(r.frame.color_value[i]), (0.0, 3.0));
        for c in 0..3 {
            assert!(
                (r.frame.rgb[c][i] - want[c]).abs() < 1e-6,
                "pixel {i}: {:?} vs {want:?}",
                rgb(&r, i)
            );
        }
    }
    assert!(
        covered > r.frame.len() / 8,
        "the slice covers {covered} pixels"
    );
}

/// A slice painted by the length of a vector of two fields (`|ramp,sphere|`) shows, at each of
/// its points, the length of the two values that slices painted by each field show there: the
/// components are sampled where the hit is and joined, and the colour range is the magnitude's
/// own.
#[test]
fn a_slice_painted_by_a_magnitude_shows_the_length_of_its_fields_values() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let mut scene = scene(&path);
    scene.set_isosurfaces(&[]).unwrap();
    let slice = Slice::parse_axis("z=0.4").unwrap();
    let v = View {
        camera: Some(CameraPlacement {
            pos: [0.3, 0.2, 3.0],
            look_at: Some([0.5, 0.5, 0.4]),
            up: Some([0.0, 1.0, 0.0]),
        }),
        color_scale: ColorScale::default(),
        ..view()
    };
    let painted_by = |by: ColorBy, scene: &mut Scene| {
        scene.set_slices(&[slice], Some(by)).unwrap();
        render(scene, &v, &|_| {}).unwrap()
    };
    let sphere = painted_by(ColorBy::Field("sphere".into()), &mut scene);
    let magnitude: ColorBy = "| ramp, sphere |".parse().unwrap();
    assert_eq!(magnitude, ColorBy::magnitude(&["ramp", "sphere"]).unwrap());
    let both = painted_by(magnitude, &mut scene);
    assert_eq!(both.color_ranges.len(), 1);
    assert_eq!(both.color_ranges[0].field, "|ramp,sphere|");
    let mut checked = 0;
    for i in 0..both.frame.len() {
        let (m, s) = (both.frame.color_value[i], sphere.frame.color_value[i]);
        assert_eq!(m.is_nan(), s.is_nan(), "pixel {i}");
        let p = hit(&both, i);
        if m.is_nan() || p.iter().any(|&x| !(COARSE..=1.0 - COARSE).contains(&x)) {
            continue;
        }
        let want = (ramp(p).powi(2) + f64::from(s).powi(2)).sqrt();
        assert!(
            (f64::from(m) - want).abs() < 2e-3,
            "pixel {i} at {p:?}: {m}, want {want}"
        );
        checked += 1;
    }
    assert!(checked > both.frame.len() / 8, "{checked} pixels checked");
}

/// A surface painted by one field and a slice by another: each field takes the robust range of
/// its own values in view, and the slice's unlit pixels are its field's colours on its range.
/// One given range for both is refused.
#[test]
fn a_surface_and_a_slice_painted_by_two_fields_each_take_their_own_range() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let mut scene = painted_by_ramp(&path);
    let slice = Slice::parse_axis("z=0.4").unwrap();
    scene
        .set_slices(&[slice], Some(ColorBy::Field("sphere".into())))
        .unwrap();
    let mut v = View {
        camera: Some(CameraPlacement {
            pos: [0.3, 0.2, 3.0],
            look_at: Some([0.5, 0.5, 0.4]),
            up: Some([0.0, 1.0, 0.0]),
        }),
        ..view()
    };
    v.color_scale.range = None;
    let r = render(&scene, &v, &|_| {}).unwrap();
    let fields: Vec<&str> = r.color_ranges.iter().map(|c| c.field.as_str()).collect();
    assert_eq!(fields, ["ramp", "sphere"]);
    let (on_ramp, on_sphere) = (r.color_ranges[0].range, r.color_ranges[1].range);
    let sphere_value = |p: [f64; 3]| Case::Sphere.value(p);
    let (mut on_slice, mut on_surface) = (Vec::new(), Vec::new());
    for i in 0..r.frame.len() {
        if r.frame.alpha[i] == 0.0 {
            continue;
        }
        let p = hit(&r, i);
        if p.iter().any(|&x| !(COARSE..=1.0 - COARSE).contains(&x)) {
            continue;
        }
        let value = f64::from(r.frame.color_value[i]);
        if (p[2] - 0.4).abs() < 1e-6 {
            on_slice.push(value);
            assert!((value - sphere_value(p)).abs() < 2e-3, "pixel {i} at {p:?}");
            let want = v.color_scale.linear(value, on_sphere);
            for c in 0..3 {
                assert!((r.frame.rgb[c][i] - want[c]).abs() < 1e-6, "pixel {i}");
            }
        } else {
            on_surface.push(value);
            assert!((value - ramp(p)).abs() < 2e-3, "pixel {i} at {p:?}");
        }
    }
    assert!(
        on_slice.len() > 300 && on_surface.len() > 300,
        "{} slice and {} surface pixels",
        on_slice.len(),
        on_surface.len()
    );
    // Each range is the 1st to 99th percentile of its own field's values (seen at every 4th
    // pixel): it holds nearly all of them, and not the other field's.
    let within = |values: &[f64], (lo, hi): (f64, f64)| {
        values.iter().filter(|&&x| x >= lo && x <= hi).count() as f64 / values.len() as f64
    };
    assert!(within(&on_slice, on_sphere) > 0.9, "{on_sphere:?}");
    assert!(within(&on_surface, on_ramp) > 0.9, "{on_ramp:?}");
    assert!(
        within(&on_slice, on_ramp) < 0.5 && within(&on_surface, on_sphere) < 0.5,
        "{on_ramp:?} {on_sphere:?}"
    );
    let legend = Legend::of_frame(&scene, &v, &r);
    let titles: Vec<&str> = legend.color_bars.iter().map(|b| b.title.as_str()).collect();
    assert_eq!(titles, ["ramp", "sphere"]);

    v.color_scale.range = Some((0.0, 3.0));
    let err = render(&scene, &v, &|_| {}).unwrap_err().to_string();
    assert!(err.contains("2 fields that paint"), "{err}");

    // A field with a scale of its own: its colormap and range paint it; the given range is
    // then the other field's alone.
    let magma = ColorScale {
        colormap: Colormap::Magma,
        range: Some((0.0, 0.5)),
        log: false,
    };
    v.field_scales = vec![("sphere".into(), magma)];
    let r = render(&scene, &v, &|_| {}).unwrap();
    let got: Vec<(&str, (f64, f64), Colormap)> = r
        .color_ranges
        .iter()
        .map(|c| (c.field.as_str(), c.range, c.scale.colormap))
        .collect();
    assert_eq!(
        got,
        [
            ("ramp", (0.0, 3.0), Colormap::Viridis),
            ("sphere", (0.0, 0.5), Colormap::Magma)
        ]
    );
    let mut checked = 0;
    for i in 0..r.frame.len() {
        let p = hit(&r, i);
        if r.frame.alpha[i] == 0.0 || (p[2] - 0.4).abs() > 1e-6 {
            continue;
        }
        let want = magma.linear(f64::from(r.frame.color_value[i]), (0.0, 0.5));
        for c in 0..3 {
            assert!((r.frame.rgb[c][i] - want[c]).abs() < 1e-6, "pixel {i}");
        }
        checked += 1;
    }
    assert!(checked > 300, "{checked} slice pixels");
    let legend = Legend::of_frame(&scene, &v, &r);
    assert_eq!(legend.color_bars[1].colormap, Colormap::Magma);
    v.field_scales = vec![("nope".into(), magma)];
    let err = render(&scene, &v, &|_| {}).unwrap_err().to_string();
    assert!(err.contains("nope, which paints nothing"), "{err}");
}

/// A slice's default painter is the field that paints the surfaces, whichever of
/// `set_slices` and `set_color_by` comes first (the CLI set the slices first and then refused
/// `--slice` with `--color-by` as two colour scales).
#[test]
fn a_slice_takes_the_surfaces_painter_whichever_is_set_first() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let slice = Slice::parse_axis("z=0.4").unwrap();
    let ramp_paints = [Some(ColorBy::Field("ramp".into()))];
    let mut slices_first = scene(&path);
    slices_first.set_slices(&[slice], None).unwrap();
    slices_first.set_color_by(&ramp_paints).unwrap();
    let mut painters_first = scene(&path);
    painters_first.set_color_by(&ramp_paints).unwrap();
    painters_first.set_slices(&[slice], None).unwrap();
    for s in [&slices_first, &painters_first] {
        assert_eq!(s.slices()[0].1, ColorBy::Field("ramp".into()));
        assert!(render(s, &view(), &|_| {}).is_ok());
    }
    assert!(slices_first
        .set_slices(&[slice], Some(ColorBy::Field("no such field".into())))
        .is_err());
    assert_eq!(
        slices_first.slices()[0].1,
        ColorBy::Field("ramp".into()),
        "a refused call leaves the slices as they were"
    );
}

/// Surfaces painted by level beside a slice painted by a field: the colour bar is the field's
/// and the level palette joins the list on the left, so that both are explained.
#[test]
fn levels_and_a_field_painting_one_frame_both_get_a_legend() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let mut scene = scene(&path);
    scene.set_isosurfaces(&[IsoSpec::new(0.0)]).unwrap();
    scene.set_color_by(&[Some(ColorBy::Level)]).unwrap();
    let slice = Slice::parse_axis("z=0.4").unwrap();
    scene
        .set_slices(&[slice], Some(ColorBy::Field("ramp".into())))
        .unwrap();
    let r = render(&scene, &view(), &|_| {}).unwrap();
    let legend = Legend::of_frame(&scene, &view(), &r);
    let titles: Vec<&str> = legend.color_bars.iter().map(|b| b.title.as_str()).collect();
    assert_eq!(titles, ["ramp"]);
    let painted = r.painted_levels.clone().unwrap();
    assert!(!painted.is_empty());
    for l in painted {
        let entry = (format!("level {l}"), Some(Swatch::Patch(level_srgb8(l))));
        assert!(legend.entries.contains(&entry), "{:?}", legend.entries);
    }
}

/// The levels of the file's pixels where surface `0`, painted by level, is the first hit.
fn levels_shown(r: &Rendered) -> Vec<u32> {
    let mut seen: Vec<u32> = (0..r.frame.len())
        .filter(|&i| r.frame.alpha[i] > 0.0 && r.frame.color_value[i] == r.frame.level[i])
        .map(|i| r.frame.level[i] as u32)
        .collect();
    seen.sort_unstable();
    seen.dedup();
    seen
}

/// The level palette lists the levels painted into the frame, not every level of the file: a
/// surface that lies on the finer level only shows that level's swatch, and a slice across
/// both levels shows both.
#[test]
fn the_level_palette_lists_the_levels_the_frame_shows() {
    let dir = tempfile::tempdir().unwrap();
    // Bricks of 4 cells: the finer level covers the sphere's surroundings, not the whole domain.
    let path = sphere_and_ramp(dir.path(), &SynthParams::unit_cube(2, 2, 16, 4), &ramp);
    let mut scene = scene(&path);
    scene.set_isosurfaces(&[IsoSpec::new(0.0)]).unwrap();
    scene.set_color_by(&[Some(ColorBy::Level)]).unwrap();
    let r = render(&scene, &view(), &|_| {}).unwrap();
    let shown = levels_shown(&r);
    assert_eq!(shown, [1], "the sphere lies in the refined region");
    assert_eq!(r.painted_levels.as_deref(), Some(&shown[..]));
    assert_eq!(Legend::of_frame(&scene, &view(), &r).levels, shown);

    scene.set_isosurfaces(&[]).unwrap();
    let slice = Slice::parse_axis("z=0.5").unwrap();
    scene.set_slices(&[slice], Some(ColorBy::Level)).unwrap();
    let r = render(&scene, &view(), &|_| {}).unwrap();
    assert_eq!(levels_shown(&r), [0, 1]);
    assert_eq!(r.painted_levels.as_deref(), Some(&[0, 1][..]));
    assert_eq!(Legend::of_frame(&scene, &view(), &r).levels, [0, 1]);

    // A frame painted by level but showing none of it has no palette.
    let away = View {
        camera: Some(CameraPlacement {
            pos: [0.5, 0.5, 3.0],
            look_at: Some([0.5, 0.5, 6.0]),
            up: Some([0.0, 1.0, 0.0]),
        }),
        ..view()
    };
    let r = render(&scene, &away, &|_| {}).unwrap();
    assert_eq!(r.frame.covered(), 0);
    assert!(Legend::of_frame(&scene, &away, &r).levels.is_empty());
}

/// Surfaces made otherwise than by default say how, since they look otherwise (blocky cells,
/// cracks, sampling); the default says nothing.
#[test]
fn a_frame_names_a_reconstruction_or_method_other_than_the_default() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let line = |reconstruction, method| {
        let options = SceneOptions {
            field: Some("sphere".into()),
            reconstruction,
            method,
            ..SceneOptions::default()
        };
        let mut scene = Scene::open(&path, &options).unwrap();
        scene.set_isosurfaces(&[IsoSpec::new(0.0)]).unwrap();
        let r = render(&scene, &view(), &|_| {}).unwrap();
        let legend = Legend::of_frame(&scene, &view(), &r);
        legend
            .entries
            .iter()
            .find(|e| e.0.starts_with("surfaces: "))
            .map(|e| e.0.clone())
    };
    use amr_render::{Reconstruction, TraceMethod};
    assert_eq!(line(Reconstruction::Octant, TraceMethod::Hybrid), None);
    assert_eq!(
        line(Reconstruction::Nearest, TraceMethod::Hybrid).as_deref(),
        Some("surfaces: nearest reconstruction")
    );
    assert_eq!(
        line(Reconstruction::Octant, TraceMethod::Sample).as_deref(),
        Some("surfaces: sampled along rays")
    );
}

/// A cut-away says so: the legend names the box the surfaces are cut to.
#[test]
fn a_clipped_frame_names_its_clip_box() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let mut scene = scene(&path);
    scene.set_isosurfaces(&[IsoSpec::new(0.0)]).unwrap();
    scene
        .set_clip(Some(
            amr_render::ClipBox::new([0.5, 0.0, 0.0], [1.0, 1.0, 1.0]).unwrap(),
        ))
        .unwrap();
    let r = render(&scene, &view(), &|_| {}).unwrap();
    let legend = Legend::of_frame(&scene, &view(), &r);
    let line = "surfaces cut to (0.5, 0, 0) .. (1, 1, 1)".to_string();
    assert!(
        legend.entries.contains(&(line, None)),
        "{:?}",
        legend.entries
    );
}

#[test]
fn level_painting_shows_each_hit_s_level() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let mut scene = scene(&path);
    scene.set_isosurfaces(&[IsoSpec::new(0.0)]).unwrap();
    scene.set_color_by(&[Some(ColorBy::Level)]).unwrap();
    let r = render(&scene, &view(), &|_| {}).unwrap();
    let covered: Vec<usize> = (0..r.frame.len())
        .filter(|&i| r.frame.alpha[i] > 0.0)
        .collect();
    assert!(!covered.is_empty());
    for i in covered {
        assert_eq!(r.frame.color_value[i], r.frame.level[i], "pixel {i}");
    }
}

/// Pixel coordinates of world point `p` seen by `c` in a `w x h` frame.
fn project(c: &Camera, p: [f64; 3], (w, h): (u32, u32)) -> (f64, f64) {
    let v = [0, 1, 2].map(|a| p[a] - c.pos[a]);
    let f = c.forward();
    let (right, up) = c.basis();
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let depth = dot(v, f);
    let tan = (0.5 * c.fov_deg).to_radians().tan();
    let sx = dot(v, right) / depth / (tan * f64::from(w) / f64::from(h));
    let sy = dot(v, up) / depth / tan;
    (
        (sx + 1.0) * 0.5 * f64::from(w),
        (1.0 - sy) * 0.5 * f64::from(h),
    )
}

/// Distance from point `q` to the segment `a`-`b` in the image plane.
fn to_segment(q: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = (dx * dx + dy * dy).max(1e-12);
    let t = (((q.0 - a.0) * dx + (q.1 - a.1) * dy) / len2).clamp(0.0, 1.0);
    ((q.0 - a.0 - t * dx).powi(2) + (q.1 - a.1 - t * dy).powi(2)).sqrt()
}

#[test]
fn the_domain_outline_is_drawn_where_its_edges_project_and_nowhere_else() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let mut scene = scene(&path);
    scene.set_isosurfaces(&[IsoSpec::new(0.0)]).unwrap();
    let plain = render(&scene, &view(), &|_| {}).unwrap();
    let lined = render(
        &scene,
        &View {
            outline: Outline::Domain,
            ..view()
        },
        &|_| {},
    )
    .unwrap();
    let size = view().size;
    let edges: Vec<((f64, f64), (f64, f64))> =
        amr_render::outline::box_edges([0.0; 3], [1.0; 3], Background::default().outline())
            .map(|s| {
                (
                    project(&lined.camera, s.a, size),
                    project(&lined.camera, s.b, size),
                )
            })
            .collect();
    let mut on_line = 0;
    for y in 0..size.1 {
        for x in 0..size.0 {
            let i = (y * size.0 + x) as usize;
            let centre = (f64::from(x) + 0.5, f64::from(y) + 0.5);
            let near = edges
                .iter()
                .map(|&(a, b)| to_segment(centre, a, b))
                .fold(f64::INFINITY, f64::min);
            let changed = (0..3).any(|c| plain.frame.rgb[c][i] != lined.frame.rgb[c][i]);
            if near > 1.5 {
                assert!(
                    !changed,
                    "pixel ({x}, {y}) is {near:.1} px from every edge but changed"
                );
            }
            if near < 0.3 && plain.frame.alpha[i] == 0.0 {
                let want = Background::default().outline();
                assert_eq!(
                    [0, 1, 2].map(|c| lined.frame.rgb[c][i]),
                    want,
                    "pixel ({x}, {y}) on an edge"
                );
                on_line += 1;
            }
        }
    }
    assert!(on_line > 100, "only {on_line} pixels on the edges checked");
}

#[test]
fn the_default_field_skips_round_off_and_the_default_isovalue_is_the_median() {
    let dir = tempfile::tempdir().unwrap();
    let roundoff = |p: [f64; 3]| 1e-14 * (p[0] - 0.5);
    let path2 = dir.path().join("second.amrk");
    let mut spec =
        build_hierarchy(&Case::Sphere, "x", &SynthParams::unit_cube(2, 2, 16, 8)).unwrap();
    spec.fields = vec!["x_velocity".into(), "temp".into()];
    let temp = |p: [f64; 3]| 300.0 + 1000.0 * p[2] * p[2];
    write_fields(&path2, spec, &[&roundoff, &temp], WriterOptions::default()).unwrap();
    let scene = Scene::open(&path2, &SceneOptions::default()).unwrap();
    assert_eq!(scene.field_name(), "temp");
    // temp = 300 + 1000 z^2 over cells in z: its median over the cells is near 300 + 1000 / 4,
    // far from the middle of its range (800).
    let iso = scene.default_isovalue();
    assert!((iso - 550.0).abs() < 60.0, "default isovalue {iso}");
}

#[test]
fn the_default_field_is_the_density_unless_it_is_constant() {
    let dir = tempfile::tempdir().unwrap();
    let x = |p: [f64; 3]| p[0];
    let constant = |_: [f64; 3]| 1.0;
    type Field<'a> = &'a (dyn Fn([f64; 3]) -> f64 + Sync);
    let cases: [([&str; 2], [Field; 2], &str); 3] = [
        (["temp", "Density"], [&x, &x], "Density"),
        (["rho", "velx"], [&x, &x], "rho"),
        (["density", "temp"], [&constant, &x], "temp"),
    ];
    for (names, fields, want) in cases {
        let path = dir.path().join(format!("{}.amrk", names[0]));
        let mut spec =
            build_hierarchy(&Case::Sphere, "x", &SynthParams::unit_cube(2, 2, 16, 8)).unwrap();
        spec.fields = names.iter().map(|s| s.to_string()).collect();
        write_fields(&path, spec, &fields, WriterOptions::default()).unwrap();
        let scene = Scene::open(&path, &SceneOptions::default()).unwrap();
        assert_eq!(scene.field_name(), want, "{names:?}");
    }
}

#[test]
fn a_median_on_a_floor_gives_the_median_above_the_floor() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("floor.amrk");
    let mut spec =
        build_hierarchy(&Case::Sphere, "x", &SynthParams::unit_cube(2, 2, 16, 8)).unwrap();
    spec.fields = vec!["density".into()];
    // Zero for x < 0.6 (the median cell is there), (x - 0.6)^4 above: values crowd near the
    // floor, so the middle of the range (0.0128) is far above the typical value.
    let floor = |p: [f64; 3]| (p[0] - 0.6).max(0.0).powi(4);
    write_fields(&path, spec, &[&floor], WriterOptions::default()).unwrap();
    let scene = Scene::open(&path, &SceneOptions::default()).unwrap();
    let iso = f64::from(scene.default_isovalue());
    // The median cell above the floor has x between 0.7 and 0.9 (finer cells near the sphere
    // weigh more): (x - 0.6)^4 between 1e-4 and 8.1e-3.
    assert!((1e-4..=8.1e-3).contains(&iso), "default isovalue {iso}");
}

#[test]
fn a_painted_frame_with_its_legend_matches_the_golden_preview() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let scene = painted_by_ramp(&path);
    let v = View {
        size: (240, 180),
        outline: Outline::Domain,
        ..view()
    };
    let r = render(&scene, &v, &|_| {}).unwrap();
    let (w, h) = (r.frame.width, r.frame.height);
    let mut rgb = preview_rgb8(&r.frame, &r.background);
    Legend::of_frame(&scene, &v, &r).draw(&mut rgb, w, h);
    let golden =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/render_golden/painted_legend.ppm");
    assert_matches_golden(&golden, w, h, &rgb, "sphere painted by ramp, with legend");
}

/// On a white background (`--background white`, for a figure on a page) the picture shows white
/// where no surface or line is, and its outline, coordinate labels and legend text turn dark;
/// on the default grey they stay light.
#[test]
fn a_white_background_shows_white_and_turns_lines_and_labels_dark() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let scene = painted_by_ramp(&path);
    let picture = |background: Background| {
        let v = View {
            size: (320, 240),
            outline: Outline::Domain,
            background,
            ..view()
        };
        let r = render(&scene, &v, &|_| {}).unwrap();
        let mut rgb = preview_rgb8(&r.frame, &r.background);
        Legend::of_frame(&scene, &v, &r).draw(&mut rgb, 320, 240);
        (r.frame.alpha, rgb)
    };
    let white: Background = "white".parse().unwrap();
    let grey = Background::default();
    for (background, bare, ink_dark) in [(white, [255u8; 3], true), (grey, grey.srgb8(), false)] {
        let (alpha, rgb) = picture(background);
        let pixel = |i: usize| [rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]];
        let empty: Vec<usize> = (0..alpha.len()).filter(|&i| alpha[i] == 0.0).collect();
        let bare_count = empty.iter().filter(|&&i| pixel(i) == bare).count();
        assert!(
            bare_count * 10 > empty.len() * 7,
            "{bare:?}: {bare_count} of {} empty pixels show the background",
            empty.len()
        );
        // Lines and text where no surface is: dark on white, light on grey.
        let inked = empty
            .iter()
            .filter(|&&i| match ink_dark {
                true => pixel(i).iter().all(|&c| c < 80),
                false => pixel(i).iter().all(|&c| c > 200),
            })
            .count();
        assert!(inked > 200, "{bare:?}: {inked} pixels of lines and text");
        // The legend's first line at the top left: its panel follows the background.
        let panel: Vec<f64> = (12..22)
            .flat_map(|y| (12..80).map(move |x| y * 320 + x))
            .map(|i| pixel(i).iter().map(|&c| f64::from(c)).sum::<f64>() / 3.0)
            .collect();
        let mean = panel.iter().sum::<f64>() / panel.len() as f64;
        match ink_dark {
            true => assert!(mean > 200.0, "a light panel: mean {mean}"),
            false => assert!(mean < 120.0, "a dark panel: mean {mean}"),
        }
    }
}

#[test]
fn level_boxes_are_not_drawn_in_a_surface_colour_unless_surfaces_are_painted_by_level() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_fields(dir.path());
    let mut scene = scene(&path);
    // The default palette's first two colours are close to the level palette's first two.
    scene
        .set_isosurfaces(&[IsoSpec::new(0.0), IsoSpec::new(0.1)])
        .unwrap();
    let v = View {
        size: (96, 72),
        outline: Outline::Boxes,
        ..view()
    };
    let colors = LevelColors::of_scene(&scene, &v.background);
    let mut avoid = vec![v.background.srgb8()];
    for (i, s) in scene.isosurfaces().iter().enumerate() {
        avoid.push(s.color_or_palette(i).map(display_srgb8));
    }
    let r = render(&scene, &v, &|_| {}).unwrap();
    let legend = Legend::of_frame(&scene, &v, &r);
    let strokes: Vec<[u8; 3]> = legend
        .entries
        .iter()
        .filter_map(|(_, s)| match s {
            Some(Swatch::Stroke(c)) => Some(*c),
            _ => None,
        })
        .collect();
    assert_eq!(strokes.len(), scene.file().levels().len());
    for (l, c) in strokes.iter().enumerate() {
        assert_eq!(*c, colors.srgb8(l as u32));
        for a in &avoid {
            assert!(
                oklab_distance(*c, *a) > 0.1,
                "level {l} {c:?} against {a:?}"
            );
        }
    }
    // Painted by level, boxes and surfaces share the level palette.
    scene.set_color_by(&[Some(ColorBy::Level), None]).unwrap();
    let colors = LevelColors::of_scene(&scene, &v.background);
    for l in 0..4 {
        assert_eq!(colors.srgb8(l), level_srgb8(l));
    }
}
