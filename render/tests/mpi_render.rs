//! `mpirun -n 2` and `-n 4` (oversubscribed) against the single-process frame: the replicated mode
//! gives the same pixels bit for bit; the partitioned mode the same first hits (Z, P, N, level,
//! coverage) and, without shadows and ambient occlusion, nearly the same colour.
//!
//! Runs with the `mpi` feature only, and fails, naming what is missing, when `mpirun` is absent.
#![cfg(feature = "mpi")]

use std::path::{Path, PathBuf};
use std::process::Command;

use amr_format::progress::NoProgress;
use amr_format::WriterOptions;
use amr_render::output::exr_file::read_channel;
use amr_synth::{write_synth, AnalyticField, Case, SynthParams};

const CHANNELS: [&str; 12] = [
    "R", "G", "B", "A", "Z", "N.X", "N.Y", "N.Z", "P.X", "P.Y", "P.Z", "level",
];
const FIRST_HIT: [&str; 9] = ["A", "Z", "N.X", "N.Y", "N.Z", "P.X", "P.Y", "P.Z", "level"];

/// `$MPIRUN`, or `mpirun` or `mpiexec` on `PATH`.
fn mpirun() -> PathBuf {
    if let Some(p) = std::env::var_os("MPIRUN") {
        return PathBuf::from(p);
    }
    let path = std::env::var_os("PATH").unwrap_or_default();
    for dir in std::env::split_paths(&path) {
        for name in ["mpirun", "mpiexec"] {
            let p = dir.join(name);
            if p.is_file() {
                return p;
            }
        }
    }
    panic!(
        "the `mpi` feature is on but neither mpirun nor mpiexec is on PATH: install Open MPI \
         (openmpi-bin, see .ci/install-deps) or set MPIRUN=/path/to/mpirun"
    );
}

/// A small three-level file of two blobs, with leaves enough to share among four ranks.
fn dataset(dir: &Path) -> PathBuf {
    let path = dir.join("blobs.amrk");
    let params = SynthParams::unit_cube(3, 2, 16, 8);
    write_synth(
        &path,
        Case::Blobs,
        &params,
        WriterOptions::default(),
        &NoProgress,
    )
    .unwrap();
    path
}

fn render_args(file: &Path, out: &Path, extra: &[&str]) -> Vec<String> {
    let mut a: Vec<String> = [
        file.to_str().unwrap(),
        "--iso",
        "10:orange:1",
        "--iso",
        "5:#3070ff:0.4",
        "--size",
        "96x72",
        "-o",
        out.to_str().unwrap(),
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    a.extend(extra.iter().map(|s| s.to_string()));
    a
}

fn check(out: std::process::Output, what: &str) {
    assert!(
        out.status.success(),
        "{what} failed ({}):\n{}{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

fn single(file: &Path, out: &Path, extra: &[&str]) {
    let o = Command::new(env!("CARGO_BIN_EXE_amr-render"))
        .args(render_args(file, out, extra))
        .output()
        .unwrap();
    check(o, "single-process render");
}

/// `mpirun -n N amr-render`, arguments to follow.
fn mpirun_render(n: usize) -> Command {
    let mut c = Command::new(mpirun());
    c.args(["--oversubscribe", "--bind-to", "none", "-n", &n.to_string()])
        .arg(env!("CARGO_BIN_EXE_amr-render"))
        // Open MPI refuses root (as in CI containers) without these.
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_btl_vader_single_copy_mechanism", "none");
    c
}

fn mpi(n: usize, file: &Path, out: &Path, extra: &[&str]) -> String {
    let o = mpirun_render(n)
        .args(render_args(file, out, extra))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    check(o, &format!("mpirun -n {n} {extra:?}"));
    err
}

fn channel(path: &Path, name: &str) -> Vec<u32> {
    let (_, _, v) = read_channel(path, name).unwrap();
    v.iter().map(|x| x.to_bits()).collect()
}

/// How many of the R, G and B values of the frames `a` and `b` differ by more than 1e-5, and of
/// how many.
fn colour_values_off(a: &Path, b: &Path) -> (usize, usize) {
    let (mut off, mut total) = (0, 0);
    for c in ["R", "G", "B"] {
        let (_, _, x) = read_channel(a, c).unwrap();
        let (_, _, y) = read_channel(b, c).unwrap();
        total += x.len();
        off += x
            .iter()
            .zip(&y)
            .filter(|(p, q)| (*p - *q).abs() > 1e-5)
            .count();
    }
    (off, total)
}

#[test]
fn replicated_frames_equal_the_single_process_frame() {
    let dir = tempfile::tempdir().unwrap();
    let file = dataset(dir.path());
    let reference = dir.path().join("single.exr");
    single(&file, &reference, &[]);
    assert!(channel(&reference, "A")
        .iter()
        .any(|&a| f32::from_bits(a) > 0.0));
    for n in [2, 4] {
        let out = dir.path().join(format!("replicated{n}.exr"));
        let json = dir.path().join(format!("replicated{n}.json"));
        mpi(n, &file, &out, &["--stats-json", json.to_str().unwrap()]);
        for c in CHANNELS {
            assert!(
                channel(&out, c) == channel(&reference, c),
                "-n {n}: channel {c} differs from the single-process frame"
            );
        }
        let stats = std::fs::read_to_string(&json).unwrap();
        assert!(stats.contains(&format!("\"mpi_ranks\": {n}")), "{stats}");
        assert_eq!(stats.matches("\"rank\":").count(), n, "{stats}");
    }
}

#[test]
fn every_reconstruction_under_mpirun_equals_its_single_process_frame() {
    let dir = tempfile::tempdir().unwrap();
    let file = dataset(dir.path());
    for (recon, method) in [
        ("octant", "hybrid"),
        ("current", "hybrid"),
        ("nearest", "hybrid"),
        ("octant", "sample"),
    ] {
        let extra = ["--reconstruction", recon, "--method", method, "--ao", "1"];
        let reference = dir.path().join(format!("single-{recon}-{method}.exr"));
        single(&file, &reference, &extra);
        let out = dir.path().join(format!("mpi-{recon}-{method}.exr"));
        mpi(2, &file, &out, &extra);
        for c in CHANNELS {
            assert!(
                channel(&out, c) == channel(&reference, c),
                "{recon}/{method}: channel {c} differs from the single-process frame"
            );
        }
    }
    // The reconstructions give different frames: each rank traced the one asked for.
    let z = |r: &str| channel(&dir.path().join(format!("mpi-{r}-hybrid.exr")), "N.X");
    assert_ne!(z("octant"), z("nearest"));
    assert_ne!(z("current"), z("nearest"));
}

#[test]
fn partitioned_frames_have_the_single_process_first_hits() {
    let dir = tempfile::tempdir().unwrap();
    let file = dataset(dir.path());
    let reference = dir.path().join("single.exr");
    // No outline: lines behind transparent surfaces are blended by the coverage, which a
    // composite sums in another order.
    let flat = ["--no-shadows", "--ao", "0", "--outline", "none"];
    single(&file, &reference, &flat);
    for n in [2, 4] {
        let out = dir.path().join(format!("partitioned{n}.exr"));
        let json = dir.path().join(format!("partitioned{n}.json"));
        let mut extra = vec![
            "--mpi-mode",
            "partitioned",
            "--stats-json",
            json.to_str().unwrap(),
        ];
        extra.extend(flat);
        mpi(n, &file, &out, &extra);
        for c in FIRST_HIT {
            assert!(
                channel(&out, c) == channel(&reference, c),
                "-n {n}: channel {c} differs from the single-process frame"
            );
        }
        // Colour: the same up to the order of floating-point sums, except where a transparent
        // surface crosses a part boundary (docs/mpi.md).
        let (off, total) = colour_values_off(&out, &reference);
        eprintln!("-n {n}: {off} of {total} colour values differ by more than 1e-5");
        assert!(
            off * 100 <= total,
            "-n {n}: {off} of {total} colour values differ"
        );
        let stats = std::fs::read_to_string(&json).unwrap();
        assert!(stats.contains("\"mpi_mode\": \"partitioned\""), "{stats}");
        // Each rank holds only its part of the octants.
        let single_json = dir.path().join("single.json");
        single(
            &file,
            &dir.path().join("s.exr"),
            &["--stats-json", single_json.to_str().unwrap()],
        );
        let total_octants = |s: &str| -> u64 {
            let line = s
                .lines()
                .find(|l| l.contains("\"active_octants\""))
                .unwrap();
            line.split(':')
                .nth(1)
                .unwrap()
                .trim()
                .trim_end_matches(',')
                .parse()
                .unwrap()
        };
        let all = total_octants(&std::fs::read_to_string(&single_json).unwrap());
        assert_eq!(total_octants(&stats), all, "{stats}");
        let per_rank: Vec<u64> = stats
            .split("\"active_octants\": ")
            .skip(2)
            .map(|s| s.split(',').next().unwrap().trim().parse().unwrap())
            .collect();
        assert_eq!(per_rank.len(), n, "{stats}");
        assert_eq!(per_rank.iter().sum::<u64>(), all);
        assert!(
            per_rank.iter().all(|&k| k * n as u64 <= 2 * all),
            "{per_rank:?} of {all}"
        );
    }
}

/// Surfaces painted by a field and by level, and a translucent slice, under mpirun's
/// replicated mode: the frame, its painted values and its picture with the legend's colour bar
/// equal the single process's, bit for bit (they were left out under mpirun until
/// 2026-12-07). The partitioned mode says it leaves them out.
#[test]
fn painted_surfaces_and_slices_under_mpirun_equal_the_single_process_frame() {
    let dir = tempfile::tempdir().unwrap();
    let file = dataset(dir.path());
    let paint = [
        "--color-by",
        "blobs",
        "--color-by",
        "level",
        "--slice",
        "z=0.45:0.6",
        "--colormap",
        "magma",
    ];
    // Large enough for the legend and its colour bar.
    let args = |out: &Path, extra: &[&str]| -> Vec<String> {
        let png = out.with_extension("png");
        let mut a = render_args(&file, out, &paint);
        a.extend(extra.iter().map(|s| s.to_string()));
        a.extend(["--preview".into(), png.to_str().unwrap().into()]);
        a.iter()
            .map(|s| {
                if s == "96x72" {
                    "240x180".into()
                } else {
                    s.clone()
                }
            })
            .collect()
    };
    let reference = dir.path().join("single.exr");
    let o = Command::new(env!("CARGO_BIN_EXE_amr-render"))
        .args(args(&reference, &[]))
        .output()
        .unwrap();
    check(o, "single-process render");
    let painted = channel(&reference, "color_value");
    assert!(
        painted
            .iter()
            .filter(|&&v| f32::from_bits(v).is_finite())
            .count()
            > 1000,
        "too few painted pixels for a test"
    );
    let out = dir.path().join("replicated.exr");
    let o = mpirun_render(2).args(args(&out, &[])).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    check(o, "mpirun -n 2, painted");
    assert!(!err.contains("note"), "{err}");
    for c in CHANNELS.iter().chain(&["color_value"]) {
        assert!(
            channel(&out, c) == channel(&reference, c),
            "channel {c} differs from the single-process frame"
        );
    }
    let png = |p: &Path| std::fs::read(p.with_extension("png")).unwrap();
    assert!(
        png(&out) == png(&reference),
        "the picture (with its legend) differs"
    );
    let part = dir.path().join("part.exr");
    let extra = ["--mpi-mode", "partitioned", "--no-shadows", "--ao", "0"];
    let o = mpirun_render(2).args(args(&part, &extra)).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    check(o, "mpirun -n 2 partitioned, painted");
    assert!(err.contains("draws no --color-by and no slices"), "{err}");
}

/// Under mpirun, as in one process, the default camera frames the isosurfaces, and
/// `--frame-domain` the domain: a small surface is not left a speck in a wide view (it framed
/// the domain until 2026-12-07). Both modes, each rank holding the whole scene or a part of it.
#[test]
fn the_default_camera_under_mpirun_frames_the_surfaces_as_one_process_does() {
    let dir = tempfile::tempdir().unwrap();
    let file = dataset(dir.path());
    let camera = |out: &Path| {
        let attrs = amr_render::output::exr_file::read_text_attributes(out).unwrap();
        attrs.into_iter().find(|(k, _)| k == "camera").unwrap().1
    };
    // One blob's core: a surface in a small part of the domain.
    let args = |out: &Path, extra: &[&str]| -> Vec<String> {
        let mut a: Vec<String> = [file.to_str().unwrap(), "--iso", "40", "--size", "96x72"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        a.extend(extra.iter().map(|s| s.to_string()));
        a.extend(["-o".to_string(), out.to_str().unwrap().to_string()]);
        a
    };
    let run_single = |out: &Path, extra: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_amr-render"))
            .args(args(out, extra))
            .output()
            .unwrap();
        check(o, "single-process render");
        camera(out)
    };
    let framed = run_single(
        &dir.path().join("framed.exr"),
        &["--no-shadows", "--ao", "0"],
    );
    let domain = run_single(
        &dir.path().join("domain.exr"),
        &["--no-shadows", "--ao", "0", "--frame-domain"],
    );
    assert_ne!(framed, domain, "the surface fills the domain: no test");
    for (mode, want) in [
        ("replicated", &framed),
        ("partitioned", &framed),
        ("replicated", &domain),
    ] {
        let mut extra = vec!["--mpi-mode", mode, "--no-shadows", "--ao", "0"];
        if want == &domain {
            extra.push("--frame-domain");
        }
        let out = dir.path().join(format!("{mode}-{}.exr", extra.len()));
        let o = mpirun_render(2).args(args(&out, &extra)).output().unwrap();
        check(o, &format!("mpirun -n 2 {extra:?}"));
        assert_eq!(&camera(&out), want, "{extra:?}");
    }
}

#[test]
fn mpi_options_without_mpirun_are_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let file = dataset(dir.path());
    let o = Command::new(env!("CARGO_BIN_EXE_amr-render"))
        .args(render_args(
            &file,
            &dir.path().join("x.exr"),
            &["--mpi-mode", "partitioned"],
        ))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("mpirun"));
}

#[test]
fn a_bad_file_under_mpirun_is_one_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.amrk");
    let out = dir.path().join("x.exr");
    let o = mpirun_render(2)
        .args(render_args(&missing, &out, &[]))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert_eq!(err.matches("missing.amrk").count(), 1, "{err}");
}

#[test]
fn a_clip_or_view_limited_extraction_under_mpirun_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let file = dataset(dir.path());
    let out = dir.path().join("x.exr");
    for extra in [&["--clip", "0,0,0,0.5,1,1"][..], &["--extract-in-view"]] {
        let o = mpirun_render(1)
            .args(render_args(&file, &out, extra))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{extra:?}: {err}");
        assert!(
            err.contains("not supported under mpirun"),
            "{extra:?}: {err}"
        );
        assert!(!out.exists());
    }
}

/// Surfaces of two fields (`--iso FIELD=V`) in partitioned mode (refused until 2026-12-07):
/// each rank extracts its share of each field's leaves, and the frame has the single-process
/// first hits.
#[test]
fn partitioned_frames_of_two_fields_have_the_single_process_first_hits() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("two.amrk");
    let params = SynthParams::unit_cube(3, 2, 16, 8);
    let mut spec = amr_synth::build_hierarchy(&Case::Sphere, "sphere", &params).unwrap();
    spec.fields = vec!["sphere".into(), "ramp".into()];
    let sphere = |p: [f64; 3]| Case::Sphere.value(p);
    let ramp = |p: [f64; 3]| p[0] + 0.5 * p[1];
    amr_synth::write_fields(&file, spec, &[&sphere, &ramp], WriterOptions::default()).unwrap();
    let args = |out: &Path| -> Vec<String> {
        [
            file.to_str().unwrap(),
            "--field",
            "sphere",
            "--iso",
            "0:orange",
            "--iso",
            "ramp=1:#3070ff",
            "--size",
            "96x72",
            "--no-shadows",
            "--ao",
            "0",
            "--outline",
            "none",
            "-o",
            out.to_str().unwrap(),
        ]
        .iter()
        .map(|s| s.to_string())
        .collect()
    };
    let reference = dir.path().join("single.exr");
    let o = Command::new(env!("CARGO_BIN_EXE_amr-render"))
        .args(args(&reference))
        .output()
        .unwrap();
    check(o, "single-process render");
    let out = dir.path().join("partitioned.exr");
    let o = mpirun_render(2)
        .args(args(&out))
        .args(["--mpi-mode", "partitioned"])
        .output()
        .unwrap();
    check(o, "mpirun -n 2 --mpi-mode partitioned, two fields");
    let covered = channel(&reference, "A")
        .iter()
        .filter(|&&a| f32::from_bits(a) > 0.0)
        .count();
    assert!(covered > 300, "{covered} pixels covered");
    for c in FIRST_HIT {
        assert!(
            channel(&out, c) == channel(&reference, c),
            "channel {c} differs from the single-process frame"
        );
    }
    // Both surfaces are in the frame: orange (red over blue) and blue pixels.
    let (r, b) = (channel(&out, "R"), channel(&out, "B"));
    let blue = r
        .iter()
        .zip(&b)
        .filter(|(r, b)| f32::from_bits(**b) > f32::from_bits(**r) + 0.05)
        .count();
    assert!(
        blue > 30 && blue + 30 < covered,
        "{blue} blue pixels of {covered}"
    );
}

/// An orthographic view under mpirun: replicated frames equal the single process's bit for bit,
/// and partitioned ones have its first hits and nearly its colour. The view's parallel rays
/// cross split planes that the camera's position lies beyond; that the parts are ordered along
/// the view there is checked by `partition::tests` (this frame came out the same with the
/// order taken from the camera's position).
#[test]
fn orthographic_frames_under_mpirun_equal_the_single_process_frame() {
    let dir = tempfile::tempdir().unwrap();
    let file = dataset(dir.path());
    // Rays along (-1, 1, 0) from a camera whose x is the domain's middle.
    let view = [
        "--ortho",
        "--camera-pos",
        "0.5,-0.5,0.5",
        "--look-at",
        "-0.5,0.5,0.5",
        "--view-height",
        "1.2",
    ];
    let reference = dir.path().join("single.exr");
    single(&file, &reference, &view);
    let out = dir.path().join("replicated.exr");
    mpi(2, &file, &out, &view);
    for c in CHANNELS {
        assert!(
            channel(&out, c) == channel(&reference, c),
            "replicated: channel {c} differs from the single-process frame"
        );
    }
    let flat = ["--no-shadows", "--ao", "0", "--outline", "none"];
    let reference = dir.path().join("single-flat.exr");
    single(&file, &reference, &[&view[..], &flat].concat());
    for n in [2, 4] {
        let out = dir.path().join(format!("partitioned{n}.exr"));
        let extra = [&view[..], &flat, &["--mpi-mode", "partitioned"]].concat();
        mpi(n, &file, &out, &extra);
        for c in FIRST_HIT {
            assert!(
                channel(&out, c) == channel(&reference, c),
                "partitioned -n {n}: channel {c} differs from the single-process frame"
            );
        }
        let (off, total) = colour_values_off(&out, &reference);
        assert!(
            off * 100 <= total,
            "partitioned -n {n}: {off} of {total} colour values differ"
        );
    }
}
