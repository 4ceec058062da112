//! Shared helpers of the AMReX tests: where the shared plotfiles are, an independent reader,
//! a plotfile writer and the cell-by-cell comparison.

pub mod check;
pub mod source;
pub mod writer;

use std::path::{Path, PathBuf};

use amr_convert::bricking::ConvertOptions;
use amr_convert::dump::{convert_dump, ConvertSummary, DumpError};
use amr_format::progress::NoProgress;
use amr_format::Compression;

/// The shared real data folder `REL` (`$AMR_TEST_DATA/REL`, else `../shared/data/REL` from the
/// workspace root) when it holds `probe`; `None`, after saying on stderr that `test` was
/// skipped and why, otherwise.
pub fn shared_data(test: &str, rel: &str, probe: &str) -> Option<PathBuf> {
    let root = match std::env::var_os("AMR_TEST_DATA") {
        Some(p) => PathBuf::from(p),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"),
    };
    let dir = root.join(rel);
    if dir.join(probe).is_file() {
        Some(dir)
    } else {
        eprintln!(
            "skipped: {test}, because {} does not hold {probe} (set AMR_TEST_DATA to the folder holding {rel})",
            dir.display()
        );
        None
    }
}

/// The shared AMReX plotfiles (`amrex/` of the shared data), or `None` after saying why.
pub fn shared_amrex(test: &str) -> Option<PathBuf> {
    shared_data(test, "amrex", "example_plt_3d/Header")
}

/// Converts with default settings apart from `fields` and `brick`.
pub fn convert(
    input: &Path,
    output: &Path,
    fields: &[&str],
    brick: u32,
) -> Result<ConvertSummary, DumpError> {
    let fields: Vec<String> = fields.iter().map(|s| s.to_string()).collect();
    run_convert(input, output, &fields, brick, Compression::None)
}

/// Converts `input` (any format) as `amr-convert` does, without a progress bar.
pub fn run_convert(
    input: &Path,
    output: &Path,
    fields: &[String],
    brick: u32,
    compression: Compression,
) -> Result<ConvertSummary, DumpError> {
    let opts = ConvertOptions {
        fields: fields.to_vec(),
        brick,
        compression,
        join: true,
        ..ConvertOptions::default()
    };
    convert_dump(input, output, &opts, &NoProgress)
}

/// Asserts that converting `input` fails with a message containing every one of `needles`,
/// and that the output directory holds nothing afterwards. Returns the message.
pub fn assert_fails(input: &Path, fields: &[&str], needles: &[&str]) -> String {
    let out = tempfile::tempdir().unwrap();
    let target = out.path().join("out.amrk");
    let err = convert(input, &target, fields, 32).expect_err("the conversion should fail");
    let msg = format!("{err:#}");
    for n in needles {
        assert!(msg.contains(n), "error message lacks '{n}': {msg}");
    }
    let left: Vec<_> = std::fs::read_dir(out.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert!(
        left.is_empty(),
        "files left behind after a failed conversion: {left:?}"
    );
    msg
}
