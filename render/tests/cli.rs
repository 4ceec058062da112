//! The `amr-render` command as a user runs it: the demo, arguments as typed, outputs that must
//! not replace inputs, and statistics as JSON.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use amr_format::progress::NoProgress;
use amr_format::WriterOptions;
use amr_render::output::exr_file::read_channel;
use amr_synth::{write_synth, Case, SynthParams};

// The two-field file of the integration tests' support.
#[path = "../../tests/tests/support/synth_file.rs"]
#[allow(dead_code)]
mod synth_file;

fn amr_render(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_amr-render"))
        .args(args)
        .output()
        .expect("amr-render runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A synthetic file `name` of `case` in `dir`: `levels` levels, ratio 2, 16 cells a side on
/// level 0, over the unit cube.
fn synth(dir: &Path, name: &str, case: Case, levels: u32) -> PathBuf {
    let path = dir.join(name);
    let params = SynthParams::unit_cube(levels, 2, 16, 8);
    write_synth(&path, case, &params, WriterOptions::default(), &NoProgress).unwrap();
    path
}

/// A small two-level blobs file in `dir`.
fn blobs(dir: &Path) -> PathBuf {
    synth(dir, "blobs.amrk", Case::Blobs, 2)
}

/// The sphere case on 3 levels in `dir`.
fn sphere(dir: &Path) -> PathBuf {
    synth(dir, "sphere.amrk", Case::Sphere, 3)
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
        let o = amr_render(&[
            f,
            "--iso",
            iso,
            "--size",
            "16x12",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "--iso {iso}: {}", stderr(&o));
    }
    let o = amr_render(&["extract", f, "--iso", "-0.1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = amr_render(&[
        f,
        "--method",
        "sample",
        "--step",
        "-1",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("sample step -1 must be positive"),
        "{}",
        stderr(&o)
    );
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
        (
            vec!["--method", "sample", "--step", "1e-12"],
            "the limit is 1e6",
        ),
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
    // Inputs named like outputs, so that the names alone do not refuse them.
    let (as_exr, as_png) = (dir.path().join("in.exr"), dir.path().join("in.png"));
    std::fs::copy(&file, &as_exr).unwrap();
    std::fs::copy(&file, &as_png).unwrap();
    let (e, p) = (as_exr.to_str().unwrap(), as_png.to_str().unwrap());
    for args in [vec![e, "-o", e], vec![p, "-o", "x.exr", "--preview", p]] {
        let o = amr_render(&args);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(
            stderr(&o).contains("refusing to replace it"),
            "{}",
            stderr(&o)
        );
    }
    // Named `.amrk` as inputs are, it is refused all the same.
    let f = file.to_str().unwrap();
    for args in [vec![f, "-o", f], vec![f, "-o", "x.exr", "--preview", f]] {
        assert_eq!(amr_render(&args).status.code(), Some(1));
    }
    for input in [&file, &as_exr, &as_png] {
        assert_eq!(std::fs::read(input).unwrap(), before, "the input changed");
    }
}

/// The arguments of a 32x24 frame of `file` at iso 10 written to `out`, its statistics to `json`.
fn small_frame_with_stats<'a>(file: &'a str, out: &'a str, json: &'a str) -> [&'a str; 9] {
    [
        file,
        "--iso",
        "10",
        "--size",
        "32x24",
        "-o",
        out,
        "--stats-json",
        json,
    ]
}

#[test]
fn stats_json_has_the_documented_keys() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let out = dir.path().join("s.exr");
    let json = dir.path().join("s.json");
    let o = amr_render(&small_frame_with_stats(
        file.to_str().unwrap(),
        out.to_str().unwrap(),
        json.to_str().unwrap(),
    ));
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

/// `--stats-json -` writes the statistics to standard output, for a pipe, and no file named
/// `-`; `extract` then prints its lines for people to standard error.
#[test]
fn stats_json_dash_is_standard_output() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let out = dir.path().join("s.exr");
    let run = |args: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_amr-render"))
            .current_dir(dir.path())
            .args(args)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
        let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap_or_else(|e| {
            panic!(
                "stdout is not JSON ({e}): {}",
                String::from_utf8_lossy(&o.stdout)
            )
        });
        (json, stderr(&o))
    };
    let file = file.to_str().unwrap();
    let (frame, _) = run(&small_frame_with_stats(file, out.to_str().unwrap(), "-"));
    assert!(
        frame["active_octants"].as_u64().is_some_and(|n| n > 0),
        "{frame}"
    );
    let (runs, text) = run(&[
        "extract",
        file,
        "--iso",
        "10",
        "--iso",
        "20",
        "--stats-json",
        "-",
    ]);
    assert_eq!(runs.as_array().map(Vec::len), Some(2), "{runs}");
    assert!(
        text.contains("active voxels"),
        "the lines for people went missing: {text}"
    );
    assert!(!dir.path().join("-").exists(), "a file named - was written");
}

/// `extract --iso FIELD=V` extracts another field than `--field`, in the same run: each line is
/// the line of a run of that field alone, and a field the file lacks is refused before any
/// extraction.
#[test]
fn extract_takes_isovalues_of_several_fields() {
    let dir = tempfile::tempdir().unwrap();
    let path = sphere_and_ramp(dir.path());
    let f = path.to_str().unwrap();
    let lines = |args: &[&str]| {
        let o = amr_render(args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        String::from_utf8_lossy(&o.stdout)
            .lines()
            // Up to the counts: the times and the pages touched differ from run to run.
            .map(|l| l.split(" voxels evaluated").next().unwrap_or(l).to_string())
            .collect::<Vec<_>>()
    };
    let mixed = lines(&[
        "extract", f, "--iso", "0", "--iso", "ramp=0.6", "--iso", "0.1",
    ]);
    let first = lines(&["extract", f, "--iso", "0", "--iso", "0.1"]);
    let second = lines(&["extract", f, "--field", "ramp", "--iso", "0.6"]);
    assert_eq!(
        mixed,
        vec![first[0].clone(), second[0].clone(), first[1].clone()]
    );
    assert!(mixed[1].starts_with("field 'ramp' iso 0.6: "), "{mixed:?}");
    let o = amr_render(&["extract", f, "--iso", "0", "--iso", "nosuch=1"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("no field 'nosuch'"), "{}", stderr(&o));
    assert!(o.stdout.is_empty(), "extracted before refusing");
}

/// `--iso pQ` is the field's Q-th percentile over every cell (nearest rank), counted here from
/// every cell value of the file, rounded to the five significant digits the summary prints; the
/// same in a render, an extraction, and for a surface of another field.
#[test]
fn an_isovalue_typed_as_a_percentile_is_the_fields_value_there() {
    let dir = tempfile::tempdir().unwrap();
    let path = sphere_and_ramp(dir.path());
    let f = path.to_str().unwrap();
    let file = amr_format::AmrkFile::open(std::fs::read(&path).unwrap()).unwrap();
    let percentile = |field: usize, q: f64| {
        let mut all: Vec<f32> = (0..file.num_bricks())
            .flat_map(|b| file.brick_values(field, b).unwrap().into_owned())
            .collect();
        all.sort_by(f32::total_cmp);
        let exact = all[((all.len() - 1) as f64 * q / 100.0).round() as usize];
        let shown: f32 = format!("{:.4e}", exact).parse().unwrap();
        amr_render::field_stats::format_isovalue(shown)
    };
    let (p90, ramp_p25) = (percentile(0, 90.0), percentile(1, 25.0));
    let out = dir.path().join("p.png");
    let o = amr_render(&[
        f,
        "--iso",
        "p90",
        "--iso",
        "ramp=p25:red",
        "--size",
        "32x24",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let want = format!("iso {p90}, ramp={ramp_p25}, ");
    assert!(stderr(&o).contains(&want), "{want} not in {}", stderr(&o));
    let o = amr_render(&["extract", f, "--iso", "P90", "--iso", "ramp=p25"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    for line in [
        format!("iso {p90}: "),
        format!("field 'ramp' iso {ramp_p25}: "),
    ] {
        assert!(text.contains(&line), "{line} not in {text}");
    }
    let o = amr_render(&["extract", f, "--iso", "p100.5"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("outside p0 to p100"), "{}", stderr(&o));
    // A sweep between percentiles steps in percentile; from a number to one, in value.
    let sweep = dir.path().join("s.exr");
    let frames = |spec: &str| {
        let o = amr_render(&[
            f,
            "--iso-sweep",
            spec,
            "--size",
            "16x12",
            "-q",
            "-o",
            sweep.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{spec}: {}", stderr(&o));
        (0..3)
            .map(|k| attribute(&dir.path().join(format!("s_{k:04}.exr")), "isovalues"))
            .collect::<Vec<String>>()
    };
    let got = frames("p10:p90:3");
    for (k, q) in [10.0, 50.0, 90.0].into_iter().enumerate() {
        let want = percentile(0, q);
        assert!(
            got[k].starts_with(&format!("{want}:")),
            "frame {k}: {} for {want}",
            got[k]
        );
    }
    let got = frames("0:p90:3");
    let half: f32 = p90.parse::<f32>().unwrap() / 2.0;
    assert!(
        got[1].starts_with(&format!("{half}:")),
        "{} for {half}",
        got[1]
    );
}

/// Output cut short by the reader (`amr-render extract F ... | head -1`) ends the run quietly
/// with exit 0, as for any command-line tool, never with a panic.
#[test]
fn a_closed_pipe_on_standard_output_is_not_a_failure() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let file = file.to_str().unwrap();
    for args in [
        vec![
            "extract", file, "--iso", "10", "--iso", "20", "--runs", "50",
        ],
        vec!["verify", file],
        vec!["info", file],
    ] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_amr-render"))
            .args(&args)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let o = child.wait_with_output().unwrap();
        let err = stderr(&o);
        assert!(
            o.status.success() && !err.contains("panicked"),
            "{args:?}: {:?} {err}",
            o.status
        );
    }
}

/// A path that is not UTF-8 cannot go into a TOML scene file: refused, rather than written with
/// replacement characters that would name another file.
#[test]
fn a_scene_file_refuses_a_path_that_is_not_utf8() {
    use std::os::unix::ffi::OsStrExt;
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let odd = dir
        .path()
        .join(std::ffi::OsStr::from_bytes(b"b\xfflobs.amrk"));
    std::fs::copy(&file, &odd).unwrap();
    let scene = dir.path().join("s.toml");
    let o = Command::new(env!("CARGO_BIN_EXE_amr-render"))
        .arg(&odd)
        .args(["--size", "8x6", "-o"])
        .arg(dir.path().join("x.exr"))
        .arg("--write-scene")
        .arg(&scene)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("not valid UTF-8"), "{}", stderr(&o));
    assert!(!scene.exists());
}

/// The text attribute `key` of an EXR file.
fn attribute(path: &Path, key: &str) -> String {
    let attrs = amr_render::output::exr_file::read_text_attributes(path).unwrap();
    attrs
        .into_iter()
        .find(|(k, _)| k == key)
        .unwrap_or_else(|| panic!("{}: no attribute {key}", path.display()))
        .1
}

/// Bit patterns of a channel.
fn bits(path: &Path, channel: &str) -> Vec<u32> {
    let (_, _, v) = read_channel(path, channel).unwrap();
    v.iter().map(|x| x.to_bits()).collect()
}

#[test]
fn an_orbit_writes_numbered_frames_from_one_scene() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let (f, d) = (file.to_str().unwrap(), dir.path());
    let out = d.join("orbit.exr");
    let json = d.join("orbit.json");
    let o = amr_render(&[
        f,
        "--iso",
        "10",
        "--size",
        "32x24",
        "--ao",
        "1",
        "--orbit",
        "4",
        "-o",
        out.to_str().unwrap(),
        "--stats-json",
        json.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    for k in 0..4 {
        let frame = d.join(format!("orbit_{k:04}.exr"));
        assert_eq!(attribute(&frame, "frame"), format!("{k} of 4"));
    }
    assert!(!d.join("orbit_0004.exr").exists() && !out.exists());
    // One extraction: the frames after the first rebuild nothing.
    let stats: Vec<serde_json::Value> =
        serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(stats.len(), 4);
    assert!(
        stats[1..]
            .iter()
            .all(|s| s["extract_ms"] == 0.0 && s["bvh_ms"] == 0.0),
        "{stats:?}"
    );
    // The first frame is the single frame from the same camera; the others differ.
    let single = d.join("single.exr");
    let o = amr_render(&[
        f,
        "--iso",
        "10",
        "--size",
        "32x24",
        "--ao",
        "1",
        "-o",
        single.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(bits(&single, "R"), bits(&d.join("orbit_0000.exr"), "R"));
    assert_ne!(bits(&single, "Z"), bits(&d.join("orbit_0001.exr"), "Z"));
}

/// The values of `name=[x, y, z]` in an EXR camera attribute, as a command line takes them.
fn camera_part(camera: &str, name: &str) -> String {
    let rest = &camera[camera.find(&format!("{name}=[")).unwrap() + name.len() + 2..];
    rest[..rest.find(']').unwrap()].replace(' ', "")
}

#[test]
fn an_orbits_frames_equal_separate_runs_from_their_cameras() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let (f, d) = (file.to_str().unwrap(), dir.path());
    let common = [f, "--iso", "10", "--size", "32x24", "--ao", "1"];
    let out = d.join("orbit.exr");
    let mut args = common.to_vec();
    args.extend(["--orbit", "3", "-o", out.to_str().unwrap()]);
    let o = amr_render(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let channels = [
        "R", "G", "B", "A", "Z", "N.X", "N.Y", "N.Z", "P.X", "P.Y", "P.Z", "level",
    ];
    for k in 0..3 {
        let framed = d.join(format!("orbit_{k:04}.exr"));
        let camera = attribute(&framed, "camera");
        let [pos, look_at, up] = ["pos", "look_at", "up"].map(|p| camera_part(&camera, p));
        let alone = d.join(format!("alone{k}.exr"));
        let mut args = common.to_vec();
        args.extend(["--camera-pos", &pos, "--look-at", &look_at, "--up", &up]);
        args.extend(["-o", alone.to_str().unwrap()]);
        let o = amr_render(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        for c in channels {
            assert_eq!(bits(&alone, c), bits(&framed, c), "frame {k}, channel {c}");
        }
    }
}

#[test]
fn a_write_that_fails_mid_run_names_its_file_and_stops_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let (f, d) = (file.to_str().unwrap(), dir.path());
    // An empty frame compresses to a small file, one with a surface to a larger one: a file
    // size limit between the two fails the second frame of a sweep 1000 -> 10 -> -980 (empty).
    let view = ["--size", "64x48", "--camera-pos", "2,-1.5,1.5"];
    let size_of = |iso: &str| {
        let one = d.join(format!("one{iso}.exr"));
        let mut args = vec![f, "--iso", iso, "-o", one.to_str().unwrap()];
        args.extend(view);
        let o = amr_render(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::metadata(&one).unwrap().len()
    };
    let (empty, full) = (size_of("1000"), size_of("10"));
    assert!(empty + 2048 < full, "{empty} {full}");
    let blocks = (empty + full) / 2 / 512;
    let out = d.join("sweep.exr");
    // The shell ignores the signal a write past the limit raises, so the write fails instead.
    let script = format!("trap '' XFSZ; ulimit -f {blocks}; exec \"$0\" \"$@\"");
    let o = Command::new("sh")
        .args(["-c", &script, env!("CARGO_BIN_EXE_amr-render")])
        .args([f, "--iso-sweep", "1000:-980:3"])
        .args(view)
        .args(["-o", out.to_str().unwrap()])
        .output()
        .unwrap();
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(err.contains("sweep_0001.exr"), "{err}");
    assert!(d.join("sweep_0000.exr").exists());
    assert!(!d.join("sweep_0001.exr").exists() && !d.join("sweep_0002.exr").exists());
    let leftovers: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn a_sweep_records_its_isovalues_and_a_series_equals_separate_runs() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let (f, d) = (file.to_str().unwrap(), dir.path());
    let sweep = d.join("sweep.exr");
    let o = amr_render(&[
        f,
        "--iso-sweep",
        "6:12:3:red",
        "--size",
        "24x18",
        "-o",
        sweep.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    for (k, iso) in ["6", "9", "12"].iter().enumerate() {
        let isos = attribute(&d.join(format!("sweep_{k:04}.exr")), "isovalues");
        assert!(isos.starts_with(&format!("{iso}:")), "frame {k}: {isos}");
    }

    // A second file of the series: another field's range, so its frame differs.
    let other = d.join("other.amrk");
    let params = SynthParams::unit_cube(2, 2, 16, 8);
    write_synth(
        &other,
        Case::Sphere,
        &params,
        WriterOptions::default(),
        &NoProgress,
    )
    .unwrap();
    let o_ = other.to_str().unwrap();
    let series = d.join("series.exr");
    let cam = ["--camera-pos", "2,-1.5,1.5", "--look-at", "0.5,0.5,0.5"];
    let mut args = vec![
        f,
        o_,
        f,
        "--iso",
        "0.1",
        "--size",
        "24x18",
        "-o",
        series.to_str().unwrap(),
    ];
    args.extend(cam);
    let o = amr_render(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    for (k, input) in [f, o_, f].iter().enumerate() {
        let alone = d.join(format!("alone{k}.exr"));
        let mut args = vec![
            *input,
            "--iso",
            "0.1",
            "--size",
            "24x18",
            "-o",
            alone.to_str().unwrap(),
        ];
        args.extend(cam);
        let o = amr_render(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let framed = d.join(format!("series_{k:04}.exr"));
        for c in ["R", "G", "B", "A", "Z"] {
            assert_eq!(bits(&alone, c), bits(&framed, c), "frame {k}, channel {c}");
        }
    }
}

#[test]
fn a_scene_file_renders_what_its_command_line_did() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let d = dir.path();
    let first = d.join("first.exr");
    let scene = d.join("scene.toml");
    let o = amr_render(&[
        file.to_str().unwrap(),
        "--iso",
        "-5:#3070ff:0.5",
        "--iso",
        "10:gold",
        "--size",
        "24x18",
        "--no-shadows",
        "--camera-pos",
        "2,-1,1",
        "-o",
        first.to_str().unwrap(),
        "--write-scene",
        scene.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&scene).unwrap();
    assert!(
        text.contains("no-shadows = true") && text.contains("iso = ["),
        "{text}"
    );
    let again = d.join("again.exr");
    let o = amr_render(&[scene.to_str().unwrap(), "-o", again.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    for c in ["R", "G", "B", "A", "Z"] {
        assert_eq!(bits(&first, c), bits(&again, c), "channel {c}");
    }
    let bad = d.join("bad.toml");
    std::fs::write(&bad, "size = \"24x18\"\n").unwrap();
    let o = amr_render(&[bad.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("no `files`"), "{}", stderr(&o));
}

/// A scene file's relative paths are its directory's: written so by `--write-scene` and read so,
/// whatever directory the command runs in; paths typed on the command line stay the working
/// directory's, and absolute ones stay absolute.
#[test]
fn a_scene_file_reads_its_relative_paths_from_its_own_directory() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir_all(d.join("run")).unwrap();
    std::fs::create_dir_all(d.join("figs")).unwrap();
    synth(&d.join("run"), "blobs.amrk", Case::Blobs, 2);
    let run_in = |cwd: &Path, args: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_amr-render"))
            .args(args)
            .current_dir(cwd)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{args:?} in {}: {}",
            cwd.display(),
            stderr(&o)
        );
    };
    let picture = ["--iso", "10", "--size", "32x24", "--no-shadows", "-q"];
    let mut args = vec![
        "run/blobs.amrk",
        "-o",
        "figs/f.png",
        "--stats-json",
        "figs/f.json",
    ];
    args.extend(picture);
    args.extend(["--write-scene", "figs/f.toml"]);
    run_in(d, &args);
    let text = std::fs::read_to_string(d.join("figs/f.toml")).unwrap();
    for line in [
        r#"files = ["../run/blobs.amrk"]"#,
        r#"output = "f.png""#,
        r#"stats-json = "f.json""#,
    ] {
        assert!(text.contains(line), "{line} not in {text}");
    }
    let first = std::fs::read(d.join("figs/f.png")).unwrap();
    std::fs::remove_file(d.join("figs/f.png")).unwrap();
    run_in(&d.join("figs"), &["f.toml"]);
    assert_eq!(std::fs::read(d.join("figs/f.png")).unwrap(), first);
    std::fs::remove_file(d.join("figs/f.png")).unwrap();
    run_in(&d.join("run"), &["../figs/f.toml"]);
    assert_eq!(std::fs::read(d.join("figs/f.png")).unwrap(), first);
    // An option after the scene file is the command line's: from the working directory.
    run_in(&d.join("run"), &["../figs/f.toml", "-o", "here.png"]);
    assert_eq!(std::fs::read(d.join("run/here.png")).unwrap(), first);
    // Written from a scene into another directory, the paths follow; absolute ones stay.
    let abs_out = d.join("abs.png");
    let abs_out = abs_out.to_str().unwrap();
    run_in(
        &d.join("run"),
        &[
            "../figs/f.toml",
            "-o",
            abs_out,
            "--write-scene",
            "again.toml",
        ],
    );
    let text = std::fs::read_to_string(d.join("run/again.toml")).unwrap();
    assert!(text.contains(r#"files = ["blobs.amrk"]"#), "{text}");
    assert!(text.contains(&format!("output = {abs_out:?}")), "{text}");
}

#[test]
fn animation_counts_must_agree() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let f = file.to_str().unwrap();
    let out = dir.path().join("x.exr");
    let o = amr_render(&[f, f, "--orbit", "3", "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("frame counts must agree"),
        "{}",
        stderr(&o)
    );
}

/// A surface at its field's largest value is a set of points no ray meets: the empty frame's
/// warning says so, and what to take instead, rather than that the camera does not see it.
#[test]
fn an_empty_frame_at_the_fields_largest_value_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let max = {
        let bytes = std::fs::read(&file).unwrap();
        amr_format::AmrkFile::open(bytes).unwrap().fields()[0].max
    };
    let out = dir.path().join("peak.png");
    let iso = max.to_string();
    let o = amr_render(&[
        file.to_str().unwrap(),
        "--iso",
        &iso,
        "--size",
        "64x48",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let said = stderr(&o);
    assert!(
        said.contains("the frame shows none of the surface's")
            && said.contains("is blobs's largest value")
            && said.contains("take a value further below it"),
        "{said}"
    );
}

/// A picture too small for its legend is left as rendered, with a note naming the size that
/// holds it; `--no-legend` leaves the legend out of any picture, without a note.
#[test]
fn a_legend_without_room_is_left_out_with_a_note_and_no_legend_leaves_it_out() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let f = file.to_str().unwrap();
    let png = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let run = |size: &str, out: &str, extra: &[&str]| {
        let mut args = vec![
            f,
            "--iso",
            "10",
            "--color-by",
            "level",
            "--size",
            size,
            "-o",
            out,
        ];
        args.extend_from_slice(extra);
        let o = amr_render(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        stderr(&o)
    };
    let (small, small_bare) = (png("small.png"), png("small-bare.png"));
    let said = run("96x72", &small, &[]);
    assert!(
        said.contains("small.png: a 96x72 picture has no room for its legend, which is left out; it fits from --size "),
        "{said}"
    );
    let said = run("96x72", &small_bare, &["--no-legend"]);
    assert!(!said.contains("legend"), "{said}");
    let read = |p: &str| std::fs::read(p).unwrap();
    assert_eq!(read(&small), read(&small_bare), "a legend was drawn");
    let said = run("96x72", &small, &["--quiet"]);
    assert!(said.is_empty(), "--quiet printed: {said}");
    let (large, large_bare) = (png("large.png"), png("large-bare.png"));
    assert!(!run("480x360", &large, &[]).contains("legend"));
    run("480x360", &large_bare, &["--no-legend"]);
    assert_ne!(
        read(&large),
        read(&large_bare),
        "no legend drawn on 480x360"
    );
}

#[test]
fn png_output_summary_quiet_and_an_empty_frame_warning() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let f = file.to_str().unwrap();
    let png = dir.path().join("blobs.png");
    let o = amr_render(&[
        f,
        "--iso",
        "10",
        "--color-by",
        "level",
        "--size",
        "64x48",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let data = std::fs::read(&png).unwrap();
    assert_eq!(&data[..8], b"\x89PNG\r\n\x1a\n", "-o .png writes a PNG");
    let line = stderr(&o);
    for part in [
        "field blobs",
        "iso 10 (coloured by level)",
        "active voxels",
        "blobs.png",
    ] {
        assert!(line.contains(part), "summary lacks '{part}': {line}");
    }
    let o = amr_render(&[
        f,
        "--iso",
        "10",
        "--quiet",
        "--size",
        "16x12",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(
        o.status.success() && stderr(&o).is_empty(),
        "--quiet printed: {}",
        stderr(&o)
    );
    let o = amr_render(&[
        f,
        "--iso",
        "1e9",
        "--quiet",
        "--size",
        "16x12",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("the frame shows no surface: blobs ranges over"),
        "{}",
        stderr(&o)
    );
    // A surface the camera looks away from is named with where it lies, not the field's range.
    let o = amr_render(&[
        f,
        "--quiet",
        "--size",
        "16x12",
        "--camera-pos",
        "0.5,0.5,-3",
        "--look-at",
        "0.5,0.5,-10",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("the frame shows none of the surface's")
            && stderr(&o).contains(
                "looking at (0.5, 0.5, -10), they are behind it: look at them (--look-at "
            ),
        "{}",
        stderr(&o)
    );
    // Why the camera misses it: the surface outside the frame, or smaller than a pixel.
    for (camera, why) in [
        (
            ["0.5,-3,0.5", "-3,0,0.5"],
            "they lie outside the frame, to its right: look at them",
        ),
        (
            ["0.5,-3,0.5", "0.5,0,3.5"],
            "they lie outside the frame, below it: look at them",
        ),
        (
            ["0.5,0.5,1e5", "0.5,0.5,0.5"],
            "they span less than a pixel of its 16x12 frame",
        ),
    ] {
        let o = amr_render(&[
            f,
            "--quiet",
            "--size",
            "16x12",
            "--camera-pos",
            camera[0],
            "--look-at",
            camera[1],
            "-o",
            png.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(stderr(&o).contains(why), "{camera:?}: {}", stderr(&o));
    }
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
    assert!(
        e.contains("blobs.amrk") && e.contains("nosuch") && e.contains("blobs"),
        "{e}"
    );
    let o = amr_render(&[f, "--color-range", "5:1", "-o", out.to_str().unwrap()]);
    assert_eq!(
        o.status.code(),
        Some(1),
        "clap refuses an inverted range: {}",
        stderr(&o)
    );
    assert!(stderr(&o).contains("needs LO < HI"), "{}", stderr(&o));
    let o = amr_render(&[f, "--colormap", "jet", "-o", out.to_str().unwrap()]);
    assert_eq!(
        o.status.code(),
        Some(1),
        "clap refuses an unknown colormap: {}",
        stderr(&o)
    );
    assert!(stderr(&o).contains("viridis"), "{}", stderr(&o));
}

/// An option the rest of the command makes void is refused, naming what it needs or what
/// overrides it: ignored, it would leave the user believing it took effect.
#[test]
fn an_option_the_command_makes_void_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let f = file.to_str().unwrap();
    let png = dir.path().join("x.png");
    let key = ["--keyframe", "0:2,2,2:0.5,0.5,0.5"];
    for (args, says) in [
        (
            vec!["--orbit-degrees", "90"],
            "--orbit-degrees applies to --orbit N",
        ),
        (vec!["--fps", "30"], "--fps applies to --movie"),
        (vec!["--step", "0.01"], "--step applies to --method sample"),
        (
            vec!["--slice-field", "blobs"],
            "--slice-field applies to --slice",
        ),
        (vec!["--exr-compression", "zip"], "writes none"),
        (
            [&key[..], &["--camera-pos", "1,1,1"]].concat(),
            "leave out --camera-pos",
        ),
        (
            [&key[..], &["--frame-domain"]].concat(),
            "leave out --frame-domain",
        ),
        (
            vec!["--frame-domain", "--camera-pos", "2,2,2"],
            "--frame-domain frames",
        ),
        (
            vec!["--view-from", "+z", "--camera-pos", "2,2,2"],
            "give one of them",
        ),
        (
            [&key[..], &["--view-from", "x"]].concat(),
            "leave out --view-from",
        ),
        (
            vec!["--up", "0,1,0"],
            "--up needs --camera-pos or --view-from",
        ),
        (vec!["--view-from", "0,0,0"], "the zero vector"),
        (vec!["--view-from", "up"], "neither an axis"),
        (
            vec!["--view-from", "-z", "--up", "0,0,3"],
            "parallel to the view direction",
        ),
    ] {
        let r = amr_render(
            &[
                &[f, "--size", "16x12", "-o", png.to_str().unwrap()],
                &args[..],
            ]
            .concat(),
        );
        assert_eq!(r.status.code(), Some(1), "{args:?}: {}", stderr(&r));
        assert!(stderr(&r).contains(says), "{args:?}: {}", stderr(&r));
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "{args:?}: an output was written"
        );
    }
    // With what they qualify, they are taken.
    let exr = dir.path().join("x.exr");
    for args in [
        vec!["--orbit", "2", "--orbit-degrees", "90"],
        vec!["--method", "sample", "--step", "0.01"],
        vec!["--slice", "x=0.5", "--slice-field", "blobs"],
        vec!["--exr-compression", "zip"],
        [&key[..], &["--keyframe", "1:2,2,3:0.5,0.5,0.5"]].concat(),
        vec!["--view-from", "-Y", "--up", "1,0,1", "--frame-domain"],
    ] {
        let r = amr_render(
            &[
                &[f, "--size", "16x12", "-o", exr.to_str().unwrap()],
                &args[..],
            ]
            .concat(),
        );
        assert!(r.status.success(), "{args:?}: {}", stderr(&r));
    }
}

/// `--iso none` draws slices alone: no isosurface, not even the default median one, and is
/// refused beside other isovalues or with nothing else to draw.
#[test]
fn iso_none_draws_the_slices_alone() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let (f, d) = (file.to_str().unwrap(), dir.path());
    let out = d.join("slice.exr");
    let o = amr_render(&[
        f,
        "--iso",
        "none",
        "--slice",
        "z=0.5",
        "--size",
        "48x36",
        // Lines cover pixels too, with no value painted.
        "--outline",
        "none",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("no isosurface, 1 slice"),
        "{}",
        stderr(&o)
    );
    assert_eq!(attribute(&out, "isovalues"), "");
    let (_, _, alpha) = read_channel(&out, "A").unwrap();
    let (_, _, painted) = read_channel(&out, "color_value").unwrap();
    assert!(alpha.iter().filter(|&&a| a > 0.0).count() > 100);
    // Every covered pixel is the slice's: painted with a value.
    let unpainted = alpha
        .iter()
        .zip(&painted)
        .filter(|(&a, v)| a > 0.0 && !v.is_finite())
        .count();
    assert_eq!(unpainted, 0);
    for (args, says) in [
        (vec!["--iso", "none"], "add a --slice"),
        (
            vec!["--iso", "none", "--iso", "10", "--slice", "z=0.5"],
            "leave out the other --iso values",
        ),
    ] {
        let mut all = vec![f, "-o", out.to_str().unwrap()];
        all.extend(args.iter().copied());
        let o = amr_render(&all);
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        assert!(stderr(&o).contains(says), "{args:?}: {}", stderr(&o));
    }
}

/// `--view-from` turns the automatic camera: it looks at the centre of what it frames from the
/// direction given (an axis or a vector), with up z (y looking along z) or `--up`, and fits
/// the surfaces (or the domain) to the picture; an orbit keeps the default framing's distance.
#[test]
fn a_view_from_an_axis_looks_along_it_at_the_framed_surfaces() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let (f, d) = (file.to_str().unwrap(), dir.path());
    let camera_of = |out: &Path| -> [[f64; 3]; 3] {
        let camera = attribute(out, "camera");
        ["pos", "look_at", "up"].map(|p| {
            let v: Vec<f64> = camera_part(&camera, p)
                .split(',')
                .map(|x| x.parse().unwrap())
                .collect();
            [v[0], v[1], v[2]]
        })
    };
    let render_from = |name: &str, extra: &[&str]| {
        let out = d.join(name);
        let mut args = vec![f, "--iso", "10", "--size", "64x48", "--ao", "0"];
        args.extend(extra);
        args.extend(["-o", out.to_str().unwrap()]);
        let o = amr_render(&args);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        out
    };
    let framed = camera_of(&render_from("framed.exr", &[]));
    let [pos, look, up] = camera_of(&render_from("top.exr", &["--view-from", "+z"]));
    // The same point looked at as the default framing (the surfaces' centre), from straight above.
    assert_eq!(look, framed[1]);
    assert!(
        pos[2] > look[2] && pos[0] == look[0] && pos[1] == look[1],
        "{pos:?}"
    );
    assert_eq!(up, [0.0, 1.0, 0.0]);
    // Fitted (the fit itself is checked in `camera::tests`): nearer than the default framing.
    let dist = |p: [f64; 3], l: [f64; 3]| (0..3).map(|a| (p[a] - l[a]).powi(2)).sum::<f64>().sqrt();
    assert!(dist(pos, look) < dist(framed[0], framed[1]));
    let [pos, _, up] = camera_of(&render_from("side.exr", &["--view-from", "-1,-1,0"]));
    assert!(
        pos[0] < look[0] && pos[1] < look[1] && pos[2] == look[2],
        "{pos:?}"
    );
    assert_eq!(up, [0.0, 0.0, 1.0]);
    let [_, _, up] = camera_of(&render_from(
        "given.exr",
        &["--view-from", "z", "--up", "1,0,0"],
    ));
    assert_eq!(up, [1.0, 0.0, 0.0]);
    // With --frame-domain it frames the domain, the unit cube, whose centre it looks at.
    let [pos, look, _] = camera_of(&render_from(
        "dom.exr",
        &["--view-from", "+x", "--frame-domain"],
    ));
    assert_eq!(look, [0.5; 3]);
    assert!(pos[0] > 1.0 && pos[1] == 0.5 && pos[2] == 0.5, "{pos:?}");
    // An orbit starts from the direction at the default framing's distance (its frames turn
    // the surfaces about the centre, so a tight fit could cut them).
    render_from("orbit.exr", &["--view-from", "+z", "--orbit", "2"]);
    let [pos, look, _] = camera_of(&d.join("orbit_0000.exr"));
    assert!((dist(pos, look) - dist(framed[0], framed[1])).abs() < 1e-9);
    assert!(pos[0] == look[0] && pos[1] == look[1] && pos[2] > look[2]);
}

/// The colour scale's options with nothing painted by a field would change nothing: the user
/// who gave them expected colour, so they are refused with what to add; with a field painting
/// a surface or a slice they are taken.
#[test]
fn a_colour_scale_without_a_painted_field_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let f = file.to_str().unwrap();
    let out = dir.path().join("x.png");
    let o = out.to_str().unwrap();
    for (args, says) in [
        (vec!["--colormap", "magma"], "--color-by FIELD or a --slice"),
        (
            vec!["--color-log", "--color-range", "1:5"],
            "--color-range, --color-log",
        ),
        (
            vec!["--color-by", "level", "--color-log"],
            "each level its own colour",
        ),
        (
            vec![
                "--slice",
                "x=0.5",
                "--slice-field",
                "level",
                "--colormap",
                "magma",
            ],
            "--slice-field FIELD",
        ),
    ] {
        let r = amr_render(&[&[f, "--size", "16x12", "-o", o], &args[..]].concat());
        assert_eq!(r.status.code(), Some(1), "{args:?}: {}", stderr(&r));
        assert!(stderr(&r).contains(says), "{args:?}: {}", stderr(&r));
        assert!(!out.exists(), "{args:?}: a frame was written");
    }
    for args in [
        vec!["--color-by", "blobs", "--colormap", "magma", "--color-log"],
        vec!["--slice", "x=0.5", "--color-range", "1:5"],
        vec![
            "--color-by",
            "level",
            "--slice",
            "x=0.5",
            "--colormap",
            "magma",
        ],
    ] {
        let r = amr_render(&[&[f, "--size", "16x12", "-o", o], &args[..]].concat());
        assert!(r.status.success(), "{args:?}: {}", stderr(&r));
    }
}

#[test]
fn the_exr_header_says_what_was_drawn_in_plain_text() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let f = file.to_str().unwrap();
    let out = dir.path().join("h.exr");
    let o = amr_render(&[
        f,
        "--iso",
        "10:steelblue",
        "--iso",
        "6::0.3",
        "--color-by",
        "none",
        "--color-by",
        "blobs",
        "--slice",
        "z=0.5",
        "--slice-field",
        "blobs",
        "--size",
        "48x36",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let isos = attribute(&out, "isovalues");
    assert!(
        isos.starts_with("10:#4682b4 6:#") && isos.ends_with(":0.3"),
        "{isos}"
    );
    assert_eq!(attribute(&out, "field"), "blobs");
    assert_eq!(attribute(&out, "color_by"), "- blobs");
    assert!(attribute(&out, "slices").contains("color_by=blobs"));
    assert!(
        !isos.contains("Some("),
        "no Rust debug output in the header"
    );
    let (_, _, v) = read_channel(&out, "color_value").unwrap();
    assert!(
        v.iter().any(|x| x.is_finite()),
        "the painted values are a channel"
    );
}

#[test]
fn auto_series_keeps_one_colour_range_over_a_series() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a = blobs(d);
    let b = d.join("finer.amrk");
    let params = SynthParams::unit_cube(3, 2, 16, 8);
    write_synth(
        &b,
        Case::Blobs,
        &params,
        WriterOptions::default(),
        &NoProgress,
    )
    .unwrap();
    let out = d.join("s.exr");
    let o = amr_render(&[
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--iso",
        "10",
        "--color-by",
        "blobs",
        "--color-range",
        "auto-series",
        "--size",
        "24x18",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let first = attribute(&d.join("s_0000.exr"), "color_range");
    assert_eq!(first, attribute(&d.join("s_0001.exr"), "color_range"));
    let o = amr_render(&[
        a.to_str().unwrap(),
        "--iso",
        "10",
        "--color-range",
        "auto-series",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("nothing is painted by a field"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn clip_boxes_that_cut_nothing_sensible_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let out = dir.path().join("c.exr");
    for (clip, says) in [
        ("0,0,0,1,1", "has 5 numbers; give six"),
        ("0,0,0,1,1,1,1", "has 7 numbers; give six"),
        ("0,0,0,1,nan,1", "finite"),
        ("0,0,0,1,x,1", "'x' in clip box"),
        (
            "0,0.6,0,1,0.5,1",
            "on the y axis the lower bound 0.6 is not below the upper bound 0.5",
        ),
        ("0,0,0.5,1,1,0.5", "on the z axis"),
        ("2,2,2,3,3,3", "does not overlap the domain"),
        ("-1,-1,-1,0,0,0", "does not overlap the domain"),
    ] {
        let o = amr_render(&[
            file.to_str().unwrap(),
            "--iso",
            "10",
            "--size",
            "16x12",
            "--clip",
            clip,
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(1), "--clip {clip}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(
            e.contains(says) && !e.contains("panicked"),
            "--clip {clip}: {e}"
        );
        if says.contains("domain") {
            assert!(e.contains("blobs.amrk"), "the error names the file: {e}");
        }
        assert!(!out.exists());
    }
}

#[test]
fn a_clip_box_cuts_the_surfaces_and_a_scene_file_keeps_it() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let d = dir.path();
    let f = file.to_str().unwrap();
    let common = [
        "--iso",
        "5",
        "--size",
        "64x48",
        "--fov",
        "25",
        "--camera-pos",
        "2.5,0.5,0.5",
    ];
    let (whole, cut, scene) = (d.join("whole.exr"), d.join("cut.exr"), d.join("cut.toml"));
    let (wj, cj) = (d.join("whole.json"), d.join("cut.json"));
    let o = amr_render(
        &[&[f][..], &common, &["-o", whole.to_str().unwrap()]]
            .concat()
            .into_iter()
            .chain(["--stats-json", wj.to_str().unwrap()])
            .collect::<Vec<_>>(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = amr_render(
        &[&[f][..], &common]
            .concat()
            .into_iter()
            .chain(["--clip", "-1,-1,-1,0.5,2,2", "-o", cut.to_str().unwrap()])
            .chain(["--stats-json", cj.to_str().unwrap()])
            .chain(["--write-scene", scene.to_str().unwrap()])
            .collect::<Vec<_>>(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let json = |p: &Path| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
    };
    let (w, c) = (json(&wj), json(&cj));
    let active = |v: &serde_json::Value| v["active_octants"].as_u64().unwrap();
    assert!(active(&c) < active(&w), "{c} vs {w}");
    assert!(c["leaves_visited"].as_u64().unwrap() < w["leaves_visited"].as_u64().unwrap());
    // The camera on the +x side sees the surface cut at x = 0.5: further away than the whole one.
    let (zw, zc) = (
        read_channel(&whole, "Z").unwrap().2,
        read_channel(&cut, "Z").unwrap().2,
    );
    let deeper = zw
        .iter()
        .zip(&zc)
        .filter(|(a, b)| a.is_finite() && b.is_finite() && **b > **a + 0.05)
        .count();
    let seen = zc.iter().filter(|z| z.is_finite()).count();
    assert!(
        deeper > seen / 2,
        "{deeper} of {seen} pixels see through the cut"
    );
    assert!(seen > 200, "{seen} pixels");
    assert!(zc
        .iter()
        .filter(|z| z.is_finite())
        .all(|&z| z >= 2.0 - 1e-4));
    let text = std::fs::read_to_string(&scene).unwrap();
    assert!(text.contains("clip = \"-1,-1,-1,0.5,2,2\""), "{text}");
    let again = d.join("again.exr");
    let o = amr_render(&[scene.to_str().unwrap(), "-o", again.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(bits(&cut, "Z"), bits(&again, "Z"));
}

#[test]
fn extraction_in_view_renders_the_same_frame_with_less() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let d = dir.path();
    let f = file.to_str().unwrap();
    let common = [
        f,
        "--iso",
        "10",
        "--iso",
        "5:#3070ff:0.4",
        "--size",
        "40x30",
        "--no-shadows",
        "--ao",
        "0",
        "--camera-pos",
        "0.9,-0.2,0.6",
        "--look-at",
        "0.45,0.45,0.45",
        "--fov",
        "20",
    ];
    let run = |name: &str, extra: &[&str]| -> serde_json::Value {
        let out = d.join(format!("{name}.exr"));
        let json = d.join(format!("{name}.json"));
        let args: Vec<&str> = common
            .iter()
            .copied()
            .chain(extra.iter().copied())
            .chain([
                "-o",
                out.to_str().unwrap(),
                "--stats-json",
                json.to_str().unwrap(),
            ])
            .collect();
        let o = amr_render(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap()
    };
    let whole = run("whole", &[]);
    let limited = run("limited", &["--extract-in-view"]);
    let a = |v: &serde_json::Value| v["active_octants"].as_u64().unwrap();
    assert!(a(&limited) < a(&whole), "{limited} vs {whole}");
    for c in ["R", "G", "B", "A", "Z"] {
        assert_eq!(
            bits(&d.join("whole.exr"), c),
            bits(&d.join("limited.exr"), c),
            "channel {c}"
        );
    }
    // An orbit extracts again for each camera.
    let orbit: Vec<serde_json::Value> = match run("orbit", &["--extract-in-view", "--orbit", "3"]) {
        serde_json::Value::Array(v) => v,
        other => panic!("{other}"),
    };
    assert_eq!(orbit.len(), 3);
    assert!(
        orbit
            .iter()
            .all(|s| s["leaves_visited"].as_u64().unwrap() > 0),
        "{orbit:?}"
    );
}

#[test]
fn every_exr_compression_writes_the_same_channels_and_says_which_it_used() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let mut reference: Option<Vec<Vec<u32>>> = None;
    for (name, expected) in [
        ("piz", exr::compression::Compression::PIZ),
        ("zip", exr::compression::Compression::ZIP16),
        ("rle", exr::compression::Compression::RLE),
        ("none", exr::compression::Compression::Uncompressed),
    ] {
        let out = dir.path().join(format!("{name}.exr"));
        let o = amr_render(&[
            file.to_str().unwrap(),
            "--iso",
            "10",
            "--size",
            "64x48",
            "--exr-compression",
            name,
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        let meta = exr::meta::MetaData::read_from_file(&out, false).unwrap();
        assert_eq!(meta.headers[0].compression, expected, "{name}");
        let channels: Vec<Vec<u32>> = ["R", "A", "Z", "N.X", "P.Y", "level"]
            .iter()
            .map(|c| bits(&out, c))
            .collect();
        match &reference {
            None => reference = Some(channels),
            Some(r) => assert!(r == &channels, "{name}: channels differ from piz's"),
        }
    }
    let o = amr_render(&[file.to_str().unwrap(), "--exr-compression", "lzw"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("piz, zip, rle, none"), "{}", stderr(&o));
}

/// `verify` recomputes the stored tight leaf ranges (layout version 3): a stored range that
/// misses values the data give fails and names the leaf; a wider one is conservative, passes and
/// is counted.
#[test]
fn verify_finds_a_wrong_tight_range() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tight.amrk");
    let params = SynthParams::unit_cube(2, 2, 16, 8);
    let opts = amr_render::extract::writer_options(Default::default());
    write_synth(&path, Case::Blobs, &params, opts, &NoProgress).unwrap();
    let o = amr_render(&["verify", path.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(out.contains("tight leaf ranges recomputed"), "{out}");
    assert!(!out.contains("wider"), "{out}");
    let bytes = std::fs::read(&path).unwrap();
    let file = amr_format::AmrkFile::open(bytes.clone()).unwrap();
    let (leaf, (lo, hi)) = (0..file.num_leaves() as u32)
        .filter_map(|l| Some((l, file.tight_range(0, l)?)))
        .find(|&(_, (lo, hi))| lo.is_finite() && lo < hi)
        .unwrap();
    let at = file.footer().tight_ranges.offset.get() as usize + 8 * leaf as usize;
    let with_lo = |new_lo: f32| {
        let mut b = bytes.clone();
        b[at..at + 4].copy_from_slice(&new_lo.to_le_bytes());
        assert!(amr_format::reader::recompute_checksums(&mut b));
        std::fs::write(&path, &b).unwrap();
        amr_render(&["verify", path.to_str().unwrap()])
    };
    let o = with_lo(lo - 1.0);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(out.contains("1 stored wider than the data's"), "{out}");
    let o = with_lo(0.5 * (lo + hi));
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(err.contains(&format!("leaf {leaf} stores")), "{err}");
    assert!(err.contains("miss values the data give"), "{err}");
}

/// `verify` recomputes the stored part bounds (layout version 4): a stored bound that misses
/// values the data give fails and names the leaf and part; a wider one passes and is counted.
#[test]
fn verify_finds_a_wrong_part_bound() {
    use zerocopy::FromBytes;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("parts.amrk");
    let params = SynthParams::unit_cube(2, 2, 32, 16);
    let opts = amr_render::extract::writer_options(Default::default());
    write_synth(&path, Case::Blobs, &params, opts, &NoProgress).unwrap();
    let o = amr_render(&["verify", path.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(out.contains("part bounds recomputed"), "{out}");
    assert!(!out.contains("wider"), "{out}");
    let bytes = std::fs::read(&path).unwrap();
    let file = amr_format::AmrkFile::open(bytes.clone()).unwrap();
    let (leaf, part, (lo, hi)) = (0..file.num_leaves() as u32)
        .flat_map(|l| {
            let parts = file.part_ranges(0, l).unwrap();
            parts
                .iter()
                .enumerate()
                .map(move |(p, r)| (l, p, (r.min.get(), r.max.get())))
        })
        .find(|&(_, _, (lo, hi))| lo.is_finite() && lo < hi)
        .unwrap();
    let at = file.footer().part_table.get() as usize;
    let (table, _) = amr_format::raw::PartTable::read_from_prefix(&bytes[at..]).unwrap();
    let first: usize = (0..leaf)
        .map(|l| file.part_ranges(0, l).unwrap().len())
        .sum();
    let at = table.ranges.offset.get() as usize + 8 * (first + part);
    let with_lo = |new_lo: f32| {
        let mut b = bytes.clone();
        b[at..at + 4].copy_from_slice(&new_lo.to_le_bytes());
        assert!(amr_format::reader::recompute_checksums(&mut b));
        std::fs::write(&path, &b).unwrap();
        amr_render(&["verify", path.to_str().unwrap()])
    };
    let o = with_lo(lo - 1.0);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(out.contains("1 stored wider than the data's"), "{out}");
    let o = with_lo(0.5 * (lo + hi));
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains(&format!("leaf {leaf}, part {part} stores")),
        "{err}"
    );
    assert!(err.contains("miss values the data give"), "{err}");
}

#[test]
fn extract_runs_on_the_threads_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let f = file.to_str().unwrap();
    let o = amr_render(&["extract", f, "--iso", "10", "--threads", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report = String::from_utf8_lossy(&o.stdout);
    assert!(report.contains("on 1 threads"), "{report}");
    let o = amr_render(&["extract", f, "--iso", "10", "--threads", "0"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--threads 0 must be between 1"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn info_says_where_each_levels_boxes_lie() {
    let dir = tempfile::tempdir().unwrap();
    let file = sphere(dir.path());
    let o = amr_render(&["info", file.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report = String::from_utf8_lossy(&o.stdout);
    let within: Vec<&str> = report
        .lines()
        .filter_map(|l| l.trim().strip_prefix("boxes within "))
        .collect();
    assert_eq!(within.len(), 3, "{report}");
    // The base level covers the domain; the finest only around the sphere.
    let domain = report
        .lines()
        .find_map(|l| l.strip_prefix("domain extent: "))
        .unwrap();
    assert_eq!(within[0], domain, "{report}");
    assert_ne!(within[2], domain, "{report}");
}

/// `info --json` holds what the text says, as data: the levels the synthetic hierarchy was
/// written with (domains, cell sizes, ratios), every count the text prints, and each field's
/// range and percentiles keyed `p0` .. `p100`.
#[test]
fn info_json_holds_the_hierarchy_and_what_the_text_says() {
    let dir = tempfile::tempdir().unwrap();
    // 3 levels, ratio 2, 16 cells a side on level 0, over the unit cube.
    let file = sphere(dir.path());
    let f = file.to_str().unwrap();
    let o = amr_render(&["info", f, "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let levels = j["levels"].as_array().unwrap();
    assert_eq!(levels.len(), 3);
    for (l, lev) in levels.iter().enumerate() {
        let n = 16i64 << l;
        assert_eq!(
            lev["domain"],
            serde_json::json!([[0, 0, 0], [n, n, n]]),
            "level {l}"
        );
        assert_eq!(
            lev["cell_size"][0].as_f64().unwrap(),
            1.0 / n as f64,
            "level {l}"
        );
        let ratio = if l < 2 {
            serde_json::json!([2, 2, 2])
        } else {
            serde_json::Value::Null
        };
        assert_eq!(lev["ratio_to_next"], ratio, "level {l}");
    }
    assert_eq!(
        j["domain"],
        serde_json::json!([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    );
    assert!(j["simulation_time"].is_null() && j["simulation_step"].is_null());
    let sum = |key: &str| levels.iter().map(|l| l[key].as_u64().unwrap()).sum::<u64>();
    assert_eq!(j["cells"].as_u64(), Some(sum("cells")));
    assert_eq!(j["bricks"].as_u64(), Some(sum("bricks")));
    // The text prints the same counts.
    let text = String::from_utf8(amr_render(&["info", f]).stdout).unwrap();
    for key in ["cells", "bricks", "kd_leaves", "kd_depth", "file_bytes"] {
        let label = format!("{}: {}\n", key.replace('_', " "), j[key]);
        assert!(text.contains(&label), "{label:?} not in\n{text}");
    }
    let field = &j["fields"][0];
    let p = field["percentiles"].as_object().unwrap();
    let keys: Vec<&str> = p.keys().map(String::as_str).collect();
    assert_eq!(keys, ["p0", "p1", "p25", "p50", "p75", "p99", "p100"]);
    let values: Vec<f64> = p.values().map(|v| v.as_f64().unwrap()).collect();
    assert!(values.windows(2).all(|w| w[0] <= w[1]), "{p:?}");
    // Every cell is counted in so small a file: p0 and p100 are the range.
    assert_eq!(j["percentiles_subsampled"], false);
    assert_eq!(values[0], field["min"].as_f64().unwrap());
    assert_eq!(values[6], field["max"].as_f64().unwrap());
    assert!(field.get("unreadable").is_none());
}

/// An isovalue outside the field's range beside other surfaces gets a warning naming it and
/// the range (its surface is empty while the frame shows the others); the frame is written.
#[test]
fn an_isovalue_outside_the_range_beside_others_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let file = blobs(dir.path());
    let f = file.to_str().unwrap();
    let out = dir.path().join("x.png");
    let o = out.to_str().unwrap();
    let r = amr_render(&[f, "--iso", "1e6", "--iso", "10", "--size", "32x24", "-o", o]);
    assert!(r.status.success(), "{}", stderr(&r));
    let e = stderr(&r);
    assert!(
        e.contains("isovalue 1e6 lies outside blobs's range ["),
        "{e}"
    );
    assert!(out.exists());
    let r = amr_render(&[f, "--iso", "10", "--iso", "20", "--size", "32x24", "-o", o]);
    assert!(r.status.success(), "{}", stderr(&r));
    assert!(!stderr(&r).contains("lies outside"), "{}", stderr(&r));
}

/// `--iso FIELD=V` draws a surface of another field beside `--field`'s: the summary names it as
/// typed (and names no other field when every surface is of another), a scene file keeps it,
/// and a name the file does not hold is refused with the file's fields.
#[test]
fn an_isosurface_of_another_field_is_drawn_and_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = sphere_and_ramp(dir.path());
    let (file, out, scene) = (
        path.to_str().unwrap(),
        dir.path().join("f.png"),
        dir.path().join("s.toml"),
    );
    let o = amr_render(&[
        file,
        "--field",
        "sphere",
        "--iso",
        "0",
        "--iso",
        "ramp=1:red",
        "--size",
        "64x48",
        "-o",
        out.to_str().unwrap(),
        "--write-scene",
        scene.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("iso 0, ramp=1,"), "{}", stderr(&o));
    let text = std::fs::read_to_string(&scene).unwrap();
    assert!(text.contains("\"ramp=1:red\""), "{text}");
    let again = amr_render(&[scene.to_str().unwrap(), "-q"]);
    assert!(again.status.success(), "{}", stderr(&again));
    // With no surface of the scene's field, the summary does not name that field.
    let o = amr_render(&[
        file,
        "--iso",
        "ramp=1",
        "--size",
        "32x24",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("two.amrk: iso ramp=1, "),
        "{}",
        stderr(&o)
    );

    let o = amr_render(&[file, "--iso", "nope=1", "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("two.amrk") && e.contains("no field 'nope'") && e.contains("ramp"),
        "{e}"
    );
}

/// A two-level file of fields `sphere` and `ramp` in `dir`.
fn sphere_and_ramp(dir: &Path) -> PathBuf {
    synth_file::sphere_and_ramp(dir, &SynthParams::unit_cube(2, 2, 16, 8), &|p| {
        p[0] + 0.5 * p[1]
    })
}

/// A time series whose later file lacks the field of an `--iso FIELD=V` stops before its first
/// frame, naming that file.
#[test]
fn a_series_file_without_a_surfaces_field_stops_the_run_before_any_frame() {
    let dir = tempfile::tempdir().unwrap();
    let two = sphere_and_ramp(dir.path());
    let one = sphere(dir.path());
    let out = dir.path().join("f.exr");
    let o = amr_render(&[
        two.to_str().unwrap(),
        one.to_str().unwrap(),
        "--field",
        "sphere",
        "--iso",
        "0",
        "--iso",
        "ramp=1",
        "--size",
        "32x24",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("sphere.amrk") && e.contains("no field 'ramp'"),
        "{e}"
    );
    assert!(
        !dir.path().join("f_0000.exr").exists(),
        "a frame was written"
    );
}

/// `--iso-sweep FIELD=A:B:N` sweeps a surface of another field beside `--field`'s surfaces; a
/// field the file does not hold is refused before any frame.
#[test]
fn a_sweep_of_another_field_renders_its_frames() {
    let dir = tempfile::tempdir().unwrap();
    let path = sphere_and_ramp(dir.path());
    let out = dir.path().join("f.exr");
    let args = |sweep: &str| {
        amr_render(&[
            path.to_str().unwrap(),
            "--field",
            "sphere",
            "--iso",
            "0",
            "--iso-sweep",
            sweep,
            "--size",
            "32x24",
            "-q",
            "-o",
            out.to_str().unwrap(),
        ])
    };
    let o = args("ramp=0.5:1.5:3:red");
    assert!(o.status.success(), "{}", stderr(&o));
    for k in 0..3 {
        assert!(
            dir.path().join(format!("f_{k:04}.exr")).exists(),
            "frame {k}"
        );
    }
    let o = args("nope=0.5:1.5:3");
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("no field 'nope'"), "{}", stderr(&o));
}

/// A surface painted by one field and a slice by another render with a colour bar each; one
/// `--color-range` for both is refused before anything is extracted.
#[test]
fn two_fields_painting_one_frame_render_and_refuse_one_shared_range() {
    let dir = tempfile::tempdir().unwrap();
    let path = sphere_and_ramp(dir.path());
    let out = dir.path().join("f.png");
    let run = |extra: &[&str]| painted_by_two_fields(&path, &out, extra);
    let o = run(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run(&["--color-range", "0:1"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("2 fields paint (ramp, sphere)"),
        "{}",
        stderr(&o)
    );
}

/// `--color-scale FIELD=...` gives one painting field its own colormap, log scale or range
/// (so a shared `--color-range` is then the other field's alone); one for a field that paints
/// nothing is refused.
#[test]
fn a_field_takes_its_own_colour_scale() {
    let dir = tempfile::tempdir().unwrap();
    let path = sphere_and_ramp(dir.path());
    let out = dir.path().join("f.png");
    let run = |extra: &[&str]| painted_by_two_fields(&path, &out, extra);
    let o = run(&[
        "--color-scale",
        "sphere=magma:0:0.5",
        "--color-range",
        "0:3",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    // A scale without a range of its own takes `--color-range` too: two fields would share it.
    let o = run(&["--color-scale", "sphere=magma", "--color-range", "0:3"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("2 fields paint"), "{}", stderr(&o));
    let o = run(&["--color-scale", "nope=magma"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("nope paints nothing in this frame (painting: ramp, sphere)"),
        "{}",
        stderr(&o)
    );
    let o = run(&["--color-scale", "sphere=nope"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("unknown colormap 'nope'"),
        "{}",
        stderr(&o)
    );
}

/// `amr-render` on `path` (`sphere_and_ramp`'s file) with its sphere surface painted by `ramp`
/// and a slice painted by `sphere`, into `out`, with `extra` arguments.
fn painted_by_two_fields(path: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        path.to_str().unwrap(),
        "--field",
        "sphere",
        "--iso",
        "0",
        "--color-by",
        "ramp",
        "--slice",
        "z=0.4",
        "--slice-field",
        "sphere",
        "--size",
        "64x48",
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    amr_render(&args)
}

/// A camera inside a closed surface gets a warning that names it (once, for an orbit that stays
/// inside); a close-up from outside that fills the frame as well gets none.
#[test]
fn a_camera_enclosed_by_a_surface_is_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let file = sphere(dir.path());
    let f = file.to_str().unwrap();
    let out = dir.path().join("in.png");
    let o = amr_render(&[
        f,
        "--iso",
        "0",
        "--size",
        "32x24",
        "--camera-pos",
        "0.47,0.52,0.5",
        "--look-at",
        "0.47,0.52,0.0",
        "--orbit",
        "3",
        "--quiet",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let warning = "the camera at (0.47, 0.52, 0.5) is enclosed by the surface sphere = 0";
    assert_eq!(stderr(&o).matches(warning).count(), 1, "{}", stderr(&o));

    let o = amr_render(&[
        f,
        "--iso",
        "0",
        "--size",
        "32x24",
        "--camera-pos",
        "0.47,0.52,0.9",
        "--look-at",
        "0.47,0.52,0.5",
        "--fov",
        "5",
        "--quiet",
        "--stats-json",
        "-",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stats: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        stats["covered_pixels"],
        32 * 24,
        "the close-up fills the frame"
    );
    assert!(!stderr(&o).contains("enclosed"), "{}", stderr(&o));
}

/// `--color-range auto-series` with two fields painting (refused until 2026-12-07): each
/// field's colour range is its range over every file of the series, the same in every frame,
/// and a field's own `--color-scale` range stays its own.
#[test]
fn auto_series_gives_each_painting_field_its_range_over_the_series() {
    let dir = tempfile::tempdir().unwrap();
    let (da, db) = (dir.path().join("a"), dir.path().join("b"));
    std::fs::create_dir_all(&da).unwrap();
    std::fs::create_dir_all(&db).unwrap();
    let a = sphere_and_ramp(&da);
    let b = synth_file::sphere_and_ramp(&db, &SynthParams::unit_cube(2, 2, 16, 8), &|p| {
        3.0 * p[0] - 1.0
    });
    let range = |name: &str| {
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for path in [&a, &b] {
            let file = amr_format::AmrkFile::open(std::fs::read(path).unwrap()).unwrap();
            let f = &file.fields()[file.field_index(name).unwrap()];
            (lo, hi) = (lo.min(f.min), hi.max(f.max));
        }
        (f64::from(lo), f64::from(hi))
    };
    let out = dir.path().join("s.exr");
    let run_by = |by: &str, extra: &[&str]| {
        let mut args = vec![
            a.to_str().unwrap(),
            b.to_str().unwrap(),
            "--field",
            "sphere",
            "--iso",
            "0",
            "--color-by",
            by,
            "--slice",
            "z=0.5",
            "--slice-field",
            "sphere",
            "--color-range",
            "auto-series",
            "--size",
            "24x18",
            "-q",
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        amr_render(&args)
    };
    let run = |extra: &[&str]| run_by("ramp", extra);
    let o = run(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let first = attribute(&dir.path().join("s_0000.exr"), "color_ranges");
    assert_eq!(
        first,
        attribute(&dir.path().join("s_0001.exr"), "color_ranges")
    );
    // `FIELD LO HI COLORMAP; ...`, the fields in the order they first paint.
    let parsed: Vec<(String, f64, f64)> = first
        .split("; ")
        .map(|r| {
            let p: Vec<&str> = r.split(' ').collect();
            (
                p[0].to_string(),
                p[1].parse().unwrap(),
                p[2].parse().unwrap(),
            )
        })
        .collect();
    assert_eq!(parsed.len(), 2, "{first}");
    for (name, lo, hi) in &parsed {
        let (want_lo, want_hi) = range(name);
        assert!(
            (lo - want_lo).abs() <= 1e-6 * want_lo.abs().max(1.0)
                && (hi - want_hi).abs() <= 1e-6 * want_hi.abs().max(1.0),
            "{name}: {lo}..{hi}, over the series {want_lo}..{want_hi}"
        );
    }
    let o = run(&["--color-scale", "ramp=:0:1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let ranges = attribute(&dir.path().join("s_0000.exr"), "color_ranges");
    assert!(ranges.starts_with("ramp 0 1 "), "{ranges}");
    // A magnitude's range over the series: from 0 (both fields cross it) to the length of the
    // components' largest magnitudes.
    let o = run_by("|ramp,sphere|", &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let ranges = attribute(&dir.path().join("s_0000.exr"), "color_ranges");
    let (r, s) = (range("ramp"), range("sphere"));
    let far = |r: (f64, f64)| r.0.abs().max(r.1.abs());
    assert!(r.0 <= 0.0 && s.0 < 0.0 && s.1 > 0.0, "{r:?} {s:?}");
    let hi: f64 = ranges.split(' ').nth(2).unwrap().parse().unwrap();
    let want = far(r).hypot(far(s));
    assert!(ranges.starts_with("|ramp,sphere| 0 "), "{ranges}");
    assert!((hi - want).abs() <= 1e-6 * want, "{ranges}: want {want}");
    let o = run_by("|ramp,nope|", &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("'nope'"), "{}", stderr(&o));
}

/// Renders `file` with `args` into `dir/first.EXT` with `--write-scene dir/scene.toml`, then
/// that scene file alone into `dir/again.EXT`: both outputs and the scene file's text.
fn drawn_again_from_its_scene_file(
    dir: &Path,
    file: &str,
    args: &[&str],
    ext: &str,
) -> (PathBuf, PathBuf, String) {
    let (first, again) = (
        dir.join(format!("first.{ext}")),
        dir.join(format!("again.{ext}")),
    );
    let scene = dir.join("scene.toml");
    let o = amr_render(
        &[
            &[file][..],
            args,
            &["-o", first.to_str().unwrap()],
            &["--write-scene", scene.to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = amr_render(&[scene.to_str().unwrap(), "-o", again.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    (first, again, std::fs::read_to_string(&scene).unwrap())
}

/// `--ortho` draws an orthographic frame, named in the EXR header and saved in a scene file that
/// draws it again; a view height asks for `--ortho` and a positive length.
#[test]
fn an_orthographic_view_is_drawn_saved_and_checked() {
    let dir = tempfile::tempdir().unwrap();
    let file = sphere(dir.path());
    let (d, f) = (dir.path(), file.to_str().unwrap());
    let args = ["--ortho", "--view-height", "0.8", "--size", "40x30"];
    let (first, again, text) = drawn_again_from_its_scene_file(d, f, &args, "exr");
    let camera = attribute(&first, "camera");
    assert!(camera.contains("orthographic view_height=0.8"), "{camera}");
    assert!(
        text.contains("ortho = true") && text.contains("view-height = 0.8"),
        "{text}"
    );
    for c in ["R", "G", "B", "A", "Z"] {
        assert_eq!(bits(&first, c), bits(&again, c), "channel {c}");
    }
    let out = d.join("x.png");
    let out = out.to_str().unwrap();
    for (args, says) in [
        (&["--view-height", "0.5"][..], "--ortho"),
        (&["--ortho", "--view-height", "0"][..], "--view-height 0 "),
        (&["--ortho", "--view-height", "-2"][..], "--view-height -2 "),
    ] {
        let o = amr_render(&[&[f, "-o", out][..], args].concat());
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        assert!(stderr(&o).contains(says), "{args:?}: {}", stderr(&o));
    }
    assert!(!Path::new(out).exists());
}

/// `--background white` gives a PNG that is white where nothing is drawn, saved in a scene file
/// that draws it again; a colour that is not one is refused naming it.
#[test]
fn a_background_colour_is_drawn_saved_and_checked() {
    let dir = tempfile::tempdir().unwrap();
    let file = sphere(dir.path());
    let (d, f) = (dir.path(), file.to_str().unwrap());
    let args = ["--background", "white", "--size", "80x60"];
    let (first, again, text) = drawn_again_from_its_scene_file(d, f, &args, "png");
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(&first).unwrap(),
    ));
    let mut reader = decoder.read_info().unwrap();
    let mut rgb = vec![0; reader.output_buffer_size()];
    reader.next_frame(&mut rgb).unwrap();
    // The top right corner: no surface, line or legend there.
    let corner = 3 * (80 - 1);
    assert_eq!(&rgb[corner..corner + 3], &[255, 255, 255]);
    assert!(text.contains("background = \"white\""), "{text}");
    assert_eq!(
        std::fs::read(&first).unwrap(),
        std::fs::read(&again).unwrap()
    );
    let out = d.join("x.png");
    let o = amr_render(&[f, "--background", "nocolour", "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("unknown colour 'nocolour'"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists());
}
