//! The filter of the ambient occlusion across pixels: one filtered ray per hit is closer to a
//! many-ray reference than four unfiltered rays, and the filter, which reads neighbouring
//! pixels, leaves rectangles of a frame (tiles) equal to the whole frame, bit for bit, and a
//! frame rendered in bands of rows equal to its rows rendered alone.

use amr_render::shade::IsoSpec;
use amr_render::{
    frame_painting, render, render_region, CameraPlacement, Rect, Rendered, Scene, SceneOptions,
    View,
};

use crate::support::amrex::{convert, shared_data};
use crate::support::render::blobs_scene;

fn view(ao_rays: u32, ao_filter: bool) -> View {
    View {
        camera: Some(CameraPlacement {
            pos: [1.3, -0.2, 0.9],
            look_at: None,
            up: None,
        }),
        size: (160, 120),
        ao_rays,
        ao_filter,
        ..View::default()
    }
}

/// RMS difference of the linear colour over the pixels either frame covers.
fn rms(a: &Rendered, b: &Rendered) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0u64);
    for i in 0..a.frame.alpha.len() {
        if a.frame.alpha[i] > 0.0 || b.frame.alpha[i] > 0.0 {
            for c in 0..3 {
                sum += f64::from(a.frame.rgb[c][i] - b.frame.rgb[c][i]).powi(2);
                n += 1;
            }
        }
    }
    (sum / n.max(1) as f64).sqrt()
}

/// Perspective and orthographic views alike (the filter's pixel footprint is each one's).
#[test]
fn one_filtered_ray_is_closer_to_the_reference_than_four_unfiltered() {
    let dir = tempfile::tempdir().unwrap();
    let scene = blobs_scene(dir.path());
    for orthographic in [false, true] {
        let view = |ao_rays, ao_filter| View {
            orthographic,
            ..view(ao_rays, ao_filter)
        };
        let reference = render(&scene, &view(64, false), &|_| ()).unwrap();
        let four = render(&scene, &view(4, false), &|_| ()).unwrap();
        let one_filtered = render(&scene, &view(1, true), &|_| ()).unwrap();
        let one = render(&scene, &view(1, false), &|_| ()).unwrap();
        let (e4, e1f, e1) = (
            rms(&four, &reference),
            rms(&one_filtered, &reference),
            rms(&one, &reference),
        );
        assert!(
            e1f < e4 && e4 < e1,
            "orthographic {orthographic}: RMS: 1 filtered {e1f}, 4 {e4}, 1 {e1}"
        );
        assert!(
            one_filtered.stats.rays < four.stats.rays,
            "{} rays against {}",
            one_filtered.stats.rays,
            four.stats.rays
        );
    }
}

/// Near silhouettes, where the surface turns away from the camera, neighbouring pixels' hits
/// lie far apart on the surface and off the plane of the hit's smooth normal: the filter's plane
/// tolerance grows there, so that the pattern of the single rays still averages out. The scene:
/// a close-up of the densest dark-matter clump of the real Enzo dataset DD0010, coarse cells seen
/// large, much of it at grazing angles.
#[test]
fn at_grazing_angles_the_filter_still_averages_the_pattern() {
    let Some(dir) = shared_data(
        "at_grazing_angles_the_filter_still_averages_the_pattern",
        "enzo/DD0010",
        "moving7_0010.hierarchy",
    ) else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("dd0010.amrk");
    convert(
        &dir.join("moving7_0010"),
        &path,
        &["Dark_Matter_Density"],
        32,
    )
    .unwrap();
    let mut scene = Scene::open(&path, &SceneOptions::default()).unwrap();
    scene.set_isosurfaces(&[IsoSpec::new(1.337e6)]).unwrap();
    let close_up = |ao_rays, ao_filter| View {
        camera: Some(CameraPlacement {
            pos: [0.7525, 0.7485, 0.7521],
            look_at: Some([0.75085, 0.74985, 0.75085]),
            up: None,
        }),
        fov_deg: 8.0,
        size: (256, 192),
        ..view(ao_rays, ao_filter)
    };
    let reference = render(&scene, &close_up(64, false), &|_| ()).unwrap();
    let four = render(&scene, &close_up(4, false), &|_| ()).unwrap();
    let one_filtered = render(&scene, &close_up(1, true), &|_| ()).unwrap();
    let (e4, e1f) = (rms(&four, &reference), rms(&one_filtered, &reference));
    assert!(e1f < 0.6 * e4, "RMS: 1 filtered {e1f}, 4 {e4}");
}

#[test]
fn tiles_of_a_filtered_frame_equal_the_whole_frame() {
    let dir = tempfile::tempdir().unwrap();
    let scene = blobs_scene(dir.path());
    let view = view(1, true);
    let whole = render(&scene, &view, &|_| ()).unwrap().frame;
    let (w, h) = view.size;
    // Uneven tiles, one of them a single pixel, some at the frame's edges.
    let xs = [0, 1, 37, 80, 159, 160];
    let ys = [0, 2, 61, 119, 120];
    for x in xs.windows(2) {
        for y in ys.windows(2) {
            let rect = Rect {
                x0: x[0],
                y0: y[0],
                width: x[1] - x[0],
                height: y[1] - y[0],
            };
            let tile = render_region(&scene, &view, &frame_painting(&scene, &view).unwrap(), rect)
                .unwrap();
            for ty in 0..rect.height {
                for tx in 0..rect.width {
                    let p = &tile.pixels[(ty * rect.width + tx) as usize];
                    let i = ((rect.y0 + ty) * w + rect.x0 + tx) as usize;
                    for c in 0..3 {
                        assert_eq!(
                            p.rgb[c].to_bits(),
                            whole.rgb[c][i].to_bits(),
                            "{rect:?} pixel ({}, {}) of {w}x{h}",
                            rect.x0 + tx,
                            rect.y0 + ty
                        );
                    }
                    assert_eq!(p.z.to_bits(), whole.z[i].to_bits());
                }
            }
        }
    }
}

#[test]
fn a_frame_rendered_in_bands_equals_its_rows_rendered_alone() {
    // A frame of more pixels than one band (`BAND_PIXELS`, 2^17: 32 rows of 4096) is
    // rendered, filtered and written band by band; the rows on either side of each band's end
    // must be those a region of them gives (its filter sees every row around it).
    let dir = tempfile::tempdir().unwrap();
    let scene = blobs_scene(dir.path());
    let view = View {
        size: (4096, 1024),
        ..view(1, true)
    };
    let whole = render(&scene, &view, &|_| ()).unwrap().frame;
    let w = view.size.0;
    let mut covered = 0;
    for end in [256u32, 512, 768] {
        let rect = Rect {
            x0: 0,
            y0: end - 6,
            width: w,
            height: 12,
        };
        let rows =
            render_region(&scene, &view, &frame_painting(&scene, &view).unwrap(), rect).unwrap();
        for (k, p) in rows.pixels.iter().enumerate() {
            let i = (rect.y0 * w) as usize + k;
            let want = [p.rgb[0], p.rgb[1], p.rgb[2], p.alpha, p.z, p.n[0], p.level];
            let got = [
                whole.rgb[0][i],
                whole.rgb[1][i],
                whole.rgb[2][i],
                whole.alpha[i],
                whole.z[i],
                whole.n[0][i],
                whole.level[i],
            ];
            assert_eq!(
                got.map(f32::to_bits),
                want.map(f32::to_bits),
                "pixel ({}, {})",
                k as u32 % w,
                rect.y0 + k as u32 / w
            );
            covered += usize::from(p.alpha > 0.0);
        }
    }
    assert!(
        covered > 1000,
        "only {covered} pixels near the bands' ends hit"
    );
}
