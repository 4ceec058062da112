//! Streaming the cell data: box by box, field by field, in slabs of at most `chunk` rows and
//! layers read with one strided hyperslab each, ghost layers dropped, values checked and
//! converted to `f32`.
//!
//! A box's data in `data:datatype=0` is one component after the other, each x fastest over the
//! box grown by its ghost layers. A slab of rows `y0..y1` and layers `z0..z1` is `z1 - z0`
//! blocks of `(y1 - y0) * gx` values, one every `gx * gy` values: a single hyperslab. Reads
//! follow the file's order, and memory holds one slab: `chunk² × gx` values.

use amr_format::IBox;
use hdf5_metno::{Dataset, H5Type, Hyperslab, Selection, SliceOrIndex};

use super::error::{BadValue, ChomboError, Result};
use super::plotfile::{Level, Plotfile, Precision};
use crate::finite::ToFiniteF32;
use crate::hierarchy_to_amrk::{slab_ranges, Slab};
use amr_format::progress::Progress;

/// What [`stream`] read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamStats {
    /// Bytes of cell data read from the file (ghost rows and layers skipped, ghost columns read).
    pub bytes_read: u64,
}

/// Bytes [`stream`] will read for the components `comps`.
pub fn bytes_to_read(pf: &Plotfile, comps: &[usize]) -> u64 {
    let mut total = 0u64;
    for level in &pf.levels {
        for v in &level.boxes {
            for &c in comps {
                let var = &level.vars[pf.sources[c].var];
                let gx = var.stored_box(v).extent()[0] as u64;
                let e = v.extent();
                total += gx * e[1] as u64 * e[2] as u64 * var.precision.bytes();
            }
        }
    }
    total
}

/// Reads every box of every level, for each component in `comps` (indices into
/// `pf.fields`), and hands the data to `sink` one slab at a time, in file order.
pub fn stream(
    pf: &Plotfile,
    comps: &[usize],
    chunk: i64,
    progress: &dyn Progress,
    mut sink: impl FnMut(Slab) -> Result<()>,
) -> Result<StreamStats> {
    progress.set_total(bytes_to_read(pf, comps));
    let mut stats = StreamStats::default();
    let mut out = Vec::new();
    for (l, level) in pf.levels.iter().enumerate() {
        for (i, valid) in level.boxes.iter().enumerate() {
            for (f, &c) in comps.iter().enumerate() {
                let src = pf.sources[c];
                let var = &level.vars[src.var];
                let Some(data) = &var.data else { continue };
                let stored = var.stored_box(valid);
                let g = stored.extent().map(|e| e as u64);
                let cells_per_comp = g[0] * g[1] * g[2];
                let base = var.offsets[i] + src.comp as u64 * cells_per_comp;
                for (y0, y1, z0, z1) in slab_ranges(valid, chunk) {
                    let start = base
                        + (z0 - stored.lo[2]) as u64 * g[0] * g[1]
                        + (y0 - stored.lo[1]) as u64 * g[0];
                    let read = Read {
                        start,
                        step: g[0] * g[1],
                        count: (z1 - z0) as u64,
                        block: (y1 - y0) as u64 * g[0],
                    };
                    let cells = IBox::new([valid.lo[0], y0, z0], [valid.hi[0], y1, z1]);
                    let ctx = Where {
                        pf,
                        level: l,
                        index: i,
                        field: c,
                        stored,
                        cells,
                    };
                    match var.precision {
                        Precision::F32 => read_convert::<f32>(data, &read, &ctx, &mut out)?,
                        Precision::F64 => read_convert::<f64>(data, &read, &ctx, &mut out)?,
                    }
                    let bytes = read.count * read.block * var.precision.bytes();
                    stats.bytes_read += bytes;
                    progress.advance(bytes);
                    sink(Slab {
                        level: l,
                        index: i,
                        field: f,
                        valid: *valid,
                        cells,
                        values: &out,
                    })?;
                }
            }
        }
    }
    Ok(stats)
}

/// One strided 1-D selection: `count` blocks of `block` values, one every `step`, from `start`.
struct Read {
    start: u64,
    step: u64,
    count: u64,
    block: u64,
}

/// Which slab is being read, for converting and for error messages.
struct Where<'a> {
    pf: &'a Plotfile,
    level: usize,
    index: usize,
    field: usize,
    /// The box with its ghost layers: the x range each read row spans.
    stored: IBox,
    /// The valid cells wanted from the read rows.
    cells: IBox,
}

/// Reads `r` from `data` as `T` and converts the valid columns into `out`.
fn read_convert<T: ToFiniteF32 + H5Type>(
    data: &Dataset,
    r: &Read,
    at: &Where,
    out: &mut Vec<f32>,
) -> Result<()> {
    let sel = Selection::Hyperslab(Hyperslab::new(SliceOrIndex::SliceCount {
        start: r.start as usize,
        step: r.step.max(r.block) as usize,
        count: r.count as usize,
        block: r.block as usize,
    }));
    let level: &Level = &at.pf.levels[at.level];
    let raw = data.read_slice_1d::<T, _>(sel).map_err(|e| {
        ChomboError::hdf5(
            &at.pf.path,
            format!(
                "reading level_{} box {} component {}",
                at.level, at.index, at.field
            ),
            e,
        )
    })?;
    let raw = raw.as_slice().ok_or_else(|| {
        ChomboError::invalid(
            &at.pf.path,
            format!("level_{}: a slab read came back non-contiguous", at.level),
        )
    })?;
    let gx = at.stored.extent()[0] as usize;
    let skip = (at.cells.lo[0] - at.stored.lo[0]) as usize;
    let nx = at.cells.extent()[0] as usize;
    out.clear();
    for (row, values) in raw.chunks_exact(gx).enumerate() {
        for (x, &v) in values[skip..skip + nx].iter().enumerate() {
            match v.to_finite_f32() {
                Ok(f) => out.push(f),
                Err((why, value)) => {
                    let e = at.cells.extent();
                    let (y, z) = (row as i64 % e[1], row as i64 / e[1]);
                    let valid = level.boxes[at.index];
                    return Err(ChomboError::BadValue(Box::new(BadValue {
                        path: at.pf.path.clone(),
                        level: at.level,
                        index: at.index,
                        lo: valid.lo,
                        hi: valid.hi.map(|h| h - 1),
                        cell: [
                            at.cells.lo[0] + x as i64,
                            at.cells.lo[1] + y,
                            at.cells.lo[2] + z,
                        ],
                        field: at.pf.fields[at.field].clone(),
                        value,
                        why,
                    })));
                }
            }
        }
    }
    Ok(())
}
