//! `amr-convert` on hostile input (issue 15): outputs that would replace an input, a field name
//! that is not UTF-8, a crash of the HDF5 library, temporaries left by a killed writer. Each is
//! exit 1 with one message and no output, never a signal death or a replaced input.

// The integration tests' fixture writers (tests/tests/support), for a Chombo file.
#[path = "../../tests/tests/support/mod.rs"]
#[allow(dead_code)]
mod support;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Mutex;

use support::chombo::{writer, Desc};

/// The child's crash hook (`src/bin/amr-convert/isolate.rs`).
const TEST_CRASH_ENV: &str = "AMR_CONVERT_TEST_CRASH_CHILD";

const BIN: &str = env!("CARGO_BIN_EXE_amr-convert");

/// Held while a fixture is written and while a child is started: libhdf5 opens files without
/// close-on-exec and locks them, so a child forked while another test's fixture is open would
/// inherit that lock and make the other test's converter fail with "unable to lock file".
static NO_FORK_WHILE_HDF5_OPEN: Mutex<()> = Mutex::new(());

/// Runs `amr-convert args` with `env`; returns (exit code, stderr).
fn run(args: &[&Path], env: &[(&str, &str)]) -> (Option<i32>, String) {
    let child = {
        let _guard = NO_FORK_WHILE_HDF5_OPEN
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        Command::new(BIN)
            .args(args)
            .envs(env.iter().copied())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn fixture(dir: &Path) -> PathBuf {
    let input = dir.join("plt.3d.hdf5");
    let _guard = NO_FORK_WHILE_HDF5_OPEN
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    writer::write(&input, &Desc::three_levels(true)).unwrap();
    input
}

/// The names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A bad command line (an out-of-range option, an unknown flag) is exit 1 like any other bad
/// input, with clap's message; `--help` still succeeds.
#[test]
fn a_bad_command_line_is_exit_1() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture(dir.path());
    let out = dir.path().join("o.amrk");
    for bad in [&["--brick", "0"][..], &["--no-such-flag"][..]] {
        let mut args: Vec<&Path> = vec![&input, Path::new("-o"), &out];
        args.extend(bad.iter().map(Path::new));
        let (code, err) = run(&args, &[]);
        assert_eq!(code, Some(1), "{bad:?}: {err}");
        assert!(err.contains("error:"), "{bad:?}: {err}");
    }
    assert_eq!(run(&[Path::new("--help")], &[]).0, Some(0));
    assert!(!out.exists());
}

/// A series whose inputs are missing or not dumps leaves no output directory behind: a missing
/// input is refused before the directory is made, and one that fails to convert removes the
/// directory this run made while it is still empty.
#[test]
fn a_failed_series_leaves_no_directory() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture(dir.path());
    let not_a_dump = dir.path().join("notes");
    std::fs::create_dir(&not_a_dump).unwrap();
    let out = dir.path().join("series.amrk");
    let missing = dir.path().join("chombo");
    for (first, what) in [
        (&missing, "does not exist"),
        (&not_a_dump, "unrecognised input"),
    ] {
        let (code, err) = run(&[first, &input, Path::new("-o"), &out], &[]);
        assert_eq!(code, Some(1), "{err}");
        assert!(err.contains(what), "{err}");
        assert!(!out.exists(), "{err}");
    }
    // A series that fails after converting a dump keeps that file, and so its directory.
    let (code, err) = run(&[&input, &not_a_dump, Path::new("-o"), &out], &[]);
    assert_eq!(code, Some(1), "{err}");
    assert_eq!(names(&out), ["plt.amrk"]);
}

#[test]
fn an_output_that_is_the_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture(dir.path());
    let before = std::fs::read(&input).unwrap();
    let (code, err) = run(&[&input, Path::new("-o"), &input], &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("is the input"), "{err}");
    assert_eq!(std::fs::read(&input).unwrap(), before);
    assert_eq!(names(dir.path()), ["plt.3d.hdf5"]);
}

#[test]
fn an_output_inside_a_plotfile_directory_or_a_device_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let plt = dir.path().join("plt00000");
    std::fs::create_dir(&plt).unwrap();
    std::fs::write(plt.join("Header"), "HyperCLaw-V1.1\n").unwrap();
    let (code, err) = run(&[&plt, Path::new("-o"), &plt.join("Header")], &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("inside the input directory"), "{err}");
    assert_eq!(
        std::fs::read(plt.join("Header")).unwrap(),
        b"HyperCLaw-V1.1\n"
    );
    let input = fixture(dir.path());
    let (code, err) = run(&[&input, Path::new("-o"), Path::new("/dev/null")], &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("not a regular file"), "{err}");
    let (code, err) = run(
        &[
            Path::new("synth"),
            Path::new("sphere"),
            Path::new("-o"),
            dir.path(),
        ],
        &[],
    );
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("is a directory"), "{err}");
}

/// A component name whose bytes are not UTF-8 is an error at conversion, not a file that its
/// readers then refuse.
#[test]
fn a_field_name_that_is_not_utf8_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture(dir.path());
    let mut bytes = std::fs::read(&input).unwrap();
    let at = bytes
        .windows(7)
        .position(|w| w == b"density")
        .expect("the name is stored as its bytes");
    bytes[at + 6] = 0xFF;
    std::fs::write(&input, bytes).unwrap();
    let out = dir.path().join("out.amrk");
    let (code, err) = run(&[&input, Path::new("-o"), &out], &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("component_0") && err.contains("not UTF-8"),
        "{err}"
    );
    assert_eq!(names(dir.path()), ["plt.3d.hdf5"]);
}

/// The child reading HDF5 dies of a signal (as it does inside libhdf5 on some corrupt files):
/// the parent says so, exits 1 and leaves nothing behind.
#[test]
fn a_crash_of_the_hdf5_child_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture(dir.path());
    let out = dir.path().join("out.amrk");
    let (code, err) = run(&[&input, Path::new("-o"), &out], &[(TEST_CRASH_ENV, "1")]);
    assert_eq!(code, Some(1), "{err}");
    let want = format!(
        "{}: the HDF5 library crashed reading it (signal 6); the file is probably corrupt",
        input.display()
    );
    assert!(err.contains(&want), "{err}");
    assert_eq!(names(dir.path()), ["plt.3d.hdf5"]);
    let (code, err) = run(&[&input, Path::new("-o"), &out], &[]);
    assert_eq!(code, Some(0), "{err}");
}

/// Temporaries of a writer killed mid-way (its PID gone) are removed by the next conversion to
/// the same target; another target's are left alone.
#[test]
fn temporaries_of_a_killed_writer_are_removed_by_the_next_run() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture(dir.path());
    let out = dir.path().join("out.amrk");
    // PIDs above the kernel's limit (2^22) never run.
    let stale = [
        ".out.amrk.99999999.Ab12Cd.tmp",
        ".out.amrk.99999999.Ef34Gh.spill",
    ];
    for s in stale {
        std::fs::write(dir.path().join(s), b"left by a killed writer").unwrap();
    }
    std::fs::write(dir.path().join(".other.amrk.99999999.Ab12Cd.tmp"), b"x").unwrap();
    let (code, err) = run(&[&input, Path::new("-o"), &out], &[]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(
        names(dir.path()),
        [".other.amrk.99999999.Ab12Cd.tmp", "out.amrk", "plt.3d.hdf5"]
    );
}

/// One-byte corruptions of the fixture that kill a converter reading it in-process (SIGSEGV in
/// `H5Aiterate2` with the system libhdf5 1.10, found by a random search): exit 1 naming the
/// file, nothing left behind, whichever way the library fails on them.
#[test]
fn one_byte_corruptions_that_crash_libhdf5_are_errors() {
    for (at, byte) in [(2077, 34u8), (11667, 159), (13472, 155), (1325, 97)] {
        let dir = tempfile::tempdir().unwrap();
        let input = fixture(dir.path());
        let mut bytes = std::fs::read(&input).unwrap();
        bytes[at] = byte;
        std::fs::write(&input, bytes).unwrap();
        let out = dir.path().join("out.amrk");
        let (code, err) = run(&[&input, Path::new("-o"), &out], &[("RUST_BACKTRACE", "0")]);
        assert_eq!(code, Some(1), "byte {at} = {byte}: {err}");
        assert!(
            err.contains(&input.display().to_string()),
            "byte {at}: {err}"
        );
        assert_eq!(names(dir.path()), ["plt.3d.hdf5"], "byte {at}: {err}");
    }
}

/// A child killed from outside (not a crash) is not blamed on the file.
#[test]
fn a_child_killed_from_outside_is_not_called_a_crash() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture(dir.path());
    let out = dir.path().join("out.amrk");
    let (code, err) = run(
        &[&input, Path::new("-o"), &out],
        &[(TEST_CRASH_ENV, "kill")],
    );
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("killed by signal 9") && !err.contains("crashed"),
        "{err}"
    );
    assert_eq!(names(dir.path()), ["plt.3d.hdf5"]);
}

/// Copies the directory tree `from` into `to`, leaving out the files named in `skip`.
fn copy_tree_without(from: &Path, to: &Path, skip: &[&str]) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let name = entry.file_name();
        if skip.iter().any(|s| name == *s) {
            continue;
        }
        if entry.file_type().unwrap().is_dir() {
            copy_tree_without(&entry.path(), &to.join(&name), skip);
        } else {
            std::fs::copy(entry.path(), to.join(&name)).unwrap();
        }
    }
}

/// An error that wraps the operating system's or a library's says their message once: the
/// message printed is the chain of causes, and a cause whose text is already in its wrapper's
/// message is not also its source (an AMReX data file and an Enzo HDF5 file missing, from the
/// shared real data).
#[test]
fn an_error_says_each_cause_once() {
    let Some(amrex) = support::amrex::shared_amrex("an_error_says_each_cause_once") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let plt = dir.path().join("plt");
    copy_tree_without(&amrex.join("example_plt_3d"), &plt, &["Cell_D_00001"]);
    let (code, err) = run(&[&plt, Path::new("-o"), &dir.path().join("a.amrk")], &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("Cell_D_00001"), "{err}");
    assert_eq!(err.matches("No such file or directory").count(), 1, "{err}");

    let Some(enzo) = support::amrex::shared_data(
        "an_error_says_each_cause_once",
        "enzo",
        "DD0010/moving7_0010",
    ) else {
        return;
    };
    let dd = dir.path().join("DD0010");
    copy_tree_without(&enzo.join("DD0010"), &dd, &["moving7_0010.cpu0000"]);
    let (code, err) = run(
        &[
            &dd.join("moving7_0010"),
            Path::new("-o"),
            &dir.path().join("e.amrk"),
        ],
        &[],
    );
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("moving7_0010.cpu0000"), "{err}");
    assert_eq!(err.matches("H5Fopen").count(), 1, "{err}");
}

/// `--keep-boxes` reaches the child that reads HDF5: level 0's two boxes of the fixture, which
/// share a face, are one brick by default and two with it.
#[test]
fn keep_boxes_reaches_the_hdf5_child() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture(dir.path());
    let joined = dir.path().join("joined.amrk");
    let kept = dir.path().join("kept.amrk");
    let brick = Path::new("16");
    let flag = Path::new("--brick");
    let (code, joined_msg) = run(&[&input, Path::new("-o"), &joined, flag, brick], &[]);
    assert_eq!(code, Some(0), "{joined_msg}");
    let keep = Path::new("--keep-boxes");
    let (code, kept_msg) = run(&[&input, Path::new("-o"), &kept, flag, brick, keep], &[]);
    assert_eq!(code, Some(0), "{kept_msg}");
    assert!(
        joined_msg.contains("of 6 boxes in 8 bricks"),
        "{joined_msg}"
    );
    assert!(kept_msg.contains("of 6 boxes in 9 bricks"), "{kept_msg}");
}
