//! Chombo plotfiles written by the tests themselves through the HDF5 library, in the layout
//! Chombo's `WriteAMRHierarchyHDF5` produces, plus knobs that break them on purpose.

pub mod check;
pub mod writer;

/// One level of a fixture: boxes in Chombo's inclusive notation `[lo_i, lo_j, lo_k, hi_i, hi_j, hi_k]`.
#[derive(Clone, Debug)]
pub struct LevelDesc {
    /// Cell size.
    pub dx: f64,
    /// Ratio to the next finer level (1 on the finest).
    pub ref_ratio: i32,
    /// The problem domain, inclusive.
    pub domain: [i32; 6],
    /// The boxes, inclusive.
    pub boxes: Vec<[i32; 6]>,
}

/// A whole fixture file and the ways to break it.
#[derive(Clone, Debug)]
pub struct Desc {
    /// Component names.
    pub comps: Vec<String>,
    /// Levels, coarsest first.
    pub levels: Vec<LevelDesc>,
    /// Ghost layers written around every box.
    pub ghost: [i32; 3],
    /// Store doubles (else floats).
    pub f64: bool,
    /// `Chombo_global/SpaceDim`.
    pub space_dim: i32,
    /// Root attributes not to write.
    pub omit_root: Vec<String>,
    /// (level, attribute) pairs not to write.
    pub omit_level: Vec<(usize, String)>,
    /// Drop this many values from the end of a level's data.
    pub truncate_data: Option<(usize, usize)>,
    /// Overwrite one valid cell: (level, box, component, cell, value).
    pub poison: Option<(usize, usize, usize, [i64; 3], f64)>,
    /// Store the components as these `LevelData` variables (name, component count; the
    /// components of `comps` in order), as checkpoint writers that call `write(handle, data,
    /// NAME)` once per variable do; empty stores every component in `data`.
    pub per_variable: Vec<(String, usize)>,
    /// Write boxes only: no `num_levels`, no data (what Chombo's `meshRefineTest` leaves).
    pub boxes_only: bool,
    /// Declare this level's `boxes` with 2³³ entries and write none (HDF5 allocates lazily).
    pub huge_boxes: Option<usize>,
    /// Declare this level's data at its full length but write none of it.
    pub unwritten_data: Option<usize>,
    /// Add the root attributes only `AMR::writeCheckpointFile` writes (`regrid_interval_N`).
    pub checkpoint_marker: bool,
}

impl Desc {
    /// Three levels (ratios 2 then 4), partial refinement, anisotropic ghost layers, three
    /// components; a non-cubic domain.
    pub fn three_levels(f64: bool) -> Self {
        let l0 = LevelDesc {
            dx: 0.5,
            ref_ratio: 2,
            domain: [0, 0, 0, 15, 11, 7],
            boxes: vec![[0, 0, 0, 7, 11, 7], [8, 0, 0, 15, 11, 7]],
        };
        let l1 = LevelDesc {
            dx: 0.25,
            ref_ratio: 4,
            domain: [0, 0, 0, 31, 23, 15],
            boxes: vec![[4, 4, 2, 13, 11, 9], [14, 6, 2, 21, 13, 7]],
        };
        let l2 = LevelDesc {
            dx: 0.0625,
            ref_ratio: 1,
            domain: [0, 0, 0, 127, 95, 63],
            boxes: vec![[20, 20, 10, 43, 35, 29], [60, 28, 10, 75, 43, 21]],
        };
        Desc {
            comps: vec!["density".into(), "phi".into(), "chi".into()],
            levels: vec![l0, l1, l2],
            ghost: [2, 1, 3],
            f64,
            space_dim: 3,
            omit_root: Vec::new(),
            omit_level: Vec::new(),
            truncate_data: None,
            poison: None,
            per_variable: Vec::new(),
            boxes_only: false,
            checkpoint_marker: false,
            huge_boxes: None,
            unwritten_data: None,
        }
    }
}

impl Desc {
    /// A checkpoint whose level data is one `LevelData` per variable: a scalar `density` and a
    /// 3-component `mom` whose components the root lists as `xmom`, `ymom`, `zmom`; the root
    /// carries `AMR::writeCheckpointFile`'s attributes.
    pub fn per_variable_checkpoint() -> Self {
        let mut d = Desc::three_levels(true);
        d.comps = vec![
            "density".into(),
            "xmom".into(),
            "ymom".into(),
            "zmom".into(),
        ];
        d.per_variable = vec![("density".into(), 1), ("mom".into(), 3)];
        d.checkpoint_marker = true;
        d
    }
}

/// The value stored at a valid cell: smooth, different per level and component, and (as f64)
/// not exactly representable in f32, so that rounding is exercised.
pub fn value(level: usize, comp: usize, p: [i64; 3]) -> f64 {
    let [x, y, z] = p.map(|v| v as f64);
    (comp as f64 + 1.0) * ((0.37 * x + 1.13 * y - 0.71 * z).sin() * 10.0 + level as f64 * 100.0)
        + 1.0 / 3.0
}

/// The value stored at a ghost cell: far from every valid value, so a ghost that leaks into the
/// output fails the comparison.
pub fn ghost_value(level: usize, comp: usize, p: [i64; 3]) -> f64 {
    -1.0e6 - value(level, comp, p)
}
