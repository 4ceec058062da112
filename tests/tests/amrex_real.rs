//! The converter on real plotfiles written by PeleLM (shared data, not in the repository):
//! every stored value is checked against an independent reading, and the four damaged
//! plotfiles must fail with a clear message and leave nothing behind.

use crate::support::amrex::check::{check_against, check_conversion};
use crate::support::amrex::run_convert;
use crate::support::amrex::source::read_plotfile;
use crate::support::amrex::{assert_fails, convert, shared_amrex};
use amr_format::Compression;

#[test]
fn example_plt_3d_converts_exactly() {
    let Some(data) = shared_amrex("example_plt_3d_converts_exactly") else {
        return;
    };
    let input = data.join("example_plt_3d");
    let src = read_plotfile(&input);
    let out = tempfile::tempdir().unwrap();
    for brick in [32, 3] {
        let target = out.path().join(format!("b{brick}.amrk"));
        let s = convert(&input, &target, &[], brick).unwrap();
        assert_eq!(s.cells, 8 * 8 * 8 * (1 + 8 + 64));
        let c = check_against(&src, &target, &[]);
        assert_eq!(c.values, s.cells * 38);
        assert_eq!(c.min_max, 73 * 38, "every box's Cell_H min and max");
    }
}

/// PeleLM cut each level into boxes of `8^3` cells; joined, the levels' 73 boxes are 10 bricks of
/// at most `16^3`: one a level for the two coarse levels, eight for the finest, one per aligned
/// block (the file streams its boxes by data file, not in the order `Cell_H` lists them). Every
/// value is still where it was, and the surfaces extracted from both files have the same active
/// voxels.
#[test]
fn example_plt_3d_small_boxes_join_into_fewer_bricks() {
    use amr_convert::bricking::ConvertOptions;
    use amr_convert::dump::convert_dump;
    use amr_render::extract::Extractor;
    let Some(data) = shared_amrex("example_plt_3d_small_boxes_join_into_fewer_bricks") else {
        return;
    };
    let input = data.join("example_plt_3d");
    let out = tempfile::tempdir().unwrap();
    let convert_with = |join: bool| {
        let target = out.path().join(format!("join-{join}.amrk"));
        let opts = ConvertOptions {
            fields: vec!["temp".into()],
            brick: 32,
            compression: Compression::None,
            join,
            ..ConvertOptions::default()
        };
        let s = convert_dump(&input, &target, &opts, &amr_format::progress::NoProgress).unwrap();
        check_conversion(&input, &target, &["temp"]);
        let file = amr_format::AmrkFile::open(std::fs::read(&target).unwrap()).unwrap();
        (s.bricks, file)
    };
    let (joined_bricks, joined) = convert_with(true);
    let (kept_bricks, kept) = convert_with(false);
    assert_eq!(kept_bricks, 73);
    assert_eq!(joined_bricks, 10);
    let finest = |f: &amr_format::AmrkFile<Vec<u8>>| {
        (0..f.num_bricks())
            .filter(|&b| f.brick(b).level == 2)
            .map(|b| f.brick(b).cells.extent())
            .collect::<Vec<_>>()
    };
    assert_eq!(finest(&joined), vec![[16; 3]; 8]);
    let (a, b) = (
        Extractor::new(&joined, 0, 64 << 20).unwrap(),
        Extractor::new(&kept, 0, 64 << 20).unwrap(),
    );
    let info = &kept.fields()[0];
    for t in [0.1f32, 0.3, 0.5, 0.7, 0.9] {
        let iso = info.min + (info.max - info.min) * t;
        let (x, y) = (a.extract(iso).unwrap().stats, b.extract(iso).unwrap().stats);
        assert!(y.active > 0, "iso {iso}: no surface");
        assert_eq!(
            (x.active, x.active_duals),
            (y.active, y.active_duals),
            "iso {iso}"
        );
    }
}

#[test]
fn example_plt_3d_compressed_keeps_values() {
    let Some(data) = shared_amrex("example_plt_3d_compressed_keeps_values") else {
        return;
    };
    let input = data.join("example_plt_3d");
    let out = tempfile::tempdir().unwrap();
    let target = out.path().join("z.amrk");
    let fields = ["temp".to_string(), "Y(CH2(S))".to_string()];
    run_convert(&input, &target, &fields, 8, Compression::Zstd { level: 3 }).unwrap();
    check_conversion(&input, &target, &["temp", "Y(CH2(S))"]);
}

#[test]
fn plt1_y_converts_with_bracketed_names() {
    let Some(data) = shared_amrex("plt1_y_converts_with_bracketed_names") else {
        return;
    };
    let input = data.join("plt1_Y");
    let out = tempfile::tempdir().unwrap();
    let all = out.path().join("all.amrk");
    convert(&input, &all, &[], 32).unwrap();
    let c = check_conversion(&input, &all, &[]);
    assert_eq!(c.values, 37376 * 4);
    let some = out.path().join("some.amrk");
    convert(&input, &some, &["Y(O2)", "Y(H)"], 5).unwrap();
    check_conversion(&input, &some, &["Y(O2)", "Y(H)"]);
}

#[test]
fn unknown_field_lists_the_available_ones() {
    let Some(data) = shared_amrex("unknown_field_lists_the_available_ones") else {
        return;
    };
    assert_fails(
        &data.join("plt1_Y"),
        &["Y(N2)"],
        &["no field named 'Y(N2)'", "Y(H), Y(H2), Y(H2O), Y(O2)"],
    );
}

#[test]
fn bad_binary_shape_is_refused() {
    let Some(data) = shared_amrex("bad_binary_shape_is_refused") else {
        return;
    };
    let input = data.join("bad_plotfiles/plt_3d_badbinaryshape");
    assert_fails(
        &input,
        &[],
        &[
            "Level_2/Cell_D_00001",
            "has 35 components",
            "Cell_H says 38",
        ],
    );
}

#[test]
fn bad_index_is_refused() {
    let Some(data) = shared_amrex("bad_index_is_refused") else {
        return;
    };
    let input = data.join("bad_plotfiles/plt_3d_badindexes");
    assert_fails(
        &input,
        &[],
        &[
            "Level_1/Cell_D_00001",
            "covers (8,0,0)..=(15,7,7)",
            "as (9,0,0)..=(15,7,7)",
        ],
    );
}

#[test]
fn missing_binary_data_is_refused() {
    let Some(data) = shared_amrex("missing_binary_data_is_refused") else {
        return;
    };
    let input = data.join("bad_plotfiles/plt_3d_missingbindata");
    assert_fails(
        &input,
        &[],
        &["Level_0/Cell_D_00000", "truncated", "155659 bytes long"],
    );
}

#[test]
fn missing_index_is_refused() {
    let Some(data) = shared_amrex("missing_index_is_refused") else {
        return;
    };
    let input = data.join("bad_plotfiles/plt_3d_missingindexes");
    assert_fails(&input, &[], &["Level_2/Cell_H", "line 69", "box 63 of 64"]);
}

/// Real dumps handed to the renderer instead of their conversion: the error says what they look
/// like and the `amr-convert` command to run (a plotfile's directory for its `Header`; an Enzo
/// dataset's parameter file for its hierarchy or data file).
#[test]
fn real_dumps_given_to_the_renderer_name_the_conversion() {
    let Some(data) = shared_amrex("real_dumps_given_to_the_renderer_name_the_conversion") else {
        return;
    };
    let message = |p: &std::path::Path| match amr_render::mapping::open_mapped(p) {
        Ok(_) => panic!("{} opened as an .amrk file", p.display()),
        Err(e) => e.to_string(),
    };
    let plt = data.join("example_plt_3d");
    for p in [plt.clone(), plt.join("Header")] {
        let m = message(&p);
        let want = format!("amr-convert {} -o OUT.amrk", plt.display());
        assert!(m.contains("AMReX plotfile") && m.contains(&want), "{m}");
    }
    let enzo = data.join("../enzo/DD0010");
    if enzo.is_dir() {
        for part in ["moving7_0010.hierarchy", "moving7_0010.cpu0000"] {
            let m = message(&enzo.join(part));
            let want = format!("amr-convert {} -o", enzo.join("moving7_0010").display());
            assert!(m.contains("Enzo dataset") && m.contains(&want), "{m}");
        }
    }
}
