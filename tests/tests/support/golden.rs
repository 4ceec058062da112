//! Golden images: a picture compared pixel by pixel with a stored PPM, with a per-pixel
//! threshold and an allowed fraction of pixels over it; on failure the expected, actual and
//! difference images are written. `AMR_RENDER_BLESS=1` rewrites the stored image instead.

use std::path::{Path, PathBuf};

use amr_render::output::png_preview::write_png;

/// Largest per-channel difference (of 255) a pixel may have.
const PIXEL_TOL: i32 = 6;
/// Largest fraction of pixels over `PIXEL_TOL`.
const BAD_FRACTION: f64 = 0.002;

/// Asserts that `actual` (`w x h` RGB8) matches the golden image at `golden` (`context` names
/// the case in the failure), or rewrites it under `AMR_RENDER_BLESS`.
pub fn assert_matches_golden(golden: &Path, w: u32, h: u32, actual: &[u8], context: &str) {
    if std::env::var_os("AMR_RENDER_BLESS").is_some() {
        write_ppm(golden, w, h, actual);
        eprintln!("wrote {}", golden.display());
        return;
    }
    let (gw, gh, expected) = read_ppm(golden).unwrap_or_else(|| {
        panic!(
            "no golden image {}: run with AMR_RENDER_BLESS=1",
            golden.display()
        )
    });
    assert_eq!((gw, gh), (w, h), "{context}: golden image size");
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
        let stem = golden
            .file_stem()
            .map_or("golden".into(), |s| s.to_string_lossy().into_owned());
        let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(stem);
        std::fs::create_dir_all(&out).unwrap();
        write_png(&out.join("expected.png"), w, h, &expected).unwrap();
        write_png(&out.join("actual.png"), w, h, actual).unwrap();
        write_png(&out.join("diff.png"), w, h, &diff).unwrap();
        panic!(
            "{context}: {bad} pixels differ by more than {PIXEL_TOL}/255 (allowed {allowed}, worst {worst}); \
             expected, actual and diff images in {}",
            out.display()
        );
    }
}

pub fn write_ppm(path: &Path, w: u32, h: u32, rgb: &[u8]) {
    let mut data = format!("P6\n{w} {h}\n255\n").into_bytes();
    data.extend_from_slice(rgb);
    std::fs::write(path, data).unwrap();
}

pub fn read_ppm(path: &Path) -> Option<(u32, u32, Vec<u8>)> {
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
