//! Float32 plotfiles as AMReX writes them. The FAB header below is typed out from AMReX's own
//! writer (`FABio_binary::write_header` in AMReX_FArrayBox.cpp prints `"FAB " << RealDescriptor`;
//! `operator<<(ostream&, RealDescriptor)` and `putarray` in AMReX_FabConv.cpp print each array as
//! `(number of entries, (entries))`), not produced by the reader or by the tests' writer.

use crate::support::amrex::writer::Real;
use amr_format::AmrkFile;

/// The `Header` of a one-level plotfile: one field `rho`, domain `(0,0,0)..(1,1,1)` on `[0,1]^3`.
const HEADER: &str = "HyperCLaw-V1.1\n1\nrho\n3\n0\n0\n0 0 0\n1 1 1\n\n\
((0,0,0) (1,1,1) (0,0,0)) \n0 \n0.5 0.5 0.5 \n0\n0\n0 1 0\n0\n0 1\n0 1\n0 1\nLevel_0/Cell\n";

/// The `Cell_H` of that level: one box, its FAB at byte 0 of `Cell_D_00000`, then the box's
/// minimum and maximum of `VALUES`.
const CELL_H: &str =
    "1\n1\n1\n0\n(1 0\n((0,0,0) (1,1,1) (0,0,0))\n)\n1\nFabOnDisk: Cell_D_00000 0\n\n\
1,1\n-7.0e+00,\n\n1,1\n4.0e+20,\n";

const FAB_F32_LE: &str =
    "FAB ((8, (32 8 23 0 1 9 0 127)),(4, (4 3 2 1)))((0,0,0) (1,1,1) (0,0,0)) 1\n";
const FAB_F32_BE: &str =
    "FAB ((8, (32 8 23 0 1 9 0 127)),(4, (1 2 3 4)))((0,0,0) (1,1,1) (0,0,0)) 1\n";
const FAB_F64_LE: &str =
    "FAB ((8, (64 11 52 0 1 12 0 1023)),(8, (8 7 6 5 4 3 2 1)))((0,0,0) (1,1,1) (0,0,0)) 1\n";

/// How a case encodes one value.
type Encode = dyn Fn(f32) -> Vec<u8>;

/// The eight cell values, x fastest.
const VALUES: [f32; 8] = [1.5, -2.25, 3.0e-7, 4.0e20, 5.0, 6.125, -7.0, 8.0];

fn plotfile(dir: &std::path::Path, fab_header: &str, bytes: &Encode) {
    std::fs::create_dir_all(dir.join("Level_0")).unwrap();
    std::fs::write(dir.join("Header"), HEADER).unwrap();
    std::fs::write(dir.join("Level_0/Cell_H"), CELL_H).unwrap();
    let mut data = fab_header.as_bytes().to_vec();
    for v in VALUES {
        data.extend(bytes(v));
    }
    std::fs::write(dir.join("Level_0/Cell_D_00000"), data).unwrap();
}

fn converted_values(input: &std::path::Path, out: &std::path::Path) -> Vec<f32> {
    crate::support::amrex::convert(input, out, &[], 32).unwrap();
    let f = AmrkFile::open(std::fs::read(out).unwrap()).unwrap();
    f.brick_values(0, 0).unwrap().to_vec()
}

#[test]
fn float32_fab_headers_as_amrex_prints_them_convert() {
    let tmp = tempfile::tempdir().unwrap();
    let cases: [(&str, &str, &Encode); 3] = [
        ("le", FAB_F32_LE, &|v: f32| v.to_le_bytes().to_vec()),
        ("be", FAB_F32_BE, &|v: f32| v.to_be_bytes().to_vec()),
        ("d", FAB_F64_LE, &|v: f32| {
            f64::from(v).to_le_bytes().to_vec()
        }),
    ];
    for (name, header, bytes) in cases {
        let dir = tmp.path().join(name);
        plotfile(&dir, header, bytes);
        let out = tmp.path().join(format!("{name}.amrk"));
        assert_eq!(converted_values(&dir, &out), VALUES, "{name}");
    }
}

#[test]
fn the_tests_writer_prints_amrex_descriptors() {
    let descriptor = |h: &str| h[4..h.find(")((").unwrap() + 1].to_string();
    assert_eq!(Real::F32Le.descriptor(), descriptor(FAB_F32_LE));
    assert_eq!(Real::F32Be.descriptor(), descriptor(FAB_F32_BE));
    assert_eq!(Real::F64Le.descriptor(), descriptor(FAB_F64_LE));
}

#[test]
fn the_old_byte_count_form_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("old");
    let old = "FAB ((4, (32 8 23 0 1 9 0 127)),(4, (4 3 2 1)))((0,0,0) (1,1,1) (0,0,0)) 1\n";
    plotfile(&dir, old, &|v: f32| v.to_le_bytes().to_vec());
    crate::support::amrex::assert_fails(
        &dir,
        &[],
        &["Cell_D_00000", "more than the 4 entries it announces"],
    );
}

/// The real PeleLM plotfile with every FAB rewritten as AMReX writes float32 little-endian
/// (the header's descriptor replaced by the float32 one from the grammar above, each value
/// stored as `f32`, `Cell_H` offsets moved accordingly) must convert to exactly the values the
/// float64 original converts to: the same numbers rounded once to `f32`.
#[test]
fn real_plotfile_rewritten_as_float32_converts_to_the_same_values() {
    let Some(data) = crate::support::amrex::shared_amrex(
        "real_plotfile_rewritten_as_float32_converts_to_the_same_values",
    ) else {
        return;
    };
    let src = data.join("example_plt_3d");
    let tmp = tempfile::tempdir().unwrap();
    let f32_dir = tmp.path().join("plt_f32");
    rewrite_as_float32(&src, &f32_dir);
    let (a, b) = (tmp.path().join("f64.amrk"), tmp.path().join("f32.amrk"));
    crate::support::amrex::convert(&src, &a, &[], 32).unwrap();
    crate::support::amrex::convert(&f32_dir, &b, &[], 32).unwrap();
    let (a, b) = (
        AmrkFile::open(std::fs::read(a).unwrap()).unwrap(),
        AmrkFile::open(std::fs::read(b).unwrap()).unwrap(),
    );
    assert_eq!(a.num_bricks(), b.num_bricks());
    assert_eq!(b.fields().len(), 38);
    for f in 0..a.fields().len() {
        for i in 0..a.num_bricks() {
            assert_eq!(a.brick_values(f, i).unwrap(), b.brick_values(f, i).unwrap());
        }
    }
}

/// Copies the plotfile `src` to `dst`, re-encoding every FAB of every `Cell_D` file from
/// float64 little-endian to float32 little-endian.
fn rewrite_as_float32(src: &std::path::Path, dst: &std::path::Path) {
    std::fs::create_dir_all(dst).unwrap();
    std::fs::copy(src.join("Header"), dst.join("Header")).unwrap();
    for l in 0.. {
        let level = src.join(format!("Level_{l}"));
        if !level.is_dir() {
            break;
        }
        let out = dst.join(format!("Level_{l}"));
        std::fs::create_dir_all(&out).unwrap();
        let cell_h = std::fs::read_to_string(level.join("Cell_H")).unwrap();
        let mut moved = std::collections::HashMap::new();
        let mut lines = Vec::new();
        for line in cell_h.lines() {
            let Some(rest) = line.strip_prefix("FabOnDisk: ") else {
                lines.push(line.to_string());
                continue;
            };
            let (file, offset) = rest.split_once(' ').unwrap();
            let offset: usize = offset.trim().parse().unwrap();
            let new = *moved
                .entry(file.to_string())
                .or_insert_with(|| reencode(&level.join(file), &out.join(file)))
                .get(&offset)
                .unwrap();
            lines.push(format!("FabOnDisk: {file} {new}"));
        }
        std::fs::write(out.join("Cell_H"), lines.join("\n") + "\n").unwrap();
    }
}

/// Re-encodes one `Cell_D` file; returns each FAB's old offset mapped to its new one.
fn reencode(
    src: &std::path::Path,
    dst: &std::path::Path,
) -> std::collections::HashMap<usize, usize> {
    const F64_LE: &str = "FAB ((8, (64 11 52 0 1 12 0 1023)),(8, (8 7 6 5 4 3 2 1)))";
    const F32_LE: &str = "FAB ((8, (32 8 23 0 1 9 0 127)),(4, (4 3 2 1)))";
    let bytes = std::fs::read(src).unwrap();
    let (mut pos, mut out, mut map) = (0, Vec::new(), std::collections::HashMap::new());
    while pos < bytes.len() {
        let end = pos + bytes[pos..].iter().position(|&b| b == b'\n').unwrap();
        let line = std::str::from_utf8(&bytes[pos..end]).unwrap();
        let rest = line
            .strip_prefix(F64_LE)
            .expect("a float64 little-endian FAB");
        let n: Vec<i64> = rest
            .split(|c: char| !(c.is_ascii_digit() || c == '-'))
            .filter(|s| !s.is_empty())
            .map(|s| s.parse().unwrap())
            .collect();
        let cells: i64 = (0..3).map(|a| n[3 + a] - n[a] + 1).product();
        let count = (cells * n[9]) as usize;
        map.insert(pos, out.len());
        out.extend_from_slice(format!("{F32_LE}{rest}\n").as_bytes());
        for c in bytes[end + 1..end + 1 + 8 * count].chunks_exact(8) {
            let v = f64::from_le_bytes(c.try_into().unwrap());
            out.extend_from_slice(&(v as f32).to_le_bytes());
        }
        pos = end + 1 + 8 * count;
    }
    std::fs::write(dst, out).unwrap();
    map
}
