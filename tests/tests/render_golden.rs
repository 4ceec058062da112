//! Golden image: a two-surface render (an opaque sphere inside a transparent one, shadows, one
//! AO ray per hit filtered across pixels, the defaults)
//! compared pixel by pixel with a stored PPM; on failure the expected, actual and difference
//! images are written. `AMR_RENDER_BLESS=1` rewrites the golden image. Also checks the EXR
//! channels: `A = 0` exactly where `Z = +inf`.

use std::path::{Path, PathBuf};

use crate::support::golden::assert_matches_golden;
use crate::support::render::{render_grid, sphere_grid};
use amr_render::output::exr_file::read_channel;
use amr_render::output::exr_file::write_exr;
use amr_render::output::png_preview::preview_rgb8;
use amr_render::shade::IsoSpec;
use amr_render::{CameraPlacement, View};

fn golden_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/render_golden/nested_spheres.ppm")
}

fn isos() -> Vec<IsoSpec> {
    vec![
        "0:gold".parse::<IsoSpec>().unwrap(),
        "0.45:#4080ff:0.35".parse::<IsoSpec>().unwrap(),
    ]
}

fn view() -> View {
    View {
        camera: Some(CameraPlacement {
            pos: [9.0, -5.0, 6.5],
            look_at: Some([2.0, 2.0, 2.0]),
            up: None,
        }),
        fov_deg: 35.0,
        size: (128, 96),
        spp: 1,
        shadows: true,
        ao_rays: 1,
        ao_filter: true,
        smooth_normals: true,
        sample_step: None,
        ..View::default()
    }
}

#[test]
fn nested_spheres_match_the_golden_image() {
    let seed = 5;
    let grid = sphere_grid(seed, 3, 2, 1.3, [0.0; 3], 1.0);
    let report = render_grid(&grid, &isos(), &view());
    let (w, h) = (report.frame.width, report.frame.height);
    let actual = preview_rgb8(&report.frame, &report.background);

    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("frame.exr");
    write_exr(&exr, &report.frame, &[]).unwrap();
    let (_, _, a) = read_channel(&exr, "A").unwrap();
    let (_, _, z) = read_channel(&exr, "Z").unwrap();
    let (_, _, level) = read_channel(&exr, "level").unwrap();
    for i in 0..a.len() {
        assert_eq!(
            a[i] == 0.0,
            z[i] == f32::INFINITY,
            "seed {seed}: pixel {i}: A {} Z {}",
            a[i],
            z[i]
        );
        assert_eq!(
            a[i] == 0.0,
            level[i] < 0.0,
            "seed {seed}: pixel {i}: A {} level {}",
            a[i],
            level[i]
        );
    }
    assert!(a.contains(&0.0) && a.iter().any(|&x| x > 0.0));
    for name in ["R", "G", "B", "N.X", "N.Y", "N.Z", "P.X", "P.Y", "P.Z"] {
        read_channel(&exr, name).unwrap();
    }

    assert_matches_golden(&golden_path(), w, h, &actual, &format!("seed {seed}"));
}
