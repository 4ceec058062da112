//! Hostile files and faults (issue 15), through the `amr-render` program: damaged files whose
//! checksums are right, outputs that would replace an input or a device, a file truncated or
//! rewritten while it is mapped, and a seeded mutation fuzzer. Every run must exit 0, or 1 with a
//! message: never a panic (101), a signal or a hang.
//!
//! The fuzzer runs `AMR_FUZZ_CASES` mutated files (default 1000, about 15 s); for a nightly run:
//! `AMR_FUZZ_CASES=100000 cargo test --release -p amr-render --test hostile fuzz -- --nocapture`
//! (`AMR_FUZZ_SEED` moves the seeds; `AMR_FUZZ_BIN` runs another `amr-render` binary, such as an
//! installed or older one). Failing files are kept in `target/hostile-fuzz/`.

use std::os::unix::fs::FileExt;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use amr_format::progress::NoProgress;
use amr_format::raw::{Footer, KdLeaf, KD_LEAF};
use amr_format::reader::recompute_checksums;
use amr_format::{Compression, WriterOptions};
use amr_render::mapping::open_mapped;
use amr_synth::{write_synth, Case, SynthParams};
use zerocopy::FromBytes;

// The fuzzers' child-process runner and the two-field file of the integration tests' support.
#[path = "../../tests/tests/support/fuzz.rs"]
mod fuzz;
#[path = "../../tests/tests/support/synth_file.rs"]
#[allow(dead_code)]
mod synth_file;

use fuzz::{env_u64, run_killed_after, Outcome};

const BIN: &str = env!("CARGO_BIN_EXE_amr-render");
/// A run taking longer than this is a hang.
const TIMEOUT: Duration = Duration::from_secs(20);

/// Whether a run ended as the fuzzers require.
trait EndedCleanly {
    /// Exit 0, or exit 1 with an `Error:` message; `None` when so, else what is wrong.
    fn problem(&self) -> Option<String>;
}

impl EndedCleanly for Outcome {
    fn problem(&self) -> Option<String> {
        match (self.timed_out, self.signal, self.code) {
            (true, ..) => Some("timed out".into()),
            (_, Some(s), _) => Some(format!("killed by signal {s}")),
            (_, _, Some(0)) => None,
            (_, _, Some(1)) if self.stderr.starts_with("Error: ") => None,
            (_, _, c) => Some(format!("exit {c:?}")),
        }
    }
}

/// Runs `amr-render args`, killing it after [`TIMEOUT`].
fn run(args: &[&str]) -> Outcome {
    run_bin(BIN.as_ref(), args)
}

/// Runs `bin args`, killing it after [`TIMEOUT`].
fn run_bin(bin: &std::ffi::OsStr, args: &[&str]) -> Outcome {
    let mut cmd = Command::new(bin);
    cmd.args(args);
    run_killed_after(cmd, TIMEOUT)
}

/// A small synthetic file and an isovalue crossing its field.
fn base_file(dir: &Path, case: Case, compress: bool) -> (PathBuf, f32) {
    let path = dir.join(format!(
        "{case}{}.amrk",
        if compress { "-zstd" } else { "" }
    ));
    let params = small_params();
    let compression = if compress {
        Compression::Zstd { level: 3 }
    } else {
        Compression::None
    };
    write_synth(
        &path,
        case,
        &params,
        WriterOptions {
            compression,
            ..Default::default()
        },
        &NoProgress,
    )
    .unwrap();
    let file = open_mapped(&path).unwrap();
    let f = &file.fields()[0];
    (path, 0.5 * (f.min + f.max))
}

fn footer_of(b: &[u8]) -> Footer {
    Footer::read_from_bytes(&b[b.len() - size_of::<Footer>()..]).unwrap()
}

/// The three runs of the fuzzer on `path`: `info`, `extract` and a 32x32 render.
fn three_runs(path: &str, iso: f32, out: &str) -> Vec<Vec<String>> {
    let iso = format!("--iso={iso}");
    let runs: [&[&str]; 3] = [
        &["info", path],
        &["extract", path, &iso],
        &[path, &iso, "-o", out, "--size", "32x32"],
    ];
    runs.iter()
        .map(|r| r.iter().map(|a| a.to_string()).collect())
        .collect()
}

/// Runs `runs` in turn; returns the first problem, naming the command.
fn check_all(bin: &std::ffi::OsStr, runs: &[Vec<String>]) -> Option<String> {
    runs.iter().find_map(|args| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let outcome = run_bin(bin, &args);
        outcome.problem().map(|m| {
            let tail: String = outcome.stderr.chars().take(600).collect();
            format!("amr-render {}: {m}: {tail}", args.join(" "))
        })
    })
}

/// Rewrites `b`: a u32 of a table, of the footer or of the header replaced, or the file cut.
fn mutate(b: &mut Vec<u8>, rng: &mut Rng) {
    let f = footer_of(b);
    let footer_at = b.len() - size_of::<Footer>();
    let tables = [
        f.levels,
        f.fields,
        f.bricks,
        f.nodes,
        f.leaves,
        f.brick_list,
        f.strings,
    ];
    for _ in 0..1 + rng.below(3) {
        let (start, len) = match rng.below(8) {
            0 => (0, 64),
            1 => (footer_at, size_of::<Footer>() - 8),
            2 => (
                f.metadata.offset.get() as usize,
                f.metadata.len.get() as usize,
            ),
            _ => {
                let s = tables[rng.below(tables.len() as u64) as usize];
                (s.offset.get() as usize, s.len.get() as usize)
            }
        };
        if len < 4 {
            continue;
        }
        let at = start + 4 * rng.below(len as u64 / 4) as usize;
        let old = u32::from_le_bytes(b[at..at + 4].try_into().unwrap());
        let new = match rng.below(6) {
            0 => old ^ (1 << rng.below(32)),
            1 => old.wrapping_add(1),
            2 => old.wrapping_sub(1),
            3 => [0, 1, 2, 3, u32::MAX, 1 << 31][rng.below(6) as usize],
            4 => old.wrapping_add(rng.below(64) as u32),
            _ => rng.next() as u32,
        };
        b[at..at + 4].copy_from_slice(&new.to_le_bytes());
    }
    if rng.below(20) == 0 {
        let keep = rng.below(b.len() as u64) as usize;
        b.truncate(keep);
    } else if rng.below(10) != 0 {
        recompute_checksums(b);
    }
}

/// SplitMix64: every case is named by its seed.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n.max(1)
    }
}

#[test]
fn fuzz_mutated_files_exit_cleanly() {
    let cases = env_u64("AMR_FUZZ_CASES", 1000);
    let seed0 = env_u64("AMR_FUZZ_SEED", 0);
    let bin = std::env::var_os("AMR_FUZZ_BIN").unwrap_or_else(|| BIN.into());
    let dir = tempfile::tempdir().unwrap();
    let bases: Vec<(Vec<u8>, f32)> = [
        (Case::Blobs, false),
        (Case::Ripple, true),
        (Case::Sphere, false),
    ]
    .into_iter()
    .map(|(case, z)| {
        let (p, iso) = base_file(dir.path(), case, z);
        (std::fs::read(p).unwrap(), iso)
    })
    .collect();
    let keep = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/hostile-fuzz");
    let (path, out) = (dir.path().join("m.amrk"), dir.path().join("m.exr"));
    let (mut opened, mut failures) = (0u64, Vec::new());
    let start = Instant::now();
    for seed in seed0..seed0 + cases {
        let mut rng = Rng(seed);
        let (base, iso) = &bases[rng.below(bases.len() as u64) as usize];
        let mut b = base.clone();
        mutate(&mut b, &mut rng);
        std::fs::write(&path, &b).unwrap();
        if amr_format::AmrkFile::open(&b[..]).is_ok() {
            opened += 1;
        }
        let runs = three_runs(path.to_str().unwrap(), *iso, out.to_str().unwrap());
        if let Some(problem) = check_all(&bin, &runs) {
            std::fs::create_dir_all(&keep).unwrap();
            let kept = keep.join(format!("seed-{seed}.amrk"));
            std::fs::write(&kept, &b).unwrap();
            failures.push(format!("seed {seed} ({}): {problem}", kept.display()));
        }
    }
    eprintln!(
        "fuzz: {cases} mutated files (seeds {seed0}..{}), {opened} opened, {} failures, {:.1} s",
        seed0 + cases,
        failures.len(),
        start.elapsed().as_secs_f64()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The synthetic files' hierarchy: three levels, bricks of 4 cells.
fn small_params() -> SynthParams {
    SynthParams {
        levels: 3,
        ratio: 2,
        base: 8,
        brick: 4,
        origin: [0.0; 3],
        size: 1.0,
    }
}

/// A small two-field file: `sphere`, refined around its zero surface, and `ramp`.
fn two_field_file(dir: &Path) -> PathBuf {
    synth_file::sphere_and_ramp(dir, &small_params(), &|p| p[0] + 0.5 * p[1])
}

/// The fuzzer of [`fuzz_mutated_files_exit_cleanly`] on a file of two fields, whose second
/// field is read by every run: extracted, traced as a surface beside the first's
/// (`--iso ramp=1`) and painting both (`AMR_FUZZ_CASES`, default 300, about 5 s).
#[test]
fn fuzz_mutated_two_field_files_exit_cleanly() {
    let cases = env_u64("AMR_FUZZ_CASES", 300);
    let seed0 = env_u64("AMR_FUZZ_SEED", 0);
    let bin = std::env::var_os("AMR_FUZZ_BIN").unwrap_or_else(|| BIN.into());
    let dir = tempfile::tempdir().unwrap();
    let base = std::fs::read(two_field_file(dir.path())).unwrap();
    let keep = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/hostile-fuzz");
    let (path, out) = (dir.path().join("m.amrk"), dir.path().join("m.exr"));
    let (p, o) = (path.to_str().unwrap(), out.to_str().unwrap());
    let runs: Vec<Vec<String>> = [
        &["info", p][..],
        &["extract", p, "--field", "ramp", "--iso", "1"],
        &[
            p,
            "--field",
            "sphere",
            "--iso",
            "0",
            "--iso",
            "ramp=1",
            "--color-by",
            "ramp",
            "-o",
            o,
            "--size",
            "32x32",
        ],
    ]
    .iter()
    .map(|r| r.iter().map(|a| a.to_string()).collect())
    .collect();
    // The undamaged file passes every run: the runs read what they are meant to.
    std::fs::write(&path, &base).unwrap();
    for args in &runs {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = run_bin(bin.as_os_str(), &args);
        assert_eq!(o.code, Some(0), "{args:?}: {}", o.stderr);
    }
    let mut failures = Vec::new();
    for seed in seed0..seed0 + cases {
        let mut rng = Rng(seed);
        let mut b = base.clone();
        mutate(&mut b, &mut rng);
        std::fs::write(&path, &b).unwrap();
        if let Some(problem) = check_all(&bin, &runs) {
            std::fs::create_dir_all(&keep).unwrap();
            let kept = keep.join(format!("two-seed-{seed}.amrk"));
            std::fs::write(&kept, &b).unwrap();
            failures.push(format!("seed {seed} ({}): {problem}", kept.display()));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The two files of the issue that panicked the renderer (a root split moved by one cell; a
/// leaf's first brick replaced by one not covering it), through every command.
#[test]
fn damaged_tree_and_brick_list_are_errors_not_panics() {
    let dir = tempfile::tempdir().unwrap();
    let (path, iso) = base_file(dir.path(), Case::Blobs, false);
    let base = std::fs::read(&path).unwrap();
    let f = footer_of(&base);

    let mut moved = base.clone();
    let at = f.nodes.offset.get() as usize;
    let root = u32::from_le_bytes(moved[at + 4..at + 8].try_into().unwrap());
    assert_ne!(root & 3, KD_LEAF);
    let split = u32::from_le_bytes(moved[at..at + 4].try_into().unwrap());
    moved[at..at + 4].copy_from_slice(&(split + 1).to_le_bytes());

    let mut relisted = base.clone();
    let leaves = <[KdLeaf]>::ref_from_bytes(
        &base[f.leaves.offset.get() as usize..][..f.leaves.len.get() as usize],
    )
    .unwrap();
    let leaf = leaves.iter().find(|l| l.brick_count.get() > 0).unwrap();
    let entry = f.brick_list.offset.get() as usize + 4 * leaf.brick_start.get() as usize;
    let first = u32::from_le_bytes(relisted[entry..entry + 4].try_into().unwrap());
    let other = (first + f.num_bricks.get() / 2) % f.num_bricks.get();
    relisted[entry..entry + 4].copy_from_slice(&other.to_le_bytes());

    for (name, mut bytes, needle) in [
        ("moved.amrk", moved, "kd leaf"),
        ("relisted.amrk", relisted, "does not cover it"),
    ] {
        assert!(recompute_checksums(&mut bytes));
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        let out = dir.path().join("o.exr");
        for args in [
            vec!["info", p.to_str().unwrap()],
            vec!["extract", p.to_str().unwrap(), "--iso", &iso.to_string()],
            vec![
                p.to_str().unwrap(),
                "--iso",
                &iso.to_string(),
                "-o",
                out.to_str().unwrap(),
                "--size",
                "32x32",
            ],
        ] {
            let o = run(&args);
            assert_eq!(o.code, Some(1), "{args:?}: {o:?}");
            assert!(
                o.stderr.contains(name) && o.stderr.contains(needle),
                "{args:?}: {}",
                o.stderr
            );
        }
    }
}

/// `-o` naming the input, or a device, is refused before any work; nothing is replaced.
#[test]
fn outputs_that_would_replace_the_input_or_a_device_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (path, iso) = base_file(dir.path(), Case::Blobs, false);
    let before = std::fs::read(&path).unwrap();
    let p = path.to_str().unwrap();
    let iso = iso.to_string();
    for (out, needle) in [(p, "is the input"), ("/dev/null", "not a regular file")] {
        let o = run(&[p, "--iso", &iso, "-o", out, "--size", "8x8"]);
        assert_eq!(o.code, Some(1), "{o:?}");
        assert!(o.stderr.contains(needle), "{}", o.stderr);
        let o = run(&[
            p,
            "--iso",
            &iso,
            "-o",
            &format!("{p}.exr"),
            "--size",
            "8x8",
            "--preview",
            out,
        ]);
        assert_eq!(o.code, Some(1), "{o:?}");
    }
    let o = run(&["extract", p, "--iso", &iso, "--stats-json", p]);
    assert_eq!(o.code, Some(1), "{o:?}");
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert!(!std::fs::metadata("/dev/null")
        .unwrap()
        .file_type()
        .is_file());
}

/// The metadata rewritten under a live map (same length): the open file keeps reading the
/// tables it validated, so verifying it sees nothing new and nothing panics.
#[test]
fn metadata_rewritten_under_the_map_is_not_seen() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = base_file(dir.path(), Case::Ripple, false);
    let file = open_mapped(&path).unwrap();
    let f = *file.footer();
    let zeros = vec![0xFFu8; f.metadata.len.get() as usize];
    let w = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    w.write_all_at(&zeros, f.metadata.offset.get()).unwrap();
    assert!(file.bytes()[f.metadata.offset.get() as usize..].starts_with(&zeros[..64]));
    file.verify().unwrap();
}

/// Run in a child process by [`truncation_under_the_map_is_an_error`]: maps a file, truncates
/// it, then reads every brick.
#[test]
fn sigbus_child() {
    let Some(path) = std::env::var_os("AMR_SIGBUS_CHILD_FILE") else {
        return;
    };
    if std::env::var_os("AMR_SIGBUS_CHILD_INSTALL").is_some() {
        amr_render::sigbus::install();
    }
    let file = open_mapped(Path::new(&path)).unwrap();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(0)
        .unwrap();
    let _ = file.verify();
    panic!("reading a truncated map raised no SIGBUS");
}

/// A file truncated while it is read: the process exits 1 naming the file, not by SIGBUS.
#[test]
fn truncation_under_the_map_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = base_file(dir.path(), Case::Blobs, false);
    let out = Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "sigbus_child", "--nocapture", "--test-threads=1"])
        .env("AMR_SIGBUS_CHILD_FILE", &path)
        .env("AMR_SIGBUS_CHILD_INSTALL", "1")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{:?}: {stderr}", out.status);
    let want = format!(
        "Error: {}: the file changed or was truncated while it was read",
        path.display()
    );
    assert!(stderr.contains(&want), "{stderr}");
}

/// The library alone takes no signal: a program that did not call `sigbus::install` sees the
/// plain SIGBUS of a truncated map, as with any other mapped file.
#[test]
fn the_library_alone_installs_no_signal_handler() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = base_file(dir.path(), Case::Blobs, false);
    let out = Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "sigbus_child", "--nocapture", "--test-threads=1"])
        .env("AMR_SIGBUS_CHILD_FILE", &path)
        .output()
        .unwrap();
    assert_eq!(out.status.signal(), Some(libc::SIGBUS), "{:?}", out.status);
}

/// Exit status of the handler [`foreign_fault_child`] installs before `sigbus::install`.
const FOREIGN_HANDLER_EXIT: i32 = 42;

extern "C" fn foreign_handler(_: libc::c_int) {
    // SAFETY: _exit(2) is async-signal-safe.
    unsafe { libc::_exit(FOREIGN_HANDLER_EXIT) }
}

/// Run in a child process by [`a_fault_outside_watched_maps_reaches_the_handler_before`]: installs
/// its own SIGBUS handler, then the library's, opens a watched `.amrk` file, and faults on another
/// map of its own.
#[test]
fn foreign_fault_child() {
    let Some(path) = std::env::var_os("AMR_FOREIGN_FAULT_CHILD_FILE") else {
        return;
    };
    // SAFETY: a plain handler that only calls _exit(2).
    unsafe {
        libc::signal(
            libc::SIGBUS,
            foreign_handler as *const () as libc::sighandler_t,
        );
    }
    amr_render::sigbus::install();
    let _watched = open_mapped(Path::new(&path)).unwrap();
    let other = Path::new(&path).with_extension("other");
    std::fs::write(&other, vec![7u8; 1 << 16]).unwrap();
    let f = std::fs::File::open(&other).unwrap();
    // SAFETY: the map is read-only; the test truncates the file under it on purpose to fault.
    let map = unsafe { memmap2::Mmap::map(&f) }.unwrap();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&other)
        .unwrap()
        .set_len(0)
        .unwrap();
    let sum: u64 = map.iter().map(|&b| u64::from(b)).sum();
    panic!("reading a truncated map raised no SIGBUS ({sum})");
}

/// A SIGBUS outside every watched map goes to the handler the program had before.
#[test]
fn a_fault_outside_watched_maps_reaches_the_handler_before() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = base_file(dir.path(), Case::Blobs, false);
    let out = Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "foreign_fault_child",
            "--nocapture",
            "--test-threads=1",
        ])
        .env("AMR_FOREIGN_FAULT_CHILD_FILE", &path)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(FOREIGN_HANDLER_EXIT),
        "{:?}: {stderr}",
        out.status
    );
    assert!(!stderr.contains("truncated while it was read"), "{stderr}");
}

/// A damaged compressed brick (its checksum checked before it is decoded): the message names
/// the file once and says the problem once, in `extract` and in a render.
#[test]
fn a_damaged_compressed_brick_is_named_once() {
    let dir = tempfile::tempdir().unwrap();
    let (path, iso) = base_file(dir.path(), Case::Ripple, true);
    let mut b = std::fs::read(&path).unwrap();
    let data_end = footer_of(&b).metadata.offset.get() as usize;
    for i in (64..data_end).step_by(7) {
        b[i] ^= 0x5A;
    }
    std::fs::write(&path, b).unwrap();
    let (p, iso) = (path.to_str().unwrap(), format!("--iso={iso}"));
    let out = dir.path().join("o.exr");
    for args in [
        vec!["extract", p, &iso],
        vec![p, &iso, "-o", out.to_str().unwrap(), "--size", "16x16"],
    ] {
        let o = run(&args);
        assert_eq!(o.code, Some(1), "{args:?}: {o:?}");
        assert_eq!(o.stderr.matches(p).count(), 1, "{}", o.stderr);
        assert_eq!(o.stderr.matches("corrupt").count(), 1, "{}", o.stderr);
        assert!(o.stderr.contains("checksum mismatch"), "{}", o.stderr);
    }
}
