//! `amr-convert info`: what a dump holds, from its metadata, for every format the converter
//! reads (the real AMReX and Enzo dumps of the shared data, Chombo and AMReX HDF5 files written
//! as their codes write them), in text and JSON; HDF5 read in a child whose crash is an error.

// The integration tests' support code: fixture writers and the shared-data folder.
#[path = "../../tests/tests/support/mod.rs"]
#[allow(dead_code)]
mod support;

use std::path::Path;
use std::process::{Command, Output};
use std::sync::Mutex;

use support::amrex::shared_data;
use support::amrex_hdf5::AmrexHdf5;

const BIN: &str = env!("CARGO_BIN_EXE_amr-convert");

/// Held while a fixture is written and a child started: libhdf5 opens files without
/// close-on-exec and locks them (as `hostile_cli.rs` explains).
static HDF5_WRITE: Mutex<()> = Mutex::new(());

/// `amr-convert info args...` with `env`.
fn info(args: &[&str], env: &[(&str, &str)]) -> Output {
    let _guard = HDF5_WRITE.lock().unwrap_or_else(|e| e.into_inner());
    let child = Command::new(BIN)
        .arg("info")
        .args(args)
        .envs(env.iter().copied())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(_guard);
    child.wait_with_output().unwrap()
}

/// The text `info` prints for `path`, which must succeed.
fn text(path: &Path) -> String {
    let o = info(&[path.to_str().unwrap()], &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap()
}

/// The JSON `info --json` prints for `path`.
fn json(path: &Path) -> serde_json::Value {
    let o = info(&[path.to_str().unwrap(), "--json"], &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn a_real_amrex_plotfile_and_enzo_dataset_are_described_from_their_metadata() {
    let test = "a_real_amrex_plotfile_and_enzo_dataset_are_described_from_their_metadata";
    if let Some(plt) = shared_data(test, "amrex/example_plt_3d", "Header") {
        let t = text(&plt);
        for line in [
            ": AMReX plotfile\n",
            "simulation: time 1.3924182125972017e-8 step 20\n",
            "fields: 38\n",
            "  level 2: boxes 64 cells 32768 domain [0, 0, 0]..[32, 32, 32] cell size [0.0005, 0.0005, 0.0005]\n",
            "cells: 37376\n",
            "146.000 KiB a field, 5.418 MiB for all 38",
            "vectors: |x_velocity,y_velocity,z_velocity| |gradpx,gradpy,gradpz| (",
        ] {
            assert!(t.contains(line), "{line:?} not in\n{t}");
        }
        let j = json(&plt);
        assert_eq!(j["levels"][1]["boxes"], 8);
        assert_eq!(j["amrk_bytes_per_field"], 37376 * 4);
    }
    if let Some(dd) = shared_data(test, "enzo/DD0010", "moving7_0010.hierarchy") {
        let t = text(&dd);
        for line in [
            ": Enzo dataset\n",
            "levels: 8\n",
            "cells: 30360\n",
            "  Temperature\n",
            "vectors: |x-velocity,y-velocity,z-velocity| (store a length or a vorticity with \
             --derive 'speed=|x-velocity,y-velocity,z-velocity|' --derive \
             'vorticity=curl(x-velocity,y-velocity,z-velocity)', or convert",
        ] {
            assert!(t.contains(line), "{line:?} not in\n{t}");
        }
    }
}

#[test]
fn hdf5_files_are_told_apart_by_their_writer() {
    let dir = tempfile::tempdir().unwrap();
    let (amrex, chombo) = (
        dir.path().join("plt00040.h5"),
        dir.path().join("plot.3d.hdf5"),
    );
    {
        let _guard = HDF5_WRITE.lock().unwrap_or_else(|e| e.into_inner());
        support::amrex_hdf5::write(&amrex, &AmrexHdf5::three_levels()).unwrap();
        let desc = support::chombo::Desc::three_levels(true);
        support::chombo::writer::write(&chombo, &desc).unwrap();
    }
    let t = text(&amrex);
    for line in [
        ": AMReX HDF5 plotfile\n",
        "simulation: time 0.00125 step 40\n",
        "  Y(OH)\n",
        "cell size [0.25, 0.125, 0.5] ratio to next [4, 4, 2]\n",
    ] {
        assert!(t.contains(line), "{line:?} not in\n{t}");
    }
    assert_eq!(json(&amrex)["levels"][0]["cell_size"][1], 0.25);
    assert!(text(&chombo).contains(": Chombo HDF5 file\n"));
    // The HDF5 part runs in a child: its crash is an error naming the file.
    let o = info(
        &[amrex.to_str().unwrap()],
        &[("AMR_CONVERT_TEST_CRASH_CHILD", "1")],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("plt00040.h5: the HDF5 library crashed reading it"),
        "{err}"
    );
}

#[test]
fn what_is_not_a_dump_is_exit_1_with_its_name() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("plt99999");
    let o = info(&[missing.to_str().unwrap()], &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("plt99999") && err.contains("does not exist"),
        "{err}"
    );
}
