//! Golden image: a two-surface render (an opaque sphere inside a transparent one, shadows, AO)
//! compared pixel by pixel with a stored PPM; on failure the expected, actual and difference
//! images are written. `AMR_RENDER_BLESS=1` rewrites the golden image. Also checks the EXR
//! channels: `A = 0` exactly where `Z = +inf`.


use std::path::{Path, PathBuf};

use amr_render::output::exr_file::read_channel;
use amr_render::output::png_preview::{preview_rgb8, write_png};
use amr_render::output::exr_file::write_exr;
use amr_render::{CameraPlacement, View};
use amr_render::shade::IsoSpec;
use crate::support::render::{render_grid, sphere_grid};

/// Largest per-channel difference (of 255) a pixel may have.
const PIXEL_TOL: i32 = 6;
/// Largest fraction of pixels over `PIXEL_TOL`.
const BAD_FRACTION: f64 = 0.002;

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
        ao_rays: 4,
        smooth_normals: true,
        sample_step: None,
        ..View::default()
    }
}

fn write_ppm(path: &Path, w: u32, h: u32, rgb: &[u8]) {
    let mut data = format!("P6\n{w} {h}\n255\n").into_bytes();
    data.extend_from_slice(rgb);
    std::fs::write(path, data).unwrap();
}

fn read_ppm(path: &Path) -> Option<(u32, u32, Vec<u8>)> {
    let data = std::fs::read(path).ok()?;
    let mut fields = Vec::new();
    let mut i = 0;
    while fields.len() < 4 {
        while data.get(i)?.is_ascii_whitespace() {
            i += 1;
        }
        let start = i;
        while !data.get(i)?.is_ascii_whitespace() {
            i += 1;
        }
        fields.push(String::from_utf8_lossy(&data[start..i]).into_owned());
    }
    let (w, h): (u32, u32) = (fields[1].parse().ok()?, fields[2].parse().ok()?);
    Some((w, h, data[i + 1..].to_vec()))
}

#[test]
fn nested_spheres_match_the_golden_image() {
    let seed = 5;
    let grid = sphere_grid(seed, 3, 2, 1.3, [0.0; 3], 1.0);
    let report = render_grid(&grid, &isos(), &view());
    let (w, h) = (report.frame.width, report.frame.height);
    let actual = preview_rgb8(&report.frame);

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

    let golden = golden_path();
    if std::env::var_os("AMR_RENDER_BLESS").is_some() {
        write_ppm(&golden, w, h, &actual);
        eprintln!("wrote {}", golden.display());
        return;
    }
    let (gw, gh, expected) = read_ppm(&golden).unwrap_or_else(|| {
        panic!(
            "no golden image {}: run with AMR_RENDER_BLESS=1",
            golden.display()
        )
    });
    assert_eq!((gw, gh), (w, h), "golden image size");
    let mut diff = vec![0u8; actual.len()];
    let mut bad = 0usize;
    let mut worst = 0;
    for p in 0..(w * h) as usize {
        let d = (0..3)
            .map(|c| (i32::from(actual[3 * p + c]) - i32::from(expected[3 * p + c])).abs())
            .max()
            .unwrap();
        worst = worst.max(d);
        if d > PIXEL_TOL {
            bad += 1;
        }
        for c in 0..3 {
            diff[3 * p + c] = (d * 8).min(255) as u8;
        }
    }
    let allowed = (BAD_FRACTION * f64::from(w * h)) as usize;
    if bad > allowed {
        let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("render_golden");
        std::fs::create_dir_all(&out).unwrap();
        write_png(&out.join("expected.png"), w, h, &expected).unwrap();
        write_png(&out.join("actual.png"), w, h, &actual).unwrap();
        write_png(&out.join("diff.png"), w, h, &diff).unwrap();
        panic!(
            "seed {seed}: {bad} pixels differ by more than {PIXEL_TOL}/255 (allowed {allowed}, worst {worst}); \
             expected, actual and diff images in {}",
            out.display()
        );
    }
}
