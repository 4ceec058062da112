//! Streams an Enzo dataset's cell data: grid by grid (each data file opened once), field by
//! field, in slabs of at most `chunk` rows and layers read with one hyperslab each, ghost zones
//! left out of the selection, values checked and converted to `f32`.
//!
//! Enzo writes each field of a grid as a 3-D dataset in C order with the axes reversed
//! (`OutDims[GridRank-dim-1] = ActiveDim[dim]` in `Grid_Group_WriteGrid.C`): dataset shape
//! `[nz, ny, nx]`, x fastest. The shape is the active cells, or all of `GridDimension` when the
//! run wrote ghost zones.

use amr_format::IBox;
use hdf5_metno::types::{FloatSize, TypeDescriptor};
use hdf5_metno::{Dataset as H5Dataset, File, H5Type, Hyperslab, Selection, SliceOrIndex};

use super::dataset::{Dataset, Grid};
use super::error::{EnzoError, Result};
use crate::finite::ToFiniteF32;
use crate::hierarchy_to_amrk::{slab_ranges, Slab};
use amr_format::progress::Progress;

/// The grids in the order [`stream`] reads them: by data file, then by grid number, so that
/// each file is opened once.
pub fn grid_order(ds: &Dataset) -> Vec<&Grid> {
    let mut order: Vec<&Grid> = ds.grids.iter().collect();
    order.sort_by(|a, b| a.file.cmp(&b.file).then(a.id.cmp(&b.id)));
    order
}

/// Streams the fields `comps` (indices into `ds.fields`) of every grid to `sink`, in slabs of
/// at most `chunk` rows and layers. Returns the bytes of cell data read.
pub fn stream(
    ds: &Dataset,
    comps: &[usize],
    chunk: i64,
    progress: &dyn Progress,
    sink: &mut dyn FnMut(Slab) -> Result<()>,
) -> Result<u64> {
    let cells: u64 = ds
        .grids
        .iter()
        .map(|g| g.valid.num_cells().unwrap_or(0))
        .sum();
    progress.set_total(cells * comps.len() as u64 * ds.value_bytes);
    let mut files = OpenFile::default();
    let mut out = Vec::new();
    let mut bytes_read = 0u64;
    for grid in grid_order(ds) {
        let file = files.get(&grid.file)?;
        for (f, &c) in comps.iter().enumerate() {
            let name = &ds.fields[c];
            let (data, stored) = field_dataset(grid, file, name)?;
            let wide = match data.dtype().and_then(|t| t.to_descriptor()) {
                Ok(TypeDescriptor::Float(FloatSize::U4)) => false,
                Ok(TypeDescriptor::Float(FloatSize::U8)) => true,
                Ok(d) => {
                    return Err(EnzoError::unsupported(
                        &grid.file,
                        format!(
                            "grid {}'s '{name}' holds {d}; only 32- and 64-bit floats are read",
                            grid.id
                        ),
                    ))
                }
                Err(e) => {
                    return Err(EnzoError::hdf5(
                        &grid.file,
                        format!("reading the type of grid {}'s '{name}'", grid.id),
                        e,
                    ))
                }
            };
            for (y0, y1, z0, z1) in slab_ranges(&grid.valid, chunk) {
                let cells = IBox::new([grid.valid.lo[0], y0, z0], [grid.valid.hi[0], y1, z1]);
                let at = Where {
                    grid,
                    field: name,
                    stored,
                    cells,
                };
                if wide {
                    read_slab::<f64>(&data, &at, &mut out)?;
                } else {
                    read_slab::<f32>(&data, &at, &mut out)?;
                }
                let bytes = out.len() as u64 * if wide { 8 } else { 4 };
                bytes_read += bytes;
                progress.advance(bytes);
                sink(Slab {
                    level: grid.level,
                    index: grid.index,
                    valid: grid.valid,
                    field: f,
                    cells,
                    values: &out,
                })?;
            }
        }
    }
    Ok(bytes_read)
}

/// The data file opened last, kept open while consecutive grids live in it.
#[derive(Default)]
pub(crate) struct OpenFile {
    current: Option<(std::path::PathBuf, File)>,
}

impl OpenFile {
    /// The HDF5 file `path`, opened unless it is the current one.
    pub(crate) fn get(&mut self, path: &std::path::Path) -> Result<&File> {
        if self.current.as_ref().is_none_or(|(p, _)| p != path) {
            let f = File::open(path)
                .map_err(|e| EnzoError::hdf5(path, "cannot open as an HDF5 file", e))?;
            self.current = Some((path.to_path_buf(), f));
        }
        match &self.current {
            Some((_, f)) => Ok(f),
            None => Err(EnzoError::invalid(path, "no HDF5 file open")),
        }
    }
}

/// Grid `grid`'s dataset `name` in `file`, and the cells it covers.
pub(crate) fn field_dataset(grid: &Grid, file: &File, name: &str) -> Result<(H5Dataset, IBox)> {
    let group = grid.group(file)?;
    if !group.link_exists(name) {
        return Err(EnzoError::invalid(
            &grid.file,
            format!(
                "grid {} has no dataset '{name}' (the first grid has)",
                grid.id
            ),
        ));
    }
    let data = group.dataset(name).map_err(|e| {
        EnzoError::hdf5(
            &grid.file,
            format!("opening grid {}'s '{name}'", grid.id),
            e,
        )
    })?;
    let stored = stored_box(grid, &data, name)?;
    Ok((data, stored))
}

/// The cells a field's dataset covers: the active cells, or the whole `GridDimension` with
/// the ghost zones around them.
fn stored_box(grid: &Grid, data: &H5Dataset, name: &str) -> Result<IBox> {
    let shape = data.shape();
    let active = grid.valid.extent();
    let ext = match shape.as_slice() {
        [z, y, x] => [*x as i64, *y as i64, *z as i64],
        _ => [-1; 3],
    };
    if ext == active {
        return Ok(grid.valid);
    }
    if ext == grid.dims {
        let lo = [0, 1, 2].map(|a| grid.valid.lo[a] - grid.start[a]);
        return Ok(IBox::new(lo, [0, 1, 2].map(|a| lo[a] + grid.dims[a])));
    }
    Err(EnzoError::invalid(
        &grid.file,
        format!(
            "grid {}'s '{name}' has shape {shape:?}, but the hierarchy gives {:?} active cells \
             (z, y, x) and GridDimension {:?} with ghost zones",
            grid.id,
            [active[2], active[1], active[0]],
            [grid.dims[2], grid.dims[1], grid.dims[0]]
        ),
    ))
}

/// Which slab is being read, for the selection and for error messages.
struct Where<'a> {
    grid: &'a Grid,
    field: &'a str,
    /// The cells the dataset covers.
    stored: IBox,
    /// The valid cells to read.
    cells: IBox,
}

/// Reads `at.cells` of `data` as `T` and converts them into `out`, x fastest.
fn read_slab<T: ToFiniteF32 + H5Type>(
    data: &H5Dataset,
    at: &Where,
    out: &mut Vec<f32>,
) -> Result<()> {
    let axis = |a: usize| SliceOrIndex::SliceCount {
        start: (at.cells.lo[a] - at.stored.lo[a]) as usize,
        step: 1,
        count: (at.cells.hi[a] - at.cells.lo[a]) as usize,
        block: 1,
    };
    let sel = Selection::Hyperslab(Hyperslab::from(vec![axis(2), axis(1), axis(0)]));
    let g = at.grid;
    let raw = data.read_slice::<T, _, ndarray::IxDyn>(sel).map_err(|e| {
        EnzoError::hdf5(
            &g.file,
            format!("reading grid {}'s '{}'", g.id, at.field),
            e,
        )
    })?;
    let raw = raw.as_slice().ok_or_else(|| {
        EnzoError::invalid(
            &g.file,
            format!("grid {}: a slab read came back non-contiguous", g.id),
        )
    })?;
    out.clear();
    out.reserve(raw.len());
    for (i, &v) in raw.iter().enumerate() {
        match v.to_finite_f32() {
            Ok(x) => out.push(x),
            Err((why, value)) => {
                let e = at.cells.extent();
                let i = i as i64;
                return Err(EnzoError::BadValue {
                    path: g.file.clone(),
                    grid: g.id,
                    level: g.level,
                    field: at.field.to_string(),
                    cell: [
                        at.cells.lo[0] + i % e[0],
                        at.cells.lo[1] + (i / e[0]) % e[1],
                        at.cells.lo[2] + i / (e[0] * e[1]),
                    ],
                    value,
                    why,
                });
            }
        }
    }
    Ok(())
}
