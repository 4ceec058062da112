//! AMReX HDF5 plotfiles written by the tests through the HDF5 library, object by object as
//! AMReX's `WriteMultiLevelPlotfileHDF5` writes them (`Src/Extern/HDF5/AMReX_PlotFileUtilHDF5.cpp`:
//! `WriteGenericPlotfileHeaderHDF5` for the attributes, `WriteMultiLevelPlotfileHDF5SingleDset`
//! for the data), not as the converter reads them:
//!
//! - root: `version_name`, `plotfile_type = "VanillaHDF5"` (C strings of `strlen + 1` bytes),
//!   `num_components`, `component_N`, `dim`, `time`, `finest_level`, `coordinate_system`,
//!   `num_levels` (every number a one-element array, as `CreateWriteHDF5AttrInt` and
//!   `CreateWriteHDF5AttrDouble` write them), and `Chombo_global/SpaceDim`;
//! - `level_N`: `ref_ratio` (the x ratio only, 1 on the finest level), `Vec_dx` (three reals),
//!   `dx` (x's only), `prob_lo` and `prob_hi` (three reals), `prob_domain` (a compound of six
//!   ints `lo_i` .. `hi_k`, no padding), `domain_type`, `steps`, `ngrid`, `time`, `ngrow`;
//! - `level_N` datasets: `boxes` (the same compound), `data:offsets=0` (64-bit integers,
//!   `nboxes + 1`), `boxcenter` (three ints per box), `data:datatype=0` (doubles: box after
//!   box, component after component, x fastest, valid cells only: ghosts are copied away), the
//!   boxes in the order of the MPI ranks that own them, not the box array's;
//! - or, as `WriteMultiLevelPlotfileHDF5MultiDset` writes them, one `data:datatype=J` per
//!   component J, each box's cells of that component alone, and offsets counted in cells.

use std::path::Path;

use hdf5_metno::types::{FixedAscii, TypeDescriptor};
use hdf5_metno::{File, Group, H5Type, Location};

use super::chombo::value;
// AMReX's box compound (`babox_id`) is Chombo's: six ints, no padding.
use super::chombo::writer::{raw_box, RawBox};

/// AMReX's centring compound (`center_id`).
#[derive(H5Type, Clone, Copy, Debug)]
#[repr(C)]
struct Center {
    i: i32,
    j: i32,
    k: i32,
}

/// One level: AMReX's geometry (`prob_lo`, cell sizes, domain) and its boxes, each with the
/// rank that owns it. Boxes are inclusive `[lo_i, lo_j, lo_k, hi_i, hi_j, hi_k]`.
#[derive(Clone, Debug)]
pub struct AmrexLevel {
    /// `geom[level].ProbLo()`.
    pub prob_lo: [f64; 3],
    /// `geom[level].CellSize()`.
    pub dx: [f64; 3],
    /// `geom[level].Domain()`, inclusive.
    pub domain: [i32; 6],
    /// The ratio to the next finer level per axis (`ref_ratio[level]`; unused on the finest).
    pub ratio: [i32; 3],
    /// The box array, with each box's owning rank.
    pub boxes: Vec<([i32; 6], usize)>,
}

/// A whole plotfile.
#[derive(Clone, Debug)]
pub struct AmrexHdf5 {
    /// `varnames`.
    pub comps: Vec<String>,
    /// Levels, coarsest first.
    pub levels: Vec<AmrexLevel>,
    /// `coordinate_system` (0: Cartesian).
    pub coord: i32,
    /// `domain_type` of every level (0: cell-centred).
    pub domain_type: [i32; 3],
    /// The simulation time and step.
    pub time: f64,
    /// `level_steps[0]`.
    pub step: i32,
    /// One dataset per component (`WriteMultiLevelPlotfileHDF5MultiDset`).
    pub multi_dset: bool,
    /// `compression = "ZLIB@N"`: the data chunked by 1024 values, shuffled and deflated at
    /// level N (`H5Pset_chunk`, `H5Pset_shuffle`, `H5Pset_deflate`).
    pub zlib: Option<u8>,
}

impl AmrexHdf5 {
    /// Three levels with anisotropic cells, a domain whose lower corner is not at the origin,
    /// ratios of 2 then (4, 4, 2), and boxes spread over three ranks.
    pub fn three_levels() -> Self {
        let l0 = AmrexLevel {
            prob_lo: [-1.0, 2.0, 0.5],
            dx: [0.5, 0.25, 1.0],
            domain: [0, 0, 0, 15, 11, 7],
            ratio: [2, 2, 2],
            boxes: vec![([0, 0, 0, 7, 11, 7], 1), ([8, 0, 0, 15, 11, 7], 0)],
        };
        let l1 = AmrexLevel {
            prob_lo: l0.prob_lo,
            dx: [0.25, 0.125, 0.5],
            domain: [0, 0, 0, 31, 23, 15],
            ratio: [4, 4, 2],
            boxes: vec![
                ([4, 4, 2, 11, 11, 9], 2),
                ([12, 4, 2, 19, 11, 9], 0),
                ([14, 12, 2, 21, 15, 7], 1),
            ],
        };
        let l2 = AmrexLevel {
            prob_lo: l0.prob_lo,
            dx: [0.0625, 0.03125, 0.25],
            domain: [0, 0, 0, 127, 95, 31],
            ratio: [1, 1, 1],
            boxes: vec![([20, 20, 6, 43, 35, 15], 1), ([60, 28, 6, 75, 43, 11], 0)],
        };
        AmrexHdf5 {
            comps: vec!["density".into(), "Temp".into(), "Y(OH)".into()],
            levels: vec![l0, l1, l2],
            coord: 0,
            domain_type: [0; 3],
            time: 0.00125,
            step: 40,
            multi_dset: false,
            zlib: None,
        }
    }

    /// Level `l`'s boxes in the order the file stores them: grouped by owning rank, ranks
    /// ascending, each rank's boxes in box-array order (`gridMap` in the writer).
    pub fn stored_boxes(&self, l: usize) -> Vec<[i32; 6]> {
        let mut boxes = self.levels[l].boxes.clone();
        boxes.sort_by_key(|&(_, rank)| rank);
        boxes.into_iter().map(|(b, _)| b).collect()
    }
}

fn ints(loc: &Location, name: &str, v: &[i32]) -> hdf5_metno::Result<()> {
    loc.new_attr::<i32>().shape(v.len()).create(name)?.write(v)
}

fn doubles(loc: &Location, name: &str, v: &[f64]) -> hdf5_metno::Result<()> {
    loc.new_attr::<f64>().shape(v.len()).create(name)?.write(v)
}

/// A scalar C string of `strlen + 1` bytes (`CreateWriteHDF5AttrString`).
fn string(loc: &Location, name: &str, v: &str) -> hdf5_metno::Result<()> {
    let a = loc
        .new_attr_builder()
        .empty_as(TypeDescriptor::FixedAscii(v.len() + 1))
        .create(name)?;
    a.write_scalar(&FixedAscii::<256>::from_ascii(v).map_err(|e| e.to_string())?)
}

/// Writes `d` to `path` with every value `value(level, comp, cell)`.
pub fn write(path: &Path, d: &AmrexHdf5) -> hdf5_metno::Result<()> {
    let file = File::create(path)?;
    let root: &Group = &file;
    let finest = d.levels.len() as i32 - 1;
    string(root, "version_name", "HyperCLaw-V1.1")?;
    string(root, "plotfile_type", "VanillaHDF5")?;
    ints(root, "num_components", &[d.comps.len() as i32])?;
    for (i, name) in d.comps.iter().enumerate() {
        string(root, &format!("component_{i}"), name)?;
    }
    ints(root, "dim", &[3])?;
    doubles(root, "time", &[d.time])?;
    ints(root, "finest_level", &[finest])?;
    ints(root, "coordinate_system", &[d.coord])?;
    ints(root, "num_levels", &[d.levels.len() as i32])?;
    let global = root.create_group("Chombo_global")?;
    ints(&global, "SpaceDim", &[3])?;
    let nc = d.comps.len();
    for (l, lev) in d.levels.iter().enumerate() {
        let grp = root.create_group(&format!("level_{l}"))?;
        let ratio = if l as i32 == finest { 1 } else { lev.ratio[0] };
        ints(&grp, "ref_ratio", &[ratio])?;
        doubles(&grp, "Vec_dx", &lev.dx)?;
        doubles(&grp, "dx", &[lev.dx[0]])?;
        let extent = [0, 1, 2].map(|a| f64::from(lev.domain[a + 3] - lev.domain[a] + 1));
        let hi: Vec<f64> = (0..3)
            .map(|a| lev.prob_lo[a] + extent[a] * lev.dx[a])
            .collect();
        doubles(&grp, "prob_lo", &lev.prob_lo)?;
        doubles(&grp, "prob_hi", &hi)?;
        grp.new_attr::<RawBox>()
            .create("prob_domain")?
            .write_scalar(&raw_box(lev.domain))?;
        ints(&grp, "domain_type", &d.domain_type)?;
        ints(&grp, "steps", &[d.step])?;
        ints(&grp, "ngrid", &[lev.boxes.len() as i32])?;
        doubles(&grp, "time", &[d.time])?;
        ints(&grp, "ngrow", &[0])?;

        let sorted = d.stored_boxes(l);
        let boxes: Vec<RawBox> = sorted.iter().map(|&b| raw_box(b)).collect();
        grp.new_dataset_builder()
            .with_data(&boxes)
            .create("boxes")?;
        // Component `c` of box `b`, x fastest.
        let cells = |b: &[i32; 6], c: usize, out: &mut Vec<f64>| {
            for z in b[2]..=b[5] {
                for y in b[1]..=b[4] {
                    for x in b[0]..=b[3] {
                        out.push(value(l, c, [x, y, z].map(i64::from)));
                    }
                }
            }
        };
        let mut offsets: Vec<i64> = vec![0];
        let mut datasets: Vec<Vec<f64>> = vec![Vec::new(); if d.multi_dset { nc } else { 1 }];
        for b in &sorted {
            for c in 0..nc {
                match d.multi_dset {
                    true => cells(b, c, &mut datasets[c]),
                    false => cells(b, c, &mut datasets[0]),
                }
            }
            offsets.push(datasets[0].len() as i64);
        }
        grp.new_dataset_builder()
            .with_data(&offsets)
            .create("data:offsets=0")?;
        let centers: Vec<Center> = sorted.iter().map(|_| Center { i: 0, j: 0, k: 0 }).collect();
        grp.new_dataset_builder()
            .with_data(&centers)
            .create("boxcenter")?;
        for (j, data) in datasets.iter().enumerate() {
            let name = format!("data:datatype={j}");
            match d.zlib {
                // The writer's chunk of 1024, cut to the data's length when that is shorter.
                Some(level) => grp
                    .new_dataset_builder()
                    .chunk(1024.min(data.len()))
                    .shuffle()
                    .deflate(level)
                    .with_data(data)
                    .create(name.as_str())?,
                None => grp
                    .new_dataset_builder()
                    .with_data(data)
                    .create(name.as_str())?,
            };
        }
    }
    file.close()?;
    Ok(())
}
