//! The `amr-render` command as a user runs it: the demo, arguments as typed, outputs that must
//! not replace inputs, and statistics as JSON.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use amr_format::progress::NoProgress;
use amr_format::WriterOptions;
use amr_render::output::exr_file::read_channel;
use amr_synth::{write_synth, Case, SynthParams};

fn amr_render(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_amr-render"))
        .args(args)
        .output()
        .expect("amr-render runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A small two-level blobs file in `dir`.
fn blobs(dir: &Path) -> PathBuf {
    let path = dir.join("blobs.amrk");
    let params = SynthParams::unit_cube(2, 2, 16, 8);
    write_synth(&path, Case::Blobs, &params, WriterOptions::default(), &NoProgress).unwrap();
    path
}

#[test]
fn demo_renders_a_frame_with_coverage() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo.exr");
    let o = amr_render(&["demo", "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h, a) = read_channel(&out, "A").unwrap();
    assert_eq!((w, h), (800, 600));
    let covered = a.iter().filter(|&&x| x > 0.0).count();
    assert!(covered > a.len() / 50, "only {covered} pixels covered");
    assert!(out.with_extension("png").exists());
}

#[test]
fn negative_isovalues_parse_as_typed() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let out = dir.path().join("neg.exr");
    let f = file.to_str().unwrap();
    for iso in ["-5", "-5:red", "-0.5:#3070ff:0.5"] {
        let o = amr_render(&[f, "--iso", iso, "--size", "16x12", "-o", out.to_str().unwrap()]);
        assert!(o.status.success(), "--iso {iso}: {}", stderr(&o));
    }
    let o = amr_render(&["extract", f, "--iso", "-0.1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = amr_render(&[f, "--method", "sample", "--step", "-1", "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("sample step -1 must be positive"), "{}", stderr(&o));
}

#[test]
fn knobs_beyond_their_limits_are_refused_with_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let out = dir.path().join("x.exr");
    let (f, o_) = (file.to_str().unwrap(), out.to_str().unwrap());
    for (args, says) in [
        (vec!["--threads", "100000"], "between 1 and 256"),
        (vec!["--spp", "100000"], "between 1 and 4096"),
        (vec!["--method", "sample", "--step", "1e-12"], "the limit is 1e6"),
        (vec!["--size", "0x10"], "at least 1x1"),
        (vec!["--fov", "200"], "outside (0, 180)"),
    ] {
        let mut all = vec![f, "-o", o_];
        all.extend(args.iter().copied());
        let o = amr_render(&all);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(says), "{args:?}: {}", stderr(&o));
        assert!(!out.exists(), "{args:?} left an output");
    }
}

#[test]
fn an_output_that_is_the_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let before = std::fs::read(&file).unwrap();
    let f = file.to_str().unwrap();
    for args in [vec![f, "-o", f], vec![f, "-o", "x.exr", "--preview", f]] {
        let o = amr_render(&args);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains("refusing to replace it"), "{}", stderr(&o));
    }
    assert_eq!(std::fs::read(&file).unwrap(), before, "the input changed");
}

#[test]
fn stats_json_has_the_documented_keys() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let out = dir.path().join("s.exr");
    let json = dir.path().join("s.json");
    let o = amr_render(&[
        file.to_str().unwrap(),
        "--iso",
        "10",
        "--size",
        "32x24",
        "-o",
        out.to_str().unwrap(),
        "--stats-json",
        json.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&json).unwrap();
    for key in [
        "active_octants",
        "refs_bytes",
        "bvh_bytes",
        "extract_ms",
        "bvh_ms",
        "render_ms",
        "rays_per_second",
        "covered_pixels",
        "peak_rss_bytes",
        "field",
        "file_bytes",
        "mapped_resident_bytes",
        "mapped_resident_peak_bytes",
    ] {
        assert!(text.contains(&format!("\"{key}\":")), "no {key} in {text}");
    }
    assert!(text.contains("\"field\": \"blobs\""), "{text}");
}

#[test]
fn png_output_summary_quiet_and_an_empty_frame_warning() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let f = file.to_str().unwrap();
    let png = dir.path().join("blobs.png");
    let o = amr_render(&[f, "--iso", "10", "--color-by", "level", "--size", "64x48", "-o", png.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let data = std::fs::read(&png).unwrap();
    assert_eq!(&data[..8], b"\x89PNG\r\n\x1a\n", "-o .png writes a PNG");
    let line = stderr(&o);
    for part in ["field blobs", "iso 10 (coloured by level)", "active voxels", "blobs.png"] {
        assert!(line.contains(part), "summary lacks '{part}': {line}");
    }
    let o = amr_render(&[f, "--iso", "10", "--quiet", "--size", "16x12", "-o", png.to_str().unwrap()]);
    assert!(o.status.success() && stderr(&o).is_empty(), "--quiet printed: {}", stderr(&o));
    let o = amr_render(&[f, "--iso", "1e9", "--quiet", "--size", "16x12", "-o", png.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("warning: the frame shows no surface: blobs ranges over"), "{}", stderr(&o));
}

#[test]
fn painting_by_a_missing_field_names_the_file_and_the_fields() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let f = file.to_str().unwrap();
    let out = dir.path().join("x.exr");
    let o = amr_render(&[f, "--color-by", "nosuch", "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("blobs.amrk") && e.contains("nosuch") && e.contains("blobs"), "{e}");
    let o = amr_render(&[f, "--color-range", "5:1", "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "clap refuses an inverted range: {}", stderr(&o));
    assert!(stderr(&o).contains("needs LO < HI"), "{}", stderr(&o));
    let o = amr_render(&[f, "--colormap", "jet", "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "clap refuses an unknown colormap: {}", stderr(&o));
    assert!(stderr(&o).contains("viridis"), "{}", stderr(&o));
}

#[test]
fn the_exr_header_says_what_was_drawn_in_plain_text() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let f = file.to_str().unwrap();
    let out = dir.path().join("h.exr");
    let o = amr_render(&[
        f, "--iso", "10:steelblue", "--iso", "6::0.3", "--color-by", "none", "--color-by", "blobs",
        "--slice", "z=0.5", "--slice-field", "blobs", "--size", "48x36", "-o", out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = std::fs::read(&out).unwrap();
    let text = String::from_utf8_lossy(&bytes);
    assert!(text.contains("10 color=#4682b4 opacity=1; 6 color=#"), "isovalues in the header");
    assert!(text.contains("color_by=blobs"), "painting in the header");
    assert!(!text.contains("Some("), "no Rust debug output in the header");
    let (_, _, v) = read_channel(&out, "color_value").unwrap();
    assert!(v.iter().any(|x| x.is_finite()), "the painted values are a channel");
}
