//! `amr-render info` and `verify` on bad files: exit code 1 and a message naming the file.

use std::path::Path;
use std::process::Command;

fn run(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_amr-render"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn expect_error(path: &Path, needle: &str) {
    for cmd in ["info", "verify"] {
        let (code, err) = run(&[cmd, path.to_str().unwrap()]);
        assert_eq!(
            code,
            1,
            "{cmd} {}: exit {code}, stderr: {err}",
            path.display()
        );
        assert!(
            err.contains(&path.display().to_string()),
            "{cmd}: error does not name the file: {err}"
        );
        assert!(err.contains(needle), "{cmd}: expected '{needle}' in: {err}");
    }
}

#[test]
fn bad_files_give_exit_code_1_and_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("empty.amrk");
    std::fs::write(&empty, b"").unwrap();
    expect_error(&empty, "empty");
    expect_error(dir.path(), "directory");
    let text = dir.path().join("text.amrk");
    std::fs::write(&text, vec![b'x'; 4096]).unwrap();
    expect_error(&text, "not an .amrk file");
    expect_error(&dir.path().join("missing.amrk"), "cannot open");
    // A FIFO is refused before it is opened: opening it would wait for a writer forever.
    let fifo = dir.path().join("fifo.amrk");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if made.is_ok_and(|s| s.success()) {
        expect_error(&fifo, "not a regular file");
    }
}

/// A compressed brick is decoded whole, so its checksum is checked first: a damaged one stops
/// `extract` and a render with an error naming the file and the brick, and no frame is written,
/// where it used to decode to wrong values and render them.
#[test]
fn a_damaged_compressed_brick_is_refused_when_it_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.amrk");
    write_small_file_stored(&good, "f", amr_format::Compression::Zstd { level: 3 });
    let mut bytes = std::fs::read(&good).unwrap();
    let file = amr_format::AmrkFile::open(bytes.clone()).unwrap();
    let damaged = (0..file.num_bricks())
        .find(|&b| file.brick_data(0, b).encoding == amr_format::compress::Encoding::ZstdShuffled)
        .expect("a brick stored compressed");
    let at = file.brick_data(0, damaged);
    bytes[(at.offset + at.len / 2) as usize] ^= 0x04;
    let bad = dir.path().join("bad.amrk");
    std::fs::write(&bad, &bytes).unwrap();
    let iso = "--iso=0.5";
    assert_eq!(run(&["extract", good.to_str().unwrap(), iso]).0, 0);
    let frame = dir.path().join("frame.png");
    for args in [
        vec!["extract", bad.to_str().unwrap(), iso],
        vec![
            bad.to_str().unwrap(),
            iso,
            "--size=32x24",
            "-o",
            frame.to_str().unwrap(),
        ],
    ] {
        let (code, err) = run(&args);
        assert_eq!(code, 1, "{args:?}: {err}");
        assert!(
            err.contains("checksum mismatch")
                && err.contains("bad.amrk")
                && err.contains(&format!("brick {damaged}")),
            "{args:?}: {err}"
        );
    }
    assert!(!frame.exists(), "no frame is written");
}

/// A raw brick is read in place, unchecked; a NaN or an infinity written into one after
/// conversion (no converter writes one) stops a render whose rays meet it, by either method or
/// on a slice, with an error naming the file, the value and the place, where it used to leave a
/// hole in the surface, and no frame is written.
#[test]
fn a_value_not_finite_written_into_a_raw_brick_stops_the_render_that_meets_it() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.amrk");
    write_small_file(&good);
    let bytes = std::fs::read(&good).unwrap();
    // Brick 0 holds 0, 1, 2, ... x fastest: the surface at 0.5 passes between its first cells.
    let at = amr_format::AmrkFile::open(bytes.clone())
        .unwrap()
        .brick_data(0, 0)
        .offset as usize;
    let frame = dir.path().join("frame.png");
    for (value, shown) in [(f32::NAN, "NaN"), (f32::INFINITY, "inf")] {
        let mut damaged = bytes.clone();
        damaged[at + 4..at + 8].copy_from_slice(&value.to_le_bytes());
        let bad = dir.path().join("bad.amrk");
        std::fs::write(&bad, &damaged).unwrap();
        // The hybrid method, the sample method, and a slice through the damaged cell alone.
        for how in [
            &["--iso=0.5"][..],
            &["--iso=0.5", "--method=sample"],
            &["--iso=1000", "--slice=z=0.0625", "--quiet"],
        ] {
            let render = |file: &Path| {
                let mut args = vec![file.to_str().unwrap(), "--size=64x48", "-o"];
                args.push(frame.to_str().unwrap());
                args.extend(how);
                run(&args)
            };
            assert_eq!(render(&good).0, 0, "{how:?}");
            std::fs::remove_file(&frame).unwrap();
            let (code, err) = render(&bad);
            assert_eq!(code, 1, "{shown} {how:?}: {err}");
            // The value read, or NaN where the reconstruction mixes an infinity with others.
            let says = |v: &str| err.contains(&format!("field 'f' is {v} near ("));
            assert!(
                err.contains("bad.amrk") && (says(shown) || says("NaN")),
                "{shown} {how:?}: {err}"
            );
            assert!(!frame.exists(), "{shown} {how:?}: no frame is written");
        }
        let (code, err) = run(&["verify", bad.to_str().unwrap()]);
        assert_eq!(code, 1);
        assert!(err.contains("checksum mismatch"), "{err}");
    }
}

#[test]
fn truncated_and_flipped_files() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.amrk");
    write_small_file(&good);
    let bytes = std::fs::read(&good).unwrap();
    let cut = dir.path().join("cut.amrk");
    std::fs::write(&cut, &bytes[..bytes.len() - 10]).unwrap();
    expect_error(&cut, "truncated");
    let mut flipped = bytes.clone();
    let data = amr_format::AmrkFile::open(bytes.clone())
        .unwrap()
        .brick_data(0, 0)
        .offset as usize;
    flipped[data + 3] ^= 0x40;
    let data_flip = dir.path().join("flip.amrk");
    std::fs::write(&data_flip, &flipped).unwrap();
    let (code, _) = run(&["info", data_flip.to_str().unwrap()]);
    assert_eq!(code, 0, "damaged brick data does not stop info");
    let (code, err) = run(&["verify", data_flip.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(
        err.contains("checksum mismatch") && err.contains("flip.amrk"),
        "{err}"
    );
    // A damaged block range table (version 2; outside the checksummed metadata) is found too.
    let mut table_flip = bytes.clone();
    table_flip[64 + 3] ^= 0x40;
    let table_path = dir.path().join("table.amrk");
    std::fs::write(&table_path, &table_flip).unwrap();
    let (code, err) = run(&["verify", table_path.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(
        err.contains("block range table") && err.contains("table.amrk"),
        "{err}"
    );
    assert_eq!(run(&["verify", good.to_str().unwrap()]).0, 0);
}

fn write_small_file(path: &Path) {
    write_small_file_with(path, "f");
}

/// [`write_small_file`] with its one field named `field`.
fn write_small_file_with(path: &Path, field: &str) {
    write_small_file_stored(path, field, amr_format::Compression::None);
}

/// [`write_small_file_with`], its bricks stored with `compression`.
fn write_small_file_stored(path: &Path, field: &str, compression: amr_format::Compression) {
    use amr_format::{AmrkWriter, BrickSpec, HierarchySpec, IBox, LevelSpec, WriterOptions};
    let domain = IBox::new([0; 3], [8; 3]);
    let spec = HierarchySpec {
        levels: vec![LevelSpec {
            cell_size: [0.125; 3],
            origin: [0.0; 3],
            ratio_to_next: [1; 3],
            domain,
        }],
        fields: vec![field.into()],
        bricks: domain
            .split([4; 3])
            .into_iter()
            .map(|c| BrickSpec { level: 0, cells: c })
            .collect(),
    };
    let options = WriterOptions {
        compression,
        ..WriterOptions::default()
    };
    let mut w = AmrkWriter::create(path, spec.clone(), options).unwrap();
    for (i, b) in spec.bricks.iter().enumerate() {
        let n = b.cells.num_cells().unwrap() as usize;
        w.write_brick(
            i,
            0,
            &(0..n).map(|k| k as f32 + i as f32).collect::<Vec<_>>(),
        )
        .unwrap();
    }
    w.finish().unwrap();
}

/// A frame or preview named for a format `amr-render` does not write is refused before
/// anything is rendered, and nothing is written.
#[test]
fn outputs_named_for_other_formats_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.amrk");
    write_small_file(&good);
    let f = good.to_str().unwrap();
    let jpg = dir.path().join("frame.jpg");
    let (code, err) = run(&[f, "--iso", "100", "-o", jpg.to_str().unwrap()]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("frame.jpg") && err.contains(".exr"), "{err}");
    let exr = dir.path().join("frame.EXR");
    let tif = dir.path().join("preview.tif");
    let args = [f, "--iso", "100", "-o", exr.to_str().unwrap()];
    let (code, err) = run(&[&args[..], &["--preview", tif.to_str().unwrap()]].concat());
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("preview.tif"), "{err}");
    let (code, err) = run(&["demo", "-o", jpg.to_str().unwrap()]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("frame.jpg"), "{err}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    // Upper-case extensions are the formats they name.
    let (code, err) = run(&args);
    assert_eq!(code, 0, "{err}");
    assert!(exr.exists());
}

/// Two outputs of one run naming one file (the statistics over the frame, through another
/// spelling of its path) are refused, as is a series with a file that does not open: before
/// any frame is written.
#[test]
fn outputs_that_collide_and_series_that_cannot_open_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.amrk");
    write_small_file(&good);
    let f = good.to_str().unwrap();
    let frame = dir.path().join("frame.exr");
    let again = dir.path().join(".").join("frame.exr");
    let (code, err) = run(&[
        f,
        "--iso",
        "100",
        "-o",
        frame.to_str().unwrap(),
        "--stats-json",
        again.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("--stats-json") && err.contains("frame 0"),
        "{err}"
    );
    let missing = dir.path().join("missing.amrk");
    let (code, err) = run(&[
        f,
        missing.to_str().unwrap(),
        "--iso",
        "100",
        "-o",
        frame.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("missing.amrk"), "{err}");
    // A later file of the series without the field asked for: refused before frame 0 too.
    let other = dir.path().join("other.amrk");
    write_small_file_with(&other, "g");
    let (code, err) = run(&[
        f,
        other.to_str().unwrap(),
        "--field",
        "f",
        "--iso",
        "100",
        "-o",
        frame.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("other.amrk: no field 'f'"), "{err}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
}

/// `--write-scene` never replaces the data it names: a scene file is `.toml`, and is refused
/// where it would replace an input; a refused scene stops the run before any frame.
#[test]
fn a_scene_file_never_replaces_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.amrk");
    write_small_file(&good);
    let before = std::fs::read(&good).unwrap();
    let f = good.to_str().unwrap();
    let frame = dir.path().join("frame.png");
    let o = frame.to_str().unwrap();
    let (code, err) = run(&[f, "--iso", "100", "-o", o, "--write-scene", f]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains(".toml"), "{err}");
    assert_eq!(std::fs::read(&good).unwrap(), before, "the input changed");
    assert!(!frame.exists());
    // A scene file beside it is written whole, and renders again.
    let scene = dir.path().join("scene.toml");
    let (code, err) = run(&[
        f,
        "--iso",
        "100",
        "-o",
        o,
        "--write-scene",
        scene.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&scene).unwrap();
    assert!(
        text.contains("good.amrk") && text.contains("frame.png"),
        "{text}"
    );
    std::fs::remove_file(&frame).unwrap();
    let (code, err) = run(&[scene.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(frame.exists());
}

/// A command that fails writes no scene file, and leaves the one it would replace as it was:
/// `amr-render scene.toml --iso ... --write-scene scene.toml` with a mistake in it must not
/// lose the scene that worked.
#[test]
fn a_failed_command_writes_no_scene_file() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.amrk");
    write_small_file(&good);
    let f = good.to_str().unwrap();
    let frame = dir.path().join("frame.png");
    let scene = dir.path().join("scene.toml");
    let s = scene.to_str().unwrap();
    let (code, err) = run(&[
        f,
        "--iso",
        "100",
        "-o",
        frame.to_str().unwrap(),
        "--write-scene",
        s,
    ]);
    assert_eq!(code, 0, "{err}");
    let before = std::fs::read(&scene).unwrap();
    // A field that does not exist, and an output directory that does not.
    let missing = dir.path().join("no").join("frame.png");
    for bad in [
        vec![s, "--field", "nonesuch", "--write-scene", s],
        vec![s, "-o", missing.to_str().unwrap(), "--write-scene", s],
    ] {
        let (code, err) = run(&bad);
        assert_eq!(code, 1, "{bad:?}: {err}");
        assert_eq!(
            std::fs::read(&scene).unwrap(),
            before,
            "{bad:?}: the scene changed"
        );
    }
    let other = dir.path().join("other.toml");
    let (code, err) = run(&[
        s,
        "--field",
        "nonesuch",
        "--write-scene",
        other.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(!other.exists(), "a failed command wrote a scene file");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        3,
        "no leftovers"
    );
}
