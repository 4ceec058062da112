//! A seeded mutation fuzzer of the readers, through the `amr-convert` program: the real dumps of
//! the shared data (the AMReX plotfiles `plt1_Y` and `example_plt_3d`, the Enzo dataset
//! `DD0010`), a Chombo plotfile and an AMReX HDF5 plotfile written by the tests' HDF5 writers,
//! copied and damaged: numbers in their text headers and `FAB` lines replaced by huge,
//! negative or malformed ones, lines dropped, doubled or swapped, files cut short, bytes of
//! their data randomized. Every run must exit 0 with a file that verifies, or 1 with an `Error:`
//! message that names the dump or a file of it and leaves no output: never a panic, a signal,
//! an allocation past [`MEMORY_LIMIT`] or a hang.
//!
//! `AMR_FUZZ_CASES` sets the number of damaged dumps (default 240, about 5 s); `AMR_FUZZ_SEED`
//! moves the seeds:
//! `AMR_FUZZ_CASES=20000 cargo test --release -p amr-convert --test fuzz_dumps -- --nocapture`.
//! A failing dump is kept in `target/convert-fuzz/seedN/` with a report of its damage and the
//! error. The shared dumps are skipped, with a message, when the shared data is absent.

// The integration tests' support code, for `shared_data`, and the fuzzers' child-process runner.
#[path = "../../tests/tests/support/fuzz.rs"]
mod fuzz;
#[path = "../../tests/tests/support/mod.rs"]
#[allow(dead_code)]
mod support;

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use amr_format::AmrkFile;
use fuzz::{env_u64, run_killed_after, Outcome};
use support::amrex::shared_data;

const BIN: &str = env!("CARGO_BIN_EXE_amr-convert");

/// A run taking longer than this is a hang (the undamaged dumps convert in well under a second).
const TIMEOUT: Duration = Duration::from_secs(30);

/// The address space a run may take: far above what these dumps need (tens of MB), far below
/// what a count taken from a damaged header on trust would ask for.
const MEMORY_LIMIT: u64 = 4 << 30;

/// One dump to damage: its folder, the path `amr-convert` is given inside it, and the fields
/// converted (fewer fields, faster runs; the damage may hit any file).
struct Dump {
    name: &'static str,
    folder: PathBuf,
    input: &'static str,
    fields: &'static [&'static str],
}

/// Runs `amr-convert args` with [`MEMORY_LIMIT`], killing it after [`TIMEOUT`].
fn run(args: &[&std::ffi::OsStr]) -> Outcome {
    let mut cmd = Command::new(BIN);
    cmd.args(args);
    // SAFETY: the closure runs in the forked child before exec and only calls setrlimit, which
    // is async-signal-safe; it touches no memory of the parent's other threads.
    unsafe {
        cmd.pre_exec(|| {
            let limit = libc::rlimit {
                rlim_cur: MEMORY_LIMIT,
                rlim_max: MEMORY_LIMIT,
            };
            if libc::setrlimit(libc::RLIMIT_AS, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    run_killed_after(cmd, TIMEOUT)
}

/// A small deterministic generator (xorshift64*), so that a seed names its case.
struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }

    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n.max(1)
    }

    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len() as u64) as usize]
    }
}

/// Numbers a damaged header may hold instead of the one written.
const HOSTILE_NUMBERS: &[&str] = &[
    "0",
    "-1",
    "1",
    "2",
    "7",
    "-2147483648",
    "2147483647",
    "2147483648",
    "4294967296",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551616",
    "99999999999999999999999",
    "1e308",
    "-1e308",
    "1e-320",
    "nan",
    "inf",
    "-inf",
    "",
    "0x10",
    "1.5",
    "--3",
];

/// The byte ranges of the numbers in `text` (digits with their sign, point and exponent).
fn numbers(text: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < text.len() {
        let starts = text[i].is_ascii_digit()
            || (matches!(text[i], b'-' | b'+' | b'.')
                && text.get(i + 1).is_some_and(u8::is_ascii_digit));
        if !starts || (i > 0 && text[i - 1].is_ascii_alphanumeric()) {
            i += 1;
            continue;
        }
        let s = i;
        i += 1;
        while i < text.len()
            && (text[i].is_ascii_digit()
                || matches!(text[i], b'.' | b'e' | b'E')
                || (matches!(text[i], b'-' | b'+') && matches!(text[i - 1], b'e' | b'E')))
        {
            i += 1;
        }
        out.push((s, i));
    }
    out
}

/// The line boundaries of `text`: each line's start and end (past its newline).
fn lines(text: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut s = 0;
    for (i, &b) in text.iter().enumerate() {
        if b == b'\n' {
            out.push((s, i + 1));
            s = i + 1;
        }
    }
    if s < text.len() {
        out.push((s, text.len()));
    }
    out
}

/// Damages a text file (a header, a box list, a hierarchy, a parameter file) once; returns
/// what was done.
fn damage_text(b: &mut Vec<u8>, rng: &mut Rng) -> String {
    let nums = numbers(b);
    let ls = lines(b);
    match rng.below(10) {
        0..=4 if !nums.is_empty() => {
            let (s, e) = *rng.pick(&nums);
            let old = String::from_utf8_lossy(&b[s..e]).into_owned();
            let new = match rng.below(3) {
                0 => {
                    // Off by a little: the kind of damage that still parses.
                    let v: f64 = old.parse().unwrap_or(0.0);
                    let d = [1.0, -1.0, 2.0, -2.0][rng.below(4) as usize];
                    match old.contains(['.', 'e', 'E']) {
                        true => format!("{}", v + d * 0.5),
                        false => format!("{}", v as i128 + d as i128),
                    }
                }
                _ => rng.pick(HOSTILE_NUMBERS).to_string(),
            };
            b.splice(s..e, new.bytes());
            format!("number {old:?} at byte {s} -> {new:?}")
        }
        5 if !ls.is_empty() => {
            let (s, e) = *rng.pick(&ls);
            b.drain(s..e);
            format!("line at byte {s} dropped")
        }
        6 if !ls.is_empty() => {
            let (s, e) = *rng.pick(&ls);
            let line = b[s..e].to_vec();
            b.splice(s..s, line);
            format!("line at byte {s} doubled")
        }
        7 if ls.len() > 1 => {
            let i = rng.below(ls.len() as u64 - 1) as usize;
            let (a, m, e) = (ls[i].0, ls[i].1, ls[i + 1].1);
            let mut swapped = b[m..e].to_vec();
            swapped.extend_from_slice(&b[a..m]);
            b.splice(a..e, swapped);
            format!("lines at bytes {a} and {m} swapped")
        }
        8 => {
            let at = rng.below(b.len() as u64 + 1) as usize;
            b.truncate(at);
            format!("cut to {at} bytes")
        }
        _ if !b.is_empty() => {
            let at = rng.below(b.len() as u64) as usize;
            let new = *rng.pick(b" x-0.(),\n\t\0\xff");
            b[at] = new;
            format!("byte {at} -> {new:#04x}")
        }
        _ => "nothing (empty file)".into(),
    }
}

/// Damages a binary file (an AMReX `Cell_D` with its text `FAB` headers, an Enzo or Chombo
/// HDF5 file)
/// once; returns what was done.
fn damage_binary(b: &mut Vec<u8>, rng: &mut Rng) -> String {
    if b.is_empty() {
        return "nothing (empty file)".into();
    }
    match rng.below(4) {
        0 => {
            let at = rng.below(b.len() as u64) as usize;
            b.truncate(at);
            format!("cut to {at} bytes")
        }
        1 => {
            // Into a `FAB ((...))` header line, where the box and the number format are.
            let fabs: Vec<usize> = b
                .windows(5)
                .enumerate()
                .filter(|(_, w)| w == b"FAB ((")
                .map(|(i, _)| i)
                .collect();
            match fabs.is_empty() {
                true => damage_text(b, rng),
                false => {
                    let start = *rng.pick(&fabs);
                    let end = b[start..]
                        .iter()
                        .position(|&c| c == b'\n')
                        .map_or(b.len(), |n| start + n + 1);
                    let mut line = b[start..end].to_vec();
                    let what = damage_text(&mut line, rng);
                    b.splice(start..end, line);
                    format!("FAB header at byte {start}: {what}")
                }
            }
        }
        _ => {
            let n = 1 + rng.below(8) as usize;
            let at = rng.below(b.len() as u64) as usize;
            for k in at..(at + n).min(b.len()) {
                b[k] = rng.next() as u8;
            }
            format!("{n} bytes at {at} randomized")
        }
    }
}

/// Copies the folder `from` into `to`, file by file.
fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let target = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_tree(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), target).unwrap();
        }
    }
}

/// Every file under `dir`, relative to it, sorted.
fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut todo = vec![PathBuf::new()];
    while let Some(rel) = todo.pop() {
        for e in std::fs::read_dir(dir.join(&rel)).unwrap() {
            let e = e.unwrap();
            let r = rel.join(e.file_name());
            match e.file_type().unwrap().is_dir() {
                true => todo.push(r),
                false => out.push(r),
            }
        }
    }
    out.sort();
    out
}

/// True for the files the readers parse as text.
fn is_text(rel: &Path) -> bool {
    let name = rel.file_name().unwrap().to_string_lossy();
    name == "Header"
        || name == "Cell_H"
        || name.ends_with(".hierarchy")
        || name.ends_with(".boundary")
        || name.ends_with(".procmap")
        || !name.contains('.') && !name.starts_with("Cell_D")
}

/// What is wrong with a run on a damaged dump, if anything: a crash, a hang, an exit other than
/// 0 or 1, an error that does not name the dump, an output left by a failure, or an output of a
/// success that does not verify.
fn problem(o: &Outcome, dump: &Path, out_dir: &Path, out: &Path) -> Option<String> {
    if o.timed_out {
        return Some("timed out".into());
    }
    if let Some(s) = o.signal {
        return Some(format!("killed by signal {s}"));
    }
    let left = std::fs::read_dir(out_dir).unwrap().count();
    match o.code {
        Some(0) => {
            let bytes = std::fs::read(out).ok()?;
            let verified = AmrkFile::open(bytes).and_then(|f| f.verify());
            verified
                .err()
                .map(|e| format!("the output does not open or verify: {e}"))
        }
        Some(1) => {
            let named = [
                dump.to_string_lossy(),
                "Level_".into(),
                "moving7_0010".into(),
            ]
            .iter()
            .any(|n| o.stderr.contains(n.as_ref()));
            if !o.stderr.starts_with("Error: ") {
                Some("exit 1 without an `Error:` message".into())
            } else if !named {
                Some("the error does not name the dump or a file of it".into())
            } else if left != 0 {
                Some(format!(
                    "{left} files left in the output folder after a failure"
                ))
            } else {
                None
            }
        }
        c => Some(format!("exit {c:?}")),
    }
}

#[test]
fn fuzz_damaged_dumps_exit_cleanly() {
    let test = "fuzz_damaged_dumps_exit_cleanly";
    let mut dumps = Vec::new();
    if let Some(folder) = shared_data(test, "amrex/plt1_Y", "Header") {
        dumps.push(Dump {
            name: "plt1_Y",
            folder,
            input: "",
            fields: &["Y(H2)", "Y(O2)"],
        });
    }
    if let Some(folder) = shared_data(test, "amrex/example_plt_3d", "Header") {
        dumps.push(Dump {
            name: "example_plt_3d",
            folder,
            input: "",
            fields: &["temp", "density"],
        });
    }
    if let Some(folder) = shared_data(test, "enzo/DD0010", "moving7_0010.hierarchy") {
        dumps.push(Dump {
            name: "DD0010",
            folder,
            input: "moving7_0010",
            fields: &["Density", "Temperature"],
        });
    }
    // No Chombo file in the shared data: a plotfile in the layout Chombo's writer produces,
    // written by the tests' own writer through the HDF5 library, whose parsing of damaged
    // files is under test here as much as the reader's.
    let chombo = tempfile::tempdir().unwrap();
    let chombo_file = chombo.path().join("plot.3d.hdf5");
    support::chombo::writer::write(&chombo_file, &support::chombo::Desc::three_levels(true))
        .unwrap();
    dumps.push(Dump {
        name: "chombo",
        folder: chombo.path().to_path_buf(),
        input: "plot.3d.hdf5",
        fields: &["density", "chi"],
    });
    // AMReX's HDF5 plotfile: Chombo's layout with AMReX's attributes, written as its writer does.
    let amrex_h5 = tempfile::tempdir().unwrap();
    let amrex_h5_file = amrex_h5.path().join("plt00040.h5");
    support::amrex_hdf5::write(
        &amrex_h5_file,
        &support::amrex_hdf5::AmrexHdf5::three_levels(),
    )
    .unwrap();
    dumps.push(Dump {
        name: "amrex_hdf5",
        folder: amrex_h5.path().to_path_buf(),
        input: "plt00040.h5",
        fields: &["density", "Y(OH)"],
    });
    let cases = env_u64("AMR_FUZZ_CASES", 240);
    let seed0 = env_u64("AMR_FUZZ_SEED", 0);
    let keep = Path::new(env!("CARGO_TARGET_TMPDIR")).join("../convert-fuzz");
    let tmp = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    let (mut converted, mut refused) = (0, 0);
    for case in 0..cases {
        let seed = seed0 + case;
        let mut rng = Rng::new(seed);
        let dump = &dumps[(case % dumps.len() as u64) as usize];
        let work = tmp.path().join(format!("case{case}"));
        let copy = work.join(dump.name);
        copy_tree(&dump.folder, &copy);
        let files = files_under(&copy);
        let mut done = Vec::new();
        for _ in 0..1 + rng.below(3) {
            let rel = rng.pick(&files).clone();
            let path = copy.join(&rel);
            let mut b = std::fs::read(&path).unwrap();
            let what = match is_text(&rel) {
                true => damage_text(&mut b, &mut rng),
                false => damage_binary(&mut b, &mut rng),
            };
            std::fs::write(&path, &b).unwrap();
            done.push(format!("{}: {what}", rel.display()));
        }
        let out_dir = work.join("out");
        std::fs::create_dir(&out_dir).unwrap();
        let out = out_dir.join("out.amrk");
        let input = copy.join(dump.input);
        let mut args: Vec<&std::ffi::OsStr> =
            vec![input.as_os_str(), "-o".as_ref(), out.as_os_str()];
        for f in dump.fields {
            args.push("--field".as_ref());
            args.push(f.as_ref());
        }
        let outcome = run(&args);
        match outcome.code {
            Some(0) => converted += 1,
            Some(1) => refused += 1,
            _ => {}
        }
        if let Some(p) = problem(&outcome, &copy, &out_dir, &out) {
            let kept = keep.join(format!("seed{seed}"));
            let _ = std::fs::remove_dir_all(&kept);
            copy_tree(&copy, &kept.join(dump.name));
            let report = format!(
                "seed {seed} ({}): {p}\n  damage: {}\n  stderr: {}",
                dump.name,
                done.join("; "),
                outcome.stderr.trim()
            );
            std::fs::write(kept.join("report.txt"), &report).unwrap();
            failures.push(report);
        }
        std::fs::remove_dir_all(&work).unwrap();
    }
    eprintln!(
        "{cases} damaged dumps: {converted} converted and verified, {refused} refused, {} failed",
        failures.len()
    );
    assert!(
        failures.is_empty(),
        "{} of {cases} damaged dumps failed (kept in {}):\n{}",
        failures.len(),
        keep.display(),
        failures.join("\n")
    );
}
