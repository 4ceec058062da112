//! AMReX HDF5 plotfiles (`WriteMultiLevelPlotfileHDF5`), written by the test as AMReX's writer
//! writes them, converted by the HDF5 reader and read back: the geometry AMReX records (cell
//! sizes per axis, the domain's lower corner at `prob_lo`, per-axis ratios of which the file
//! names only x's), the time and step, and every value rounded to f32. What the reader cannot
//! convert is refused by name.

use std::path::Path;

use amr_convert::chombo::{self, ConvertOptions};
use amr_format::progress::NoProgress;
use amr_format::{AmrkFile, Compression};

use crate::support::amrex::check::check_cells;
use crate::support::amrex_hdf5::{write, AmrexHdf5};
use crate::support::chombo::check::{chain, convert, inclusive};
use crate::support::chombo::value;

/// Converts every field of `d`, written at `dir/plt00040.h5`, into `dir/out.amrk`.
fn written_and_converted(dir: &Path, d: &AmrexHdf5, brick: u32) -> std::path::PathBuf {
    let input = dir.join("plt00040.h5");
    let output = dir.join("out.amrk");
    write(&input, d).unwrap();
    convert(&input, &output, &[], brick, Compression::None);
    output
}

#[test]
fn an_amrex_hdf5_plotfile_converts_with_its_geometry_and_every_value() {
    let d = AmrexHdf5::three_levels();
    let dir = tempfile::tempdir().unwrap();
    for brick in [8, 16] {
        let out = written_and_converted(dir.path(), &d, brick);
        let file = AmrkFile::open(std::fs::read(&out).unwrap()).unwrap();
        let names: Vec<&str> = file.fields().iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["density", "Temp", "Y(OH)"]);
        assert_eq!(file.levels().len(), 3);
        for (l, (got, want)) in file.levels().iter().zip(&d.levels).enumerate() {
            assert_eq!(got.cell_size, want.dx, "level {l} cell size");
            assert_eq!(
                got.origin, want.prob_lo,
                "level {l} origin (domain from index 0)"
            );
            assert_eq!(got.domain, inclusive(want.domain), "level {l} domain");
        }
        assert_eq!(file.levels()[0].ratio_to_next, [2, 2, 2]);
        assert_eq!(
            file.levels()[1].ratio_to_next,
            [4, 4, 2],
            "the y and z ratios come from the domains"
        );
        assert_eq!(file.simulation_time(), Some(0.00125));
        assert_eq!(file.simulation_step(), Some(40));
        let cells = check_cells(&out, &|l, f, p| value(l, f, p) as f32);
        let want: u64 = d
            .levels
            .iter()
            .flat_map(|l| &l.boxes)
            .map(|(b, _)| inclusive(*b).num_cells().unwrap())
            .sum();
        assert_eq!(cells, want * 3, "every valid cell of every field, once");
    }
}

/// `WriteMultiLevelPlotfileHDF5MultiDset`'s variant: one dataset per component.
#[test]
fn the_one_dataset_per_component_variant_converts_alike() {
    let mut d = AmrexHdf5::three_levels();
    d.multi_dset = true;
    let dir = tempfile::tempdir().unwrap();
    let out = written_and_converted(dir.path(), &d, 16);
    let file = AmrkFile::open(std::fs::read(&out).unwrap()).unwrap();
    let names: Vec<&str> = file.fields().iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names, ["density", "Temp", "Y(OH)"]);
    check_cells(&out, &|l, f, p| value(l, f, p) as f32);
    // One field of it alone.
    let one = dir.path().join("one.amrk");
    convert(
        &dir.path().join("plt00040.h5"),
        &one,
        &["Y(OH)"],
        16,
        Compression::None,
    );
    check_cells(&one, &|l, _, p| value(l, 2, p) as f32);
}

/// `compression = "ZLIB@N"`: chunked, shuffled and deflated data reads the same, in both variants.
#[test]
fn zlib_compressed_data_converts_alike() {
    for multi_dset in [false, true] {
        let mut d = AmrexHdf5::three_levels();
        d.zlib = Some(6);
        d.multi_dset = multi_dset;
        let dir = tempfile::tempdir().unwrap();
        let out = written_and_converted(dir.path(), &d, 16);
        let written = hdf5_metno::File::open(dir.path().join("plt00040.h5")).unwrap();
        let data = written.dataset("level_2/data:datatype=0").unwrap();
        assert!(
            !data.filters().is_empty(),
            "the fixture's data is not filtered"
        );
        drop((data, written));
        check_cells(&out, &|l, f, p| value(l, f, p) as f32);
    }
}

/// The stored order of boxes follows their ranks, not the box array: the test's fixture must
/// exercise it, or a reader that assumed the box array's order would pass.
#[test]
fn the_fixture_stores_boxes_in_rank_order() {
    let d = AmrexHdf5::three_levels();
    let array: Vec<[i32; 6]> = d.levels[1].boxes.iter().map(|(b, _)| *b).collect();
    assert_ne!(d.stored_boxes(1), array);
}

/// `Err` text of converting `d`.
fn refusal(d: &AmrexHdf5) -> String {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("plt.h5");
    let output = dir.path().join("out.amrk");
    write(&input, d).unwrap();
    let opts = ConvertOptions {
        fields: Vec::new(),
        brick: 16,
        compression: Compression::None,
        join: true,
        ..ConvertOptions::default()
    };
    let e = chombo::convert(&input, &output, &opts, &NoProgress).unwrap_err();
    assert!(!output.exists(), "an output was left");
    chain(&e)
}

#[test]
fn data_that_is_not_cell_centred_cartesian_is_refused_by_name() {
    let mut d = AmrexHdf5::three_levels();
    d.coord = 1;
    let e = refusal(&d);
    assert!(
        e.contains("coordinate_system = 1") && e.contains("Cartesian"),
        "{e}"
    );
    let mut d = AmrexHdf5::three_levels();
    d.domain_type = [1, 0, 0];
    let e = refusal(&d);
    assert!(
        e.contains("domain_type = [1, 0, 0]") && e.contains("cell-centred"),
        "{e}"
    );
    let mut d = AmrexHdf5::three_levels();
    // A quasi-2D run: no refinement along z.
    d.levels[1].ratio = [4, 4, 1];
    d.levels[2].domain[5] = 15;
    d.levels[2].dx[2] = 0.5;
    for (b, _) in &mut d.levels[2].boxes {
        b[2] = 2;
        b[5] = 7;
    }
    let e = refusal(&d);
    assert!(e.contains("ratio of 1") && e.contains("axis 2"), "{e}");
}
