//! An opened Enzo dataset: the parameter file and the hierarchy, every grid placed on its
//! level's integer cell grid and checked to nest inside its parent, the field names read from
//! the first grid's data. Opening reads no cell data; [`super::reader`] streams it.

use std::path::{Path, PathBuf};

use amr_format::hierarchy::MAX_LEVELS;
use amr_format::{IBox, LevelSpec};
use hdf5_metno::types::{FloatSize, TypeDescriptor};
use hdf5_metno::{File, Group};

use super::error::{EnzoError, Result};
use super::hierarchy::{read_hierarchy, GridEntry};
use super::parameters::{read_parameters, Parameters};
use super::reader::{field_dataset, stream, OpenFile};
use crate::hierarchy_to_amrk::{AmrSource, Slab};
use amr_format::progress::Progress;

/// How far (in cells of its level) a grid edge may sit from the level's cell grid: Enzo prints
/// edges with `%.16g` (or 8 digits in old single-precision builds), well inside this.
pub const EDGE_TOLERANCE: f64 = 0.01;

/// Largest `GridDimension` entry accepted.
const MAX_GRID_DIM: i64 = 1 << 31;

/// One grid, placed.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// The grid's number in the hierarchy (from 1).
    pub id: usize,
    /// The grid's level.
    pub level: usize,
    /// The grid's index among its level's boxes.
    pub index: usize,
    /// The active cells, in the level's index space (cell 0 at `DomainLeftEdge`), half-open.
    pub valid: IBox,
    /// `GridDimension`: cells per axis with ghost zones.
    pub dims: [i64; 3],
    /// `GridStartIndex`: ghost zones below the active cells.
    pub start: [i64; 3],
    /// The HDF5 file holding the grid's data, resolved beside the hierarchy.
    pub file: PathBuf,
}

impl Grid {
    /// The grid's group in its data file (`/GridNNNNNNNN` in packed files).
    pub fn group_name(&self) -> String {
        format!("Grid{:08}", self.id)
    }

    /// The group holding the grid's datasets: its `GridNNNNNNNN` group (packed layout) or the
    /// file's root (one file per grid).
    pub fn group(&self, file: &File) -> Result<Group> {
        let name = self.group_name();
        let g = if file.link_exists(&name) {
            file.group(&name)
        } else {
            file.group("/")
        };
        g.map_err(|e| {
            EnzoError::hdf5(
                &self.file,
                format!("opening the group of grid {}", self.id),
                e,
            )
        })
    }
}

/// An Enzo dataset whose metadata has been read and checked.
#[derive(Clone, Debug)]
pub struct Dataset {
    /// The parameters that place the grids.
    pub params: Parameters,
    /// The hierarchy file.
    pub hierarchy: PathBuf,
    /// Field names: the first grid's three-dimensional datasets, in the file's order.
    pub fields: Vec<String>,
    /// Bytes per stored value (4 or 8), from the first field of the first grid.
    pub value_bytes: u64,
    /// Every grid, in hierarchy order.
    pub grids: Vec<Grid>,
    /// Each level's boxes (the grids' active cells), in hierarchy order.
    pub boxes: Vec<Vec<IBox>>,
    /// Each level's cells per axis over the domain.
    pub level_dims: Vec<[i64; 3]>,
}

impl Dataset {
    /// Opens the dataset whose parameter file is `params` and hierarchy `hierarchy`.
    pub fn open(params: &Path, hierarchy: &Path) -> Result<Dataset> {
        let params = read_parameters(params)?;
        let entries = read_hierarchy(hierarchy)?;
        let dir = hierarchy.parent().unwrap_or(Path::new("."));
        let nlevels = entries.iter().map(|g| g.level).max().unwrap_or(0) + 1;
        if nlevels > MAX_LEVELS {
            return Err(EnzoError::unsupported(
                hierarchy,
                format!("{nlevels} levels; .amrk holds at most {MAX_LEVELS}"),
            ));
        }
        let mut grids: Vec<Grid> = Vec::with_capacity(entries.len());
        let mut boxes: Vec<Vec<IBox>> = vec![Vec::new(); nlevels];
        for e in &entries {
            let valid = place(&params, hierarchy, e)?;
            let file = data_file(hierarchy, dir, e)?;
            let index = boxes[e.level].len();
            boxes[e.level].push(valid);
            grids.push(Grid {
                id: e.id,
                level: e.level,
                index,
                valid,
                dims: e.dims.unwrap_or_default(),
                start: e.start.unwrap_or_default(),
                file,
            });
        }
        for (e, g) in entries.iter().zip(&grids) {
            if let Some(p) = e.parent {
                check_nesting(&params, hierarchy, &grids[p], g)?;
            }
        }
        let (fields, value_bytes) = read_fields(&grids[0])?;
        check_stored(&grids, &fields[0])?;
        let level_dims = (0..nlevels)
            .map(|l| level_dims(&params, l).unwrap_or([1; 3]))
            .collect();
        Ok(Dataset {
            level_dims,
            params,
            hierarchy: hierarchy.to_path_buf(),
            fields,
            value_bytes,
            grids,
            boxes,
        })
    }
}

/// The cells per axis of `level` (`TopGridDimensions × RefineBy^level`), if representable.
fn level_dims(params: &Parameters, level: usize) -> Option<[i64; 3]> {
    let scale = params.refine_by.checked_pow(u32::try_from(level).ok()?)?;
    let d = params.top_dims.map(|d| d.checked_mul(scale));
    Some([d[0]?, d[1]?, d[2]?])
}

/// Places grid `e` on its level's cell grid: its edges, divided by the level's cell size, must
/// round to whole cells, span as many cells as its start and end indices say, and lie inside
/// the domain.
fn place(params: &Parameters, hierarchy: &Path, e: &GridEntry) -> Result<IBox> {
    let bad = |msg: String| {
        EnzoError::invalid(hierarchy, format!("grid {} (line {}): {msg}", e.id, e.line))
    };
    let missing = |what: &str| bad(format!("no {what} line"));
    let rank = e.rank.ok_or_else(|| missing("GridRank"))?;
    if rank != 3 {
        return Err(EnzoError::unsupported(
            hierarchy,
            format!(
                "grid {} has GridRank {rank}; only 3D datasets can be converted",
                e.id
            ),
        ));
    }
    let dims = e.dims.ok_or_else(|| missing("GridDimension"))?;
    let start = e.start.ok_or_else(|| missing("GridStartIndex"))?;
    let end = e.end.ok_or_else(|| missing("GridEndIndex"))?;
    let left = e.left.ok_or_else(|| missing("GridLeftEdge"))?;
    let right = e.right.ok_or_else(|| missing("GridRightEdge"))?;
    for a in 0..3 {
        if !(1..=MAX_GRID_DIM).contains(&dims[a])
            || start[a] < 0
            || end[a] < start[a]
            || end[a] >= dims[a]
        {
            return Err(bad(format!(
                "GridDimension {dims:?}, GridStartIndex {start:?}, GridEndIndex {end:?} do not \
                 describe active cells inside the stored ones"
            )));
        }
    }
    let ldims = level_dims(params, e.level).ok_or_else(|| {
        bad(format!(
            "level {} is too deep for the root grid's size",
            e.level
        ))
    })?;
    let mut lo = [0i64; 3];
    let mut hi = [0i64; 3];
    for a in 0..3 {
        let dx = (params.right[a] - params.left[a]) / ldims[a] as f64;
        for (edge, name, out) in [
            (left[a], "GridLeftEdge", &mut lo[a]),
            (right[a], "GridRightEdge", &mut hi[a]),
        ] {
            let cells = (edge - params.left[a]) / dx;
            let whole = cells.round();
            if !whole.is_finite() || (cells - whole).abs() > EDGE_TOLERANCE {
                return Err(bad(format!(
                    "{name} {edge} on axis {a} lies {:.3} cells off level {}'s cell grid (cell size {dx})",
                    cells - whole,
                    e.level
                )));
            }
            *out = whole as i64;
        }
        let active = end[a] - start[a] + 1;
        if hi[a] - lo[a] != active {
            return Err(bad(format!(
                "its edges span {} cells of level {} on axis {a}, but GridStartIndex..GridEndIndex give {active}",
                hi[a] - lo[a],
                e.level
            )));
        }
        if lo[a] < 0 || hi[a] > ldims[a] {
            return Err(bad(format!(
                "cells {lo:?}..{hi:?} of level {} lie outside the domain's {ldims:?}",
                e.level
            )));
        }
    }
    Ok(IBox::new(lo, hi))
}

/// The grid's data file: the file name of `BaryonFileName`, beside the hierarchy (Enzo writes
/// absolute paths of the machine that ran the simulation).
fn data_file(hierarchy: &Path, dir: &Path, e: &GridEntry) -> Result<PathBuf> {
    if e.nfields.unwrap_or(0) <= 0 {
        return Err(EnzoError::unsupported(
            hierarchy,
            format!(
                "grid {} has no baryon fields (NumberOfBaryonFields = {})",
                e.id,
                e.nfields.unwrap_or(0)
            ),
        ));
    }
    let written = e.file.as_deref().ok_or_else(|| {
        EnzoError::invalid(
            hierarchy,
            format!("grid {} (line {}): no BaryonFileName line", e.id, e.line),
        )
    })?;
    let name = Path::new(written).file_name().ok_or_else(|| {
        EnzoError::invalid(
            hierarchy,
            format!("grid {}: BaryonFileName '{written}' names no file", e.id),
        )
    })?;
    Ok(dir.join(name))
}

/// Checks that `child` lies inside `parent` refined by `RefineBy`.
fn check_nesting(params: &Parameters, hierarchy: &Path, parent: &Grid, child: &Grid) -> Result<()> {
    let r = params.refine_by;
    let inside = parent
        .valid
        .refine([r; 3])
        .is_some_and(|p| p.contains_box(&child.valid));
    if !inside {
        return Err(EnzoError::invalid(
            hierarchy,
            format!(
                "grid {} (level {}, cells {:?}..{:?}) is not properly nested: it leaves its parent grid {} (cells {:?}..{:?} of level {}, refined by {r})",
                child.id, child.level, child.valid.lo, child.valid.hi, parent.id, parent.valid.lo, parent.valid.hi, parent.level
            ),
        ));
    }
    Ok(())
}

/// The field names (three-dimensional datasets of `grid`'s group, in the file's order) and the
/// bytes per value of the first.
fn read_fields(grid: &Grid) -> Result<(Vec<String>, u64)> {
    let path = &grid.file;
    let mut files = OpenFile::default();
    let group = grid.group(files.get(path)?)?;
    let names = group.member_names().map_err(|e| {
        EnzoError::hdf5(path, format!("listing the datasets of grid {}", grid.id), e)
    })?;
    let mut fields = Vec::new();
    let mut bytes = None;
    for name in names {
        let Ok(ds) = group.dataset(&name) else {
            continue;
        };
        if ds.ndim() != 3 {
            continue;
        }
        if bytes.is_none() {
            bytes = Some(match ds.dtype().and_then(|t| t.to_descriptor()) {
                Ok(TypeDescriptor::Float(FloatSize::U8)) => 8,
                _ => 4,
            });
        }
        fields.push(name);
    }
    match bytes {
        Some(b) => Ok((fields, b)),
        None => Err(EnzoError::invalid(
            path,
            format!(
                "grid {} holds no three-dimensional dataset: no fields to convert",
                grid.id
            ),
        )),
    }
}

/// How much smaller than its values a compressed dataset may be (deflate's best ratio is about
/// 1000:1).
const MAX_COMPRESSION: u64 = 1100;

/// Checks, before anything is sized from the hierarchy, that every grid's `field` dataset has
/// the grid's shape and that its stored bytes can hold the values the hierarchy promises: a
/// declared dataset costs nothing on disk, so this is what bounds the bricks and slabs sized
/// from a grid's dimensions by the files' real size.
fn check_stored(grids: &[Grid], field: &str) -> Result<()> {
    let mut files = OpenFile::default();
    for grid in grids {
        let (data, stored) = field_dataset(grid, files.get(&grid.file)?, field)?;
        let need = stored
            .num_cells()
            .and_then(|c| c.checked_mul(data.dtype().map(|t| t.size() as u64).unwrap_or(1)))
            .unwrap_or(u64::MAX);
        let have = data.storage_size();
        let room = if data.filters().is_empty() {
            have
        } else {
            have.saturating_mul(MAX_COMPRESSION)
        };
        if room < need {
            return Err(EnzoError::invalid(
                &grid.file,
                format!(
                    "grid {}'s '{field}' stores {have} bytes, but its {} cells need {need}: the \
                     data was never written or the file is damaged",
                    grid.id,
                    stored.num_cells().unwrap_or(u64::MAX)
                ),
            ));
        }
    }
    Ok(())
}

impl AmrSource for Dataset {
    type Error = EnzoError;

    fn path(&self) -> &Path {
        &self.hierarchy
    }

    fn fields(&self) -> &[String] {
        &self.fields
    }

    fn simulation(&self) -> (Option<f64>, Option<i64>) {
        (self.params.time, self.params.cycle)
    }

    /// Cell 0 of every level sits at `DomainLeftEdge`; level `l` has `TopGridDimensions ×
    /// RefineBy^l` cells over the domain.
    fn level_specs(&self) -> Vec<LevelSpec> {
        let n = self.boxes.len();
        (0..n)
            .map(|l| {
                let dims = self.level_dims[l];
                let p = &self.params;
                LevelSpec {
                    cell_size: [0, 1, 2].map(|a| (p.right[a] - p.left[a]) / dims[a] as f64),
                    origin: p.left,
                    ratio_to_next: if l + 1 < n {
                        [p.refine_by as u32; 3]
                    } else {
                        [1; 3]
                    },
                    domain: IBox::new([0; 3], dims),
                }
            })
            .collect()
    }

    fn boxes(&self) -> Vec<&[IBox]> {
        self.boxes.iter().map(Vec::as_slice).collect()
    }

    fn stream_order(&self) -> Vec<(usize, usize)> {
        super::reader::grid_order(self)
            .into_iter()
            .map(|g| (g.level, g.index))
            .collect()
    }

    fn stream(
        &self,
        comps: &[usize],
        chunk: i64,
        progress: &dyn Progress,
        sink: &mut dyn FnMut(Slab) -> Result<()>,
    ) -> Result<u64> {
        stream(self, comps, chunk, progress, sink)
    }
}
