//! The simulation time and step of real dumps reach the `.amrk` footer: the values are those
//! the codes wrote (DD0010's parameter file says `InitialTime = 0.81751317119117` and
//! `InitialCycleNumber = 10`; the PeleLM plotfile's Header gives time 1.3924182125972017e-08 and
//! level steps starting at 20).

use amr_format::AmrkFile;

use crate::support::amrex::{convert, shared_data};

fn stamp_of(input: &std::path::Path) -> (Option<f64>, Option<i64>) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.amrk");
    convert(input, &out, &[], 16).unwrap();
    let file = AmrkFile::open(std::fs::read(&out).unwrap()).unwrap();
    (file.simulation_time(), file.simulation_step())
}

#[test]
fn enzo_and_amrex_dumps_record_their_time_and_step() {
    if let Some(dir) = shared_data("simulation_stamp", "enzo/DD0010", "moving7_0010.hierarchy") {
        assert_eq!(
            stamp_of(&dir.join("moving7_0010")),
            (Some(0.81751317119117), Some(10))
        );
    }
    if let Some(dir) = shared_data("simulation_stamp", "amrex/example_plt_3d", "Header") {
        assert_eq!(stamp_of(&dir), (Some(1.3924182125972017e-08), Some(20)));
    }
}

/// `amr-render info` prints the PeleLM time in full but readably, and no ratio for the finest
/// level, which has no next level.
#[test]
fn info_prints_a_small_time_in_full_and_no_ratio_past_the_finest_level() {
    let Some(dir) = shared_data("simulation_stamp", "amrex/example_plt_3d", "Header") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out.amrk");
    convert(&dir, &out, &[], 16).unwrap();
    let text = amr_render::info::describe(&amr_render::mapping::open_mapped(&out).unwrap());
    assert!(
        text.contains("simulation: time 1.3924182125972017e-8 step 20"),
        "{text}"
    );
    let levels: Vec<&str> = text.lines().filter(|l| l.starts_with("  level ")).collect();
    assert_eq!(levels.len(), 3, "{text}");
    assert!(levels[..2]
        .iter()
        .all(|l| l.ends_with("ratio to next [2, 2, 2]")));
    assert!(!levels[2].contains("ratio"), "{}", levels[2]);
}

/// A picture of a dump says when in the simulation it was written: the legend's first line is
/// `t = 0.81751, step 10` for DD0010.
#[test]
fn the_legend_of_a_real_dump_shows_its_time_and_step() {
    let Some(dir) = shared_data("simulation_stamp", "enzo/DD0010", "moving7_0010.hierarchy") else {
        return;
    };
    use amr_render::output::legend::Legend;
    use amr_render::{render, Scene, SceneOptions, View};
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out.amrk");
    convert(&dir.join("moving7_0010"), &out, &[], 16).unwrap();
    let mut scene = Scene::open(&out, &SceneOptions::default()).unwrap();
    scene.set_isosurfaces(&[]).unwrap();
    let view = View {
        size: (16, 12),
        ..View::default()
    };
    let rendered = render(&scene, &view, &|_| {}).unwrap();
    let legend = Legend::of_frame(&scene, &view, &rendered);
    assert_eq!(
        legend.entries[0],
        ("t = 0.81751, step 10".to_string(), None)
    );
}
