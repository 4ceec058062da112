//! `amr-render info`: what a file holds: counts as plain integers a script can read, extents
//! and values with readable numbers, and each field's percentiles; the same as JSON.

use std::fmt::Write;

use amr_format::{IBox, LevelInfo};
use serde::Serialize;

use crate::coloring::vector_fields;
use crate::mapping::{read_ahead, MappedFile};

use crate::field_stats::{
    format_value, format_vector, FieldPercentiles, MAX_SAMPLES, SAMPLE_RUN, TABLE,
};

/// `v` in full (it reads back as the same `f64`), in scientific notation where plain digits
/// would run long: a PeleLM time is `1.3924182125972017e-8`, not 0.0000000139....
fn exact_number(v: f64) -> String {
    match v == 0.0 || (1e-3..1e6).contains(&v.abs()) {
        true => v.to_string(),
        false => format!("{v:e}"),
    }
}

/// What `amr-render info` reports about a file, as data: the text ([`describe`]) and the JSON
/// (`amr-render info --json`) are two forms of it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FileSummary {
    /// Length of the file.
    pub file_bytes: u64,
    /// The simulation time the converter recorded, if any.
    pub simulation_time: Option<f64>,
    /// The simulation step the converter recorded, if any.
    pub simulation_step: Option<i64>,
    /// The levels, coarsest first.
    pub levels: Vec<LevelSummary>,
    /// The domain's world box `[lo, hi]` (level 0's index domain).
    pub domain: Option<[[f64; 3]; 2]>,
    /// Bricks of every level.
    pub bricks: u64,
    /// Cells of every level.
    pub cells: u64,
    /// The fields, in file order.
    pub fields: Vec<FieldSummary>,
    /// The vectors the fields hold as x, y and z components, as `--color-by` paints by their
    /// length: `|x-velocity,y-velocity,z-velocity|` ([`crate::coloring::vector_fields`]).
    pub vectors: Vec<String>,
    /// True when the percentiles are taken over runs of cells spread over every level, not
    /// over every cell (their p0 and p100 are then the field's min and max).
    pub percentiles_subsampled: bool,
    /// Nodes of the kd-tree.
    pub kd_nodes: u64,
    /// Leaves of the kd-tree.
    pub kd_leaves: u64,
    /// Depth of the kd-tree.
    pub kd_depth: u32,
    /// Bytes of each section of the file, in file order.
    pub sections: Vec<SectionBytes>,
}

/// One level of a [`FileSummary`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LevelSummary {
    /// Bricks of the level.
    pub bricks: u64,
    /// Cells of the level.
    pub cells: u64,
    /// The level's index domain, `[lo, hi)`.
    pub domain: [[i64; 3]; 2],
    /// A cell's world size.
    pub cell_size: [f64; 3],
    /// The world position of cell index 0's lower corner.
    pub origin: [f64; 3],
    /// The refinement ratio to the next finer level (`None` for the finest).
    pub ratio_to_next: Option<[u32; 3]>,
    /// The world box around the level's bricks (`None` when it has none).
    pub boxes: Option<[[f64; 3]; 2]>,
}

/// One field of a [`FileSummary`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FieldSummary {
    /// The field's name.
    pub name: String,
    /// The smallest value of any cell (a stored `f32`, exactly).
    pub min: f64,
    /// The largest value of any cell (a stored `f32`, exactly).
    pub max: f64,
    /// True when its bricks are stored zstd-compressed.
    pub compressed: bool,
    /// The values at the quantiles of [`TABLE`] (`p0`, `p1`, `p25`, ...); `None` when the
    /// cells could not be read.
    pub percentiles: Option<Percentiles>,
    /// Why the cells could not be read, when they could not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unreadable: Option<String>,
}

/// A field's values at the quantiles of [`TABLE`], written as `{"p0": v, "p1": v, ...}`.
#[derive(Clone, Debug, PartialEq)]
pub struct Percentiles(pub Vec<(f64, f64)>);

impl Serialize for Percentiles {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut map = s.serialize_map(Some(self.0.len()))?;
        for (q, v) in &self.0 {
            map.serialize_entry(&format!("p{}", q * 100.0), v)?;
        }
        map.end()
    }
}

/// One section of a [`FileSummary`] and its length.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SectionBytes {
    /// The section's name (`data 'NAME'` for a field's bricks).
    pub name: String,
    /// Its length in bytes.
    pub bytes: u64,
}

/// What an open file holds: levels, bricks, cells, fields with their ranges and percentiles,
/// the kd-tree, and bytes by section. Reads the cells the percentiles sample.
pub fn summarize(file: &MappedFile) -> FileSummary {
    let nl = file.levels().len();
    let mut bricks = vec![0u64; nl];
    let mut cells = vec![0u64; nl];
    // The index box around each level's bricks.
    let mut covered: Vec<Option<IBox>> = vec![None; nl];
    for b in 0..file.num_bricks() {
        let info = file.brick(b);
        let l = info.level as usize;
        bricks[l] += 1;
        cells[l] += info.cells.num_cells().unwrap_or(0);
        covered[l] = Some(covered[l].map_or(info.cells, |c| c.union(&info.cells)));
    }
    let levels = file
        .levels()
        .iter()
        .enumerate()
        .map(|(l, lev)| LevelSummary {
            bricks: bricks[l],
            cells: cells[l],
            domain: [lev.domain.lo, lev.domain.hi],
            cell_size: lev.cell_size,
            origin: lev.origin,
            ratio_to_next: (l + 1 < nl).then_some(lev.ratio_to_next),
            boxes: covered[l].map(|b| [world(lev, b.lo), world(lev, b.hi)]),
        })
        .collect();
    let all: Vec<_> = (0..file.fields().len())
        .map(|i| {
            FieldPercentiles::of_reading_ahead(file, i, |r| read_ahead(file, r.iter().copied()))
        })
        .collect();
    let fields: Vec<FieldSummary> = file
        .fields()
        .iter()
        .zip(&all)
        .map(|(f, p)| FieldSummary {
            name: f.name.clone(),
            min: f64::from(f.min),
            max: f64::from(f.max),
            compressed: f.compressed,
            percentiles: p.as_ref().ok().map(|p| {
                Percentiles(
                    TABLE
                        .iter()
                        .map(|&q| {
                            let v = match (p.subsampled, q) {
                                (true, 0.0) => f64::from(f.min),
                                (true, 1.0) => f64::from(f.max),
                                _ => p.at(q),
                            };
                            (q, v)
                        })
                        .collect(),
                )
            }),
            unreadable: p.as_ref().err().map(|e| e.to_string()),
        })
        .collect();
    FileSummary {
        file_bytes: file.bytes().len() as u64,
        simulation_time: file.simulation_time(),
        simulation_step: file.simulation_step(),
        levels,
        domain: file
            .levels()
            .first()
            .map(|lev| [world(lev, lev.domain.lo), world(lev, lev.domain.hi)]),
        bricks: file.num_bricks() as u64,
        cells: cells.iter().sum(),
        vectors: vector_fields(&fields.iter().map(|f| f.name.as_str()).collect::<Vec<_>>())
            .iter()
            .map(ToString::to_string)
            .collect(),
        fields,
        percentiles_subsampled: all.iter().flatten().any(|p| p.subsampled),
        kd_nodes: file.tree().num_nodes() as u64,
        kd_leaves: file.num_leaves() as u64,
        kd_depth: file.tree_depth(),
        sections: file
            .section_sizes()
            .into_iter()
            .map(|(name, bytes)| SectionBytes { name, bytes })
            .collect(),
    }
}

/// A human-readable description of an open file: levels, bricks, cells, fields and their
/// ranges, tree depth and leaves, and bytes by section ([`summarize`] as text).
pub fn describe(file: &MappedFile) -> String {
    summarize(file).to_text()
}

impl FileSummary {
    /// The summary as `amr-render info` prints it: counts as plain integers a script can
    /// read, extents and values with readable numbers.
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        let nl = self.levels.len();
        let _ = writeln!(out, "file bytes: {}", self.file_bytes);
        match (self.simulation_time, self.simulation_step) {
            (None, None) => {}
            (time, step) => {
                let show = |v: Option<String>| v.unwrap_or_else(|| "not recorded".into());
                let _ = writeln!(
                    out,
                    "simulation: time {} step {}",
                    show(time.map(exact_number)),
                    show(step.map(|n| n.to_string()))
                );
            }
        }
        let _ = writeln!(out, "levels: {nl}");
        for (l, lev) in self.levels.iter().enumerate() {
            let _ = writeln!(
                out,
                "  level {l}: bricks {} cells {} domain {:?}..{:?} cell size {} origin {}{}",
                lev.bricks,
                lev.cells,
                lev.domain[0],
                lev.domain[1],
                format_vector(lev.cell_size),
                format_vector(lev.origin),
                match lev.ratio_to_next {
                    Some(r) => format!(" ratio to next {r:?}"),
                    None => String::new(),
                }
            );
            match lev.boxes {
                Some([lo, hi]) => {
                    let _ = writeln!(
                        out,
                        "           boxes within {} .. {}",
                        format_vector(lo),
                        format_vector(hi)
                    );
                }
                None => {
                    let _ = writeln!(out, "           no boxes");
                }
            }
        }
        if let Some([lo, hi]) = self.domain {
            let _ = writeln!(
                out,
                "domain extent: {} .. {}",
                format_vector(lo),
                format_vector(hi)
            );
        }
        let _ = writeln!(out, "bricks: {}", self.bricks);
        let _ = writeln!(out, "cells: {}", self.cells);
        let _ = writeln!(out, "fields: {}", self.fields.len());
        let width = self.fields.iter().map(|f| f.name.len()).max().unwrap_or(0);
        for f in &self.fields {
            let _ = writeln!(
                out,
                "  {:<width$}  min {:>11}  max {:>11}{}",
                f.name,
                format_value(f.min),
                format_value(f.max),
                if f.compressed { " (zstd)" } else { "" }
            );
        }
        if !self.vectors.is_empty() {
            let _ = writeln!(
                out,
                "vectors: {} (paint by a length with --color-by '{}')",
                self.vectors.join(" "),
                self.vectors[0]
            );
        }
        let over = match self.percentiles_subsampled {
            true => format!(
                "over {} runs of {SAMPLE_RUN} cells spread evenly over every level; p0 and p100 \
                 are the field's min and max",
                MAX_SAMPLES as u64 / SAMPLE_RUN
            ),
            false => "over every cell of every level".to_string(),
        };
        let _ = writeln!(out, "field percentiles ({over}):");
        let head: Vec<String> = TABLE
            .iter()
            .map(|q| format!("{:>11}", format!("p{}", q * 100.0)))
            .collect();
        let _ = writeln!(out, "  {:<width$} {}", "", head.join(" "));
        for f in &self.fields {
            let row: Vec<String> = match (&f.percentiles, &f.unreadable) {
                (Some(p), _) => {
                    p.0.iter()
                        .map(|&(_, v)| format!("{:>11}", format_value(v)))
                        .collect()
                }
                (None, e) => vec![format!("unreadable: {}", e.as_deref().unwrap_or("?"))],
            };
            let _ = writeln!(out, "  {:<width$} {}", f.name, row.join(" "));
        }
        let _ = writeln!(out, "kd nodes: {}", self.kd_nodes);
        let _ = writeln!(out, "kd leaves: {}", self.kd_leaves);
        let _ = writeln!(out, "kd depth: {}", self.kd_depth);
        let _ = writeln!(out, "sections (bytes):");
        for s in &self.sections {
            let _ = writeln!(out, "  {}: {}", s.name, s.bytes);
        }
        out
    }
}

/// The world position of the corner of `lev`'s cell index `i`.
fn world(lev: &LevelInfo, i: [i64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|a| lev.origin[a] + i[a] as f64 * lev.cell_size[a])
}
