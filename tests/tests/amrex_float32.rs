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
