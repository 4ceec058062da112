//! `amr-convert --update`: a series converted again keeps the `.amrk` files that are up to date
//! and converts the dumps that are new, changed since, or whose file is damaged or holds other
//! fields.

// The integration tests' support code: fixture writers and the shared-data folder.
#[path = "../../tests/tests/support/mod.rs"]
#[allow(dead_code)]
mod support;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, SystemTime};

use support::amrex::writer::{write_plotfile, PlotSpec};

const BIN: &str = env!("CARGO_BIN_EXE_amr-convert");

/// `amr-convert args...`, which must succeed; its standard error.
fn convert(args: &[&Path], extra: &[&str]) -> String {
    let o = Command::new(BIN).args(args).args(extra).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{args:?} {extra:?}: {err}");
    err
}

fn modified(p: &Path) -> SystemTime {
    std::fs::metadata(p).unwrap().modified().unwrap()
}

/// Sets `p`'s modification time to `t`.
fn set_modified(p: &Path, t: SystemTime) {
    let f = std::fs::File::options().append(true).open(p).unwrap();
    f.set_modified(t).unwrap();
}

#[test]
fn an_update_converts_only_the_dumps_that_changed_since() {
    let dir = tempfile::tempdir().unwrap();
    let plt: Vec<PathBuf> = ["plt00100", "plt00200"]
        .iter()
        .map(|n| dir.path().join(n))
        .collect();
    let mut spec = PlotSpec::single(8);
    spec.fields = vec!["density".into(), "temp".into()];
    for (k, p) in plt.iter().enumerate() {
        write_plotfile(p, &spec, &|c, _, x| (k + c) as f64 + x[0] as f64, 0.0);
    }
    let out = dir.path().join("amrk");
    let amrk: Vec<PathBuf> = ["plt00100.amrk", "plt00200.amrk"]
        .iter()
        .map(|n| out.join(n))
        .collect();
    let series = [
        plt[0].as_path(),
        plt[1].as_path(),
        Path::new("-o"),
        out.as_path(),
    ];
    let first = convert(&series, &["--update"]);
    assert!(!first.contains("up to date"), "{first}");
    let written = amrk.iter().map(|p| modified(p)).collect::<Vec<_>>();

    // Nothing changed: both kept, untouched.
    let again = convert(&series, &["--update"]);
    assert_eq!(again.matches("up to date, kept").count(), 2, "{again}");
    assert_eq!(
        amrk.iter().map(|p| modified(p)).collect::<Vec<_>>(),
        written
    );

    // A data file of the first dump rewritten after its conversion (the conversion's time set a
    // minute before the file's): only that dump converts again.
    let cell_d = plt[0].join("Level_0/Cell_D_00000");
    let earlier = modified(&cell_d) - Duration::from_secs(60);
    set_modified(&amrk[0], earlier);
    let after = convert(&series, &["--update"]);
    assert_eq!(after.matches("up to date, kept").count(), 1, "{after}");
    assert!(after.contains("plt00200.amrk: up to date"), "{after}");
    assert!(modified(&amrk[0]) >= modified(&cell_d));
    assert_eq!(modified(&amrk[1]), written[1]);

    // A damaged output, and outputs without the fields asked for, convert again.
    let len = std::fs::metadata(&amrk[1]).unwrap().len();
    let f = std::fs::File::options().write(true).open(&amrk[1]).unwrap();
    f.set_len(len / 2).unwrap();
    drop(f);
    let damaged = convert(&series, &["--update"]);
    assert!(!damaged.contains("plt00200.amrk: up to date"), "{damaged}");
    assert_eq!(std::fs::metadata(&amrk[1]).unwrap().len(), len);
    let one_field = convert(&series, &["--update", "--field", "temp"]);
    assert!(!one_field.contains("up to date"), "{one_field}");
    let kept = convert(&series, &["--update", "--field", "temp", "--field", "temp"]);
    assert_eq!(kept.matches("up to date, kept").count(), 2, "{kept}");

    // Without --update every dump converts, as before.
    let plain = convert(&series, &[]);
    assert!(!plain.contains("up to date"), "{plain}");

    // One dump to one file, kept the same way.
    let single = dir.path().join("one.amrk");
    let args = [plt[1].as_path(), Path::new("-o"), single.as_path()];
    convert(&args, &["--update"]);
    let kept = convert(&args, &["--update"]);
    assert!(kept.contains("one.amrk: up to date, kept"), "{kept}");
}

/// An Enzo dataset named by its parameter file: its other files (`NAME.hierarchy`,
/// `NAME.cpu0000`, ...) count as the dump's, so a data file rewritten after the conversion makes
/// it convert again (the real `DD0010`, copied).
#[test]
fn an_enzo_dataset_is_out_of_date_when_any_of_its_files_is_newer() {
    let test = "an_enzo_dataset_is_out_of_date_when_any_of_its_files_is_newer";
    let Some(real) = support::amrex::shared_data(test, "enzo/DD0010", "moving7_0010") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("DD0010");
    std::fs::create_dir(&copy).unwrap();
    for entry in std::fs::read_dir(&real).unwrap() {
        let entry = entry.unwrap();
        std::fs::copy(entry.path(), copy.join(entry.file_name())).unwrap();
    }
    let params = copy.join("moving7_0010");
    let out = dir.path().join("dd.amrk");
    let args = [params.as_path(), Path::new("-o"), out.as_path()];
    convert(&args, &["--update", "--field", "Density"]);
    let kept = convert(&args, &["--update", "--field", "Density"]);
    assert!(kept.contains("up to date, kept"), "{kept}");
    let data = copy.join("moving7_0010.cpu0000");
    set_modified(&out, modified(&data) - Duration::from_secs(60));
    let again = convert(&args, &["--update", "--field", "Density"]);
    assert!(!again.contains("up to date"), "{again}");
}
