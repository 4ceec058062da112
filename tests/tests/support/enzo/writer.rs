//! Writes an Enzo dataset as Enzo does: the parameter file's placing lines
//! (`WriteParameterFile.C`), the hierarchy's grid blocks and `Pointer:` lines in the
//! depth-first order of `Group_WriteDataHierarchy.C` (a grid, its `NextGridThisLevel` pointer,
//! that sibling's whole subtree, then its `NextGridNextLevel` pointer and its children), and
//! each field as a 3-D dataset with reversed axes (`OutDims[GridRank-dim-1] = ActiveDim[dim]`,
//! `Grid_Group_WriteGrid.C`) in `/GridNNNNNNNN` of `NAME.cpu0000`, or at the root of
//! `NAME.gridNNNN` for the one-file-per-grid layout. `BaryonFileName` is an absolute path of
//! another machine, as in real datasets.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use hdf5_metno::File;

use super::{ghost_value, value};

/// One grid and its children, in cells of its level (half-open).
#[derive(Clone, Debug)]
pub struct GridDesc {
    /// Lower corner of the active cells.
    pub lo: [i64; 3],
    /// Upper corner (exclusive).
    pub hi: [i64; 3],
    /// Grids of the next level inside this one.
    pub children: Vec<GridDesc>,
}

/// A whole dataset and the ways to break it.
#[derive(Clone, Debug)]
pub struct Desc {
    /// `TopGridRank`.
    pub rank: i64,
    /// `TopGridDimensions`.
    pub top: [i64; 3],
    /// `RefineBy`.
    pub refine_by: i64,
    /// `DomainLeftEdge`.
    pub left: [f64; 3],
    /// `DomainRightEdge`.
    pub right: [f64; 3],
    /// Field names.
    pub fields: Vec<String>,
    /// Ghost zones per side (`GridStartIndex`); written to the datasets when `write_ghosts`.
    pub ghost: [i64; 3],
    /// Write whole `GridDimension` arrays (Enzo's `WriteGhostZones`), else active cells only.
    pub write_ghosts: bool,
    /// Store doubles (else floats).
    pub f64: bool,
    /// One `.cpu0000` file with a group per grid (else one file per grid).
    pub packed: bool,
    /// The level-0 grids.
    pub roots: Vec<GridDesc>,
    /// Shift this grid's (numbered from 1) `GridLeftEdge` and `GridRightEdge` by this many of
    /// its cells along x.
    pub shift: Option<(usize, f64)>,
    /// Leave `RefineBy` out of the parameter file.
    pub omit_refine_by: bool,
    /// Declare this grid's (numbered from 1) datasets at full size but write no data (HDF5
    /// allocates lazily, so the file stays small).
    pub unwritten: Option<usize>,
}

impl Desc {
    /// Three levels, `RefineBy` 2, a non-cubic domain away from the origin, two grids on
    /// level 1 (one with a child), ghost zones written, doubles, packed.
    pub fn three_levels() -> Self {
        Desc {
            rank: 3,
            top: [8, 6, 4],
            refine_by: 2,
            left: [-1.0, 0.0, 2.0],
            right: [1.0, 1.5, 3.0],
            fields: vec!["Density".into(), "Temperature".into(), "x-velocity".into()],
            ghost: [3, 3, 3],
            write_ghosts: true,
            f64: true,
            packed: true,
            roots: vec![GridDesc {
                lo: [0, 0, 0],
                hi: [8, 6, 4],
                children: vec![
                    GridDesc {
                        lo: [2, 2, 0],
                        hi: [8, 10, 6],
                        children: vec![GridDesc {
                            lo: [6, 6, 2],
                            hi: [14, 16, 10],
                            children: vec![],
                        }],
                    },
                    GridDesc {
                        lo: [10, 0, 2],
                        hi: [16, 4, 8],
                        children: vec![],
                    },
                ],
            }],
            shift: None,
            omit_refine_by: false,
            unwritten: None,
        }
    }
}

/// Writes `d` into `dir` as dataset `NAME`; returns the parameter file's path.
pub fn write(dir: &Path, name: &str, d: &Desc) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let params = dir.join(name);
    let mut p = String::new();
    writeln!(p, "InitialCycleNumber  = 10").unwrap();
    writeln!(p, "TopGridRank         = {}", d.rank).unwrap();
    writeln!(
        p,
        "TopGridDimensions   = {} {} {} ",
        d.top[0], d.top[1], d.top[2]
    )
    .unwrap();
    if !d.omit_refine_by {
        writeln!(p, "RefineBy               = {}", d.refine_by).unwrap();
    }
    writeln!(
        p,
        "DomainLeftEdge         = {} {} {} ",
        d.left[0], d.left[1], d.left[2]
    )
    .unwrap();
    writeln!(
        p,
        "DomainRightEdge        = {} {} {} ",
        d.right[0], d.right[1], d.right[2]
    )
    .unwrap();
    for (i, f) in d.fields.iter().enumerate() {
        writeln!(p, "DataLabel[{i}]              = {f}").unwrap();
    }
    std::fs::write(&params, p).unwrap();

    let packed = d
        .packed
        .then(|| File::create(dir.join(format!("{name}.cpu0000"))).unwrap());
    let mut h = String::new();
    let mut id = 1;
    let mut w = Writer {
        d,
        dir,
        name,
        packed: packed.as_ref(),
        h: &mut h,
    };
    w.grids(&d.roots, 0, 0, &mut id);
    std::fs::write(dir.join(format!("{name}.hierarchy")), h).unwrap();
    params
}

struct Writer<'a> {
    d: &'a Desc,
    dir: &'a Path,
    name: &'a str,
    packed: Option<&'a File>,
    h: &'a mut String,
}

impl Writer<'_> {
    /// Writes `list[k]`, then (through its `NextGridThisLevel` pointer) its later siblings, then
    /// its children: `Group_WriteDataHierarchy`'s recursion.
    fn grids(&mut self, list: &[GridDesc], k: usize, level: usize, id: &mut usize) {
        let me = *id;
        let g = &list[k];
        self.block(g, level, me);
        let this = if k + 1 < list.len() { *id + 1 } else { 0 };
        writeln!(self.h, "Pointer: Grid[{me}]->NextGridThisLevel = {this}").unwrap();
        if this != 0 {
            *id += 1;
            self.grids(list, k + 1, level, id);
        }
        let next = if g.children.is_empty() { 0 } else { *id + 1 };
        writeln!(self.h, "Pointer: Grid[{me}]->NextGridNextLevel = {next}").unwrap();
        if next != 0 {
            *id += 1;
            self.grids(&g.children, 0, level + 1, id);
        }
    }

    fn block(&mut self, g: &GridDesc, level: usize, id: usize) {
        let d = self.d;
        let scale = d.refine_by.pow(level as u32);
        let dx: Vec<f64> = (0..3)
            .map(|a| (d.right[a] - d.left[a]) / (d.top[a] * scale) as f64)
            .collect();
        let shift = match d.shift {
            Some((s, by)) if s == id => by,
            _ => 0.0,
        };
        let edge = |c: [i64; 3]| -> String {
            (0..3)
                .map(|a| {
                    let v =
                        d.left[a] + c[a] as f64 * dx[a] + if a == 0 { shift * dx[0] } else { 0.0 };
                    format!("{v:.16}")
                })
                .collect::<Vec<_>>()
                .join(" ")
        };
        let active: Vec<i64> = (0..3).map(|a| g.hi[a] - g.lo[a]).collect();
        let dims: Vec<i64> = (0..3).map(|a| active[a] + 2 * d.ghost[a]).collect();
        let ints = |v: &[i64]| {
            v.iter()
                .map(|x| x.to_string())
                .collect::<Vec<_>>()
                .join(" ")
        };
        let file = if d.packed {
            format!("{}.cpu0000", self.name)
        } else {
            format!("{}.grid{id:04}", self.name)
        };
        let h = &mut *self.h;
        writeln!(h, "\nGrid = {id}").unwrap();
        writeln!(h, "Task              = 0").unwrap();
        writeln!(h, "GridRank          = {}", d.rank).unwrap();
        writeln!(h, "GridDimension     = {} ", ints(&dims)).unwrap();
        writeln!(h, "GridStartIndex    = {} ", ints(&d.ghost)).unwrap();
        let end: Vec<i64> = (0..3).map(|a| d.ghost[a] + active[a] - 1).collect();
        writeln!(h, "GridEndIndex      = {} ", ints(&end)).unwrap();
        writeln!(h, "GridLeftEdge      = {} ", edge(g.lo)).unwrap();
        writeln!(h, "GridRightEdge     = {} ", edge(g.hi)).unwrap();
        writeln!(h, "Time              = 0.8175131711911701").unwrap();
        writeln!(h, "SubgridsAreStatic = 0").unwrap();
        writeln!(h, "NumberOfBaryonFields = {}", d.fields.len()).unwrap();
        writeln!(
            h,
            "FieldType = {} ",
            ints(&(0..d.fields.len() as i64).collect::<Vec<_>>())
        )
        .unwrap();
        writeln!(h, "BaryonFileName = /scratch/elsewhere/run/DD0010/{file}").unwrap();
        writeln!(h, "CourantSafetyNumber    = 0.500000").unwrap();
        writeln!(h, "NumberOfParticles   = 2").unwrap();
        writeln!(h, "ParticleFileName = /scratch/elsewhere/run/DD0010/{file}").unwrap();
        writeln!(h, "GravityBoundaryType = 0").unwrap();

        let own;
        let group = match self.packed {
            Some(f) => f.create_group(&format!("Grid{id:08}")).unwrap(),
            None => {
                own = File::create(self.dir.join(&file)).unwrap();
                own.group("/").unwrap()
            }
        };
        let (lo, ext) = if d.write_ghosts {
            (
                (0..3).map(|a| g.lo[a] - d.ghost[a]).collect::<Vec<_>>(),
                dims.clone(),
            )
        } else {
            (g.lo.to_vec(), active.clone())
        };
        for (f, name) in d.fields.iter().enumerate() {
            let mut vals = Vec::new();
            for z in 0..ext[2] {
                for y in 0..ext[1] {
                    for x in 0..ext[0] {
                        let c = [lo[0] + x, lo[1] + y, lo[2] + z];
                        let inside = (0..3).all(|a| c[a] >= g.lo[a] && c[a] < g.hi[a]);
                        vals.push(if inside {
                            value(level, f, c)
                        } else {
                            ghost_value()
                        });
                    }
                }
            }
            let shape = [ext[2] as usize, ext[1] as usize, ext[0] as usize];
            if d.unwritten == Some(id) {
                group
                    .new_dataset::<f64>()
                    .shape(shape)
                    .create(name.as_str())
                    .unwrap();
            } else if d.f64 {
                dataset(&group, name, shape, vals);
            } else {
                dataset(
                    &group,
                    name,
                    shape,
                    vals.iter().map(|&v| v as f32).collect(),
                );
            }
        }
        group
            .new_dataset_builder()
            .with_data(&[0.5f64, 0.25])
            .create("particle_position_x")
            .unwrap();
    }
}

/// Writes `vals` as the 3-D dataset `name` of shape `shape` (z, y, x) in `group`.
fn dataset<T: hdf5_metno::H5Type>(
    group: &hdf5_metno::Group,
    name: &str,
    shape: [usize; 3],
    vals: Vec<T>,
) {
    let a = ndarray::Array3::from_shape_vec(shape, vals).unwrap();
    group
        .new_dataset_builder()
        .with_data(&a)
        .create(name)
        .unwrap();
}
