//! Evaluating a field at the cell centres of each brick and streaming the bricks into an
//! [`AmrkWriter`]: a chunk of bricks is evaluated in parallel while the previous chunk is
//! written, so memory holds two chunks of brick data at most.

use std::path::Path;
use std::time::Instant;

use amr_format::{AmrkWriter, FormatError, HierarchySpec, IBox, WriteSummary, WriterOptions};
use rayon::prelude::*;

use crate::fields::{AnalyticField, Case};
use crate::params::SynthParams;
use crate::refine::build_hierarchy;
use amr_format::progress::Progress;

/// Bricks evaluated together, per rayon thread.
const BRICKS_PER_THREAD: usize = 2;

/// What [`write_synth`] produced.
#[derive(Clone, Debug)]
pub struct SynthSummary {
    /// The parameters used (after any fitting to a cell count).
    pub params: SynthParams,
    /// Cells of each level present in the file.
    pub cells_per_level: Vec<u64>,
    /// What the writer reported.
    pub write: WriteSummary,
    /// Wall-clock seconds from the first hierarchy computation to the renamed file.
    pub seconds: f64,
}

/// Writes the synthetic dataset `case` with `params` to `path`.
pub fn write_synth(
    path: &Path,
    case: Case,
    params: &SynthParams,
    options: WriterOptions,
    progress: &dyn Progress,
) -> Result<SynthSummary, FormatError> {
    let start = Instant::now();
    let spec = build_hierarchy(&case, case.name(), params)?;
    let cells_per_level = cells_per_level(&spec);
    let write = write_spec(path, spec, &case, options, progress)?;
    Ok(SynthSummary {
        params: params.clone(),
        cells_per_level,
        write,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Writes any hierarchy whose every field takes the values of `field`, a function on the unit
/// cube that each level's index domain is mapped onto. Progress counts raw data bytes.
pub fn write_spec<F>(
    path: &Path,
    spec: HierarchySpec,
    field: &F,
    options: WriterOptions,
    progress: &dyn Progress,
) -> Result<WriteSummary, FormatError>
where
    F: AnalyticField + Sync,
{
    let bytes_per_cell = 4 * spec.fields.len() as u64;
    progress.set_total(bytes_per_cell * spec.total_cells());
    let jobs = brick_jobs(&spec);
    let nfields = spec.fields.len();
    let mut writer = AmrkWriter::create(path, spec, options).map_err(|e| e.in_file(path))?;
    let chunk = BRICKS_PER_THREAD * rayon::current_num_threads().max(1);
    let evaluate = |first: usize| -> Vec<Vec<f32>> {
        let end = (first + chunk).min(jobs.len());
        jobs[first..end]
            .par_iter()
            .map(|(domain, cells)| {
                let mut values = Vec::new();
                eval_brick(field, domain, cells, &mut values);
                values
            })
            .collect()
    };
    let mut ready = evaluate(0);
    let mut first = 0;
    while !ready.is_empty() {
        let next_first = first + ready.len();
        let written = |writer: &mut AmrkWriter| -> Result<u64, FormatError> {
            let mut cells = 0;
            for (i, values) in ready.iter().enumerate() {
                for f in 0..nfields {
                    writer.write_brick(first + i, f, values)?;
                }
                cells += values.len() as u64;
            }
            Ok(cells)
        };
        let (done, next) = rayon::join(|| written(&mut writer), || evaluate(next_first));
        progress.advance(bytes_per_cell * done.map_err(|e| e.in_file(path))?);
        ready = next;
        first = next_first;
    }
    // Not held while the writer finishes (the tight ranges' pass maps the whole file).
    drop(jobs);
    let summary = writer.finish().map_err(|e| e.in_file(path))?;
    progress.finish();
    Ok(summary)
}

/// Each brick's level index domain and cells, in the order of `spec.bricks`.
fn brick_jobs(spec: &HierarchySpec) -> Vec<(IBox, IBox)> {
    let domains: Vec<IBox> = spec.levels.iter().map(|l| l.domain).collect();
    spec.bricks
        .iter()
        .map(|b| (domains[b.level as usize], b.cells))
        .collect()
}

/// A field given as a function on the unit cube.
pub type FieldFn<'a> = &'a (dyn Fn([f64; 3]) -> f64 + Sync);

/// Writes `spec` with one function per field of `spec.fields` (in order), each on the unit cube
/// that each level's index domain is mapped onto: a file whose fields differ, for colouring one
/// field's surface by another. Holds one brick's values per field at a time.
pub fn write_fields(
    path: &Path,
    spec: HierarchySpec,
    fields: &[FieldFn<'_>],
    options: WriterOptions,
) -> Result<WriteSummary, FormatError> {
    if fields.len() != spec.fields.len() {
        return Err(FormatError::InvalidHierarchy(format!(
            "{} functions for {} fields",
            fields.len(),
            spec.fields.len()
        )));
    }
    let jobs = brick_jobs(&spec);
    let mut writer = AmrkWriter::create(path, spec, options).map_err(|e| e.in_file(path))?;
    for (b, (domain, cells)) in jobs.iter().enumerate() {
        for (f, field) in fields.iter().enumerate() {
            let mut values = Vec::new();
            eval_brick(&FnField(*field), domain, cells, &mut values);
            writer
                .write_brick(b, f, &values)
                .map_err(|e| e.in_file(path))?;
        }
    }
    writer.finish().map_err(|e| e.in_file(path))
}

/// A function seen as an [`AnalyticField`] for [`eval_brick`].
struct FnField<'a>(FieldFn<'a>);

impl AnalyticField for FnField<'_> {
    fn value(&self, p: [f64; 3]) -> f64 {
        (self.0)(p)
    }
    fn gradient(&self, _p: [f64; 3]) -> [f64; 3] {
        [0.0; 3]
    }
    fn default_iso(&self) -> f64 {
        0.0
    }
}

/// Fills `out` with `field` at the centres of the cells of `cells`, x fastest, where the level's
/// index `domain` is mapped onto the unit cube.
pub fn eval_brick<F: AnalyticField + ?Sized>(
    field: &F,
    domain: &IBox,
    cells: &IBox,
    out: &mut Vec<f32>,
) {
    let e = domain.extent();
    let axis = |a: usize| -> Vec<f64> {
        (cells.lo[a]..cells.hi[a])
            .map(|i| ((i - domain.lo[a]) as f64 + 0.5) / e[a] as f64)
            .collect()
    };
    let (xs, ys, zs) = (axis(0), axis(1), axis(2));
    out.clear();
    out.reserve(xs.len() * ys.len() * zs.len());
    for &z in &zs {
        for &y in &ys {
            out.extend(xs.iter().map(|&x| field.value([x, y, z]) as f32));
        }
    }
}

/// Total cells on each level of `spec`.
pub fn cells_per_level(spec: &HierarchySpec) -> Vec<u64> {
    let mut cells = vec![0u64; spec.levels.len()];
    for b in &spec.bricks {
        cells[b.level as usize] += b.cells.num_cells().unwrap_or(0);
    }
    cells
}

#[cfg(test)]
mod tests {
    use super::*;
    use amr_format::progress::NoProgress;
    use amr_format::{AmrkFile, Compression};

    #[test]
    fn eval_brick_uses_cell_centres_x_fastest() {
        let domain = IBox::new([0; 3], [4; 3]);
        let cells = IBox::new([1, 2, 3], [3, 3, 4]);
        let mut out = Vec::new();
        eval_brick(&Case::Sphere, &domain, &cells, &mut out);
        assert_eq!(out.len(), 2);
        let expect = |i: f64| Case::Sphere.value([(i + 0.5) / 4.0, 2.5 / 4.0, 3.5 / 4.0]) as f32;
        assert_eq!(out, vec![expect(1.0), expect(2.0)]);
    }

    #[test]
    fn written_file_holds_the_field_at_cell_centres() {
        let dir = tempfile::tempdir().unwrap();
        for (case, compression) in [
            (Case::Blobs, Compression::None),
            (Case::Ripple, Compression::Zstd { level: 3 }),
        ] {
            let path = dir.path().join(format!("{case}.amrk"));
            let params = SynthParams {
                levels: 3,
                ratio: 2,
                base: 16,
                brick: 8,
                origin: [1e6, -2.0, 0.5],
                size: 1e-3,
            };
            let summary = write_synth(
                &path,
                case,
                &params,
                WriterOptions {
                    compression,
                    ..Default::default()
                },
                &NoProgress,
            )
            .unwrap();
            assert_eq!(
                summary.cells_per_level.iter().sum::<u64>(),
                summary.write.cells
            );
            let bytes = std::fs::read(&path).unwrap();
            let file = AmrkFile::open(bytes).unwrap();
            file.verify().unwrap();
            let spec = build_hierarchy(&case, case.name(), &params).unwrap();
            let placed = crate::Placed {
                field: case,
                origin: params.origin,
                size: params.size,
            };
            let mut values = Vec::new();
            for (i, b) in spec.bricks.iter().enumerate().step_by(7) {
                let level = &spec.levels[b.level as usize];
                file.brick_values_into(0, i, &mut values).unwrap();
                let c = b.cells.lo;
                let p =
                    [0, 1, 2].map(|a| level.origin[a] + (c[a] as f64 + 0.5) * level.cell_size[a]);
                let v = placed.value(p);
                assert!(
                    (values[0] as f64 - v).abs() <= 1e-3 * (1.0 + v.abs()),
                    "{case} brick {i}: {} vs {v}",
                    values[0]
                );
            }
        }
    }
}
