//! Every reader streams its boxes in the order it declares (`AmrSource::stream_order`): the
//! converter joins only boxes that come close together in that order, so that it holds few
//! unfinished joined bricks. Checked on the real PeleLM plotfile (whose data files hold
//! boxes out of `Cell_H`'s order), the real Enzo dataset and a written Chombo file.

use amr_convert::hierarchy_to_amrk::AmrSource;
use amr_format::progress::NoProgress;

use crate::support::amrex::{shared_amrex, shared_data};
use crate::support::chombo::{writer, Desc};

/// The boxes in the order `src` streams them, for each field in turn when it streams field by
/// field: a box is counted when its first slab comes after another box's.
fn streamed<S: AmrSource>(src: &S) -> Vec<(usize, usize)>
where
    S::Error: std::fmt::Debug,
{
    let comps: Vec<usize> = (0..src.fields().len()).collect();
    let mut seen: Vec<(usize, usize)> = Vec::new();
    src.stream(&comps, 4, &NoProgress, &mut |slab| {
        let b = (slab.level, slab.index);
        if seen.last() != Some(&b) {
            seen.push(b);
        }
        Ok(())
    })
    .unwrap();
    seen
}

fn assert_declared_order<S: AmrSource>(src: &S, what: &str)
where
    S::Error: std::fmt::Debug,
{
    let declared = src.stream_order();
    let total: usize = src.boxes().iter().map(|l| l.len()).sum();
    assert_eq!(declared.len(), total, "{what}: every box once");
    assert_eq!(streamed(src), declared, "{what}");
}

#[test]
fn amrex_streams_boxes_in_declared_order() {
    let Some(data) = shared_amrex("amrex_streams_boxes_in_declared_order") else {
        return;
    };
    let pf = amr_convert::amrex::Plotfile::open(&data.join("plt1_Y")).unwrap();
    let declared = pf.stream_order();
    let listed: Vec<(usize, usize)> = pf
        .boxes()
        .iter()
        .enumerate()
        .flat_map(|(l, b)| (0..b.len()).map(move |i| (l, i)))
        .collect();
    assert_ne!(
        declared, listed,
        "the data files hold boxes out of Cell_H's order"
    );
    assert_declared_order(&pf, "plt1_Y");
}

#[test]
fn enzo_streams_grids_in_declared_order() {
    let Some(dir) = shared_data(
        "enzo_streams_grids_in_declared_order",
        "enzo/DD0010",
        "moving7_0010.hierarchy",
    ) else {
        return;
    };
    let ds = amr_convert::enzo::Dataset::open(
        &dir.join("moving7_0010"),
        &dir.join("moving7_0010.hierarchy"),
    )
    .unwrap();
    assert_declared_order(&ds, "DD0010");
}

#[test]
fn chombo_streams_boxes_in_declared_order() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plt.3d.hdf5");
    writer::write(&path, &Desc::three_levels(false)).unwrap();
    let pf = amr_convert::chombo::Plotfile::open(&path).unwrap();
    assert_declared_order(&pf, "three levels");
}
