//! `amr-render info`: what a file holds: counts as plain integers a script can read, extents
//! and values with readable numbers, and each field's percentiles.

use std::fmt::Write;

use amr_format::{IBox, LevelInfo};

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

/// A human-readable description of an open file: levels, bricks, cells, fields and their
/// ranges, tree depth and leaves, and bytes by section.
pub fn describe(file: &MappedFile) -> String {
    let mut out = String::new();
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
    let _ = writeln!(out, "file bytes: {}", file.bytes().len());
    match (file.simulation_time(), file.simulation_step()) {
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
    for (l, lev) in file.levels().iter().enumerate() {
        let _ = writeln!(
            out,
            "  level {l}: bricks {} cells {} domain {:?}..{:?} cell size {} origin {}{}",
            bricks[l],
            cells[l],
            lev.domain.lo,
            lev.domain.hi,
            format_vector(lev.cell_size),
            format_vector(lev.origin),
            match l + 1 < nl {
                true => format!(" ratio to next {:?}", lev.ratio_to_next),
                false => String::new(),
            }
        );
        match covered[l] {
            Some(b) => {
                let _ = writeln!(
                    out,
                    "           boxes within {} .. {}",
                    format_vector(world(lev, b.lo)),
                    format_vector(world(lev, b.hi))
                );
            }
            None => {
                let _ = writeln!(out, "           no boxes");
            }
        }
    }
    if let Some(lev) = file.levels().first() {
        let _ = writeln!(
            out,
            "domain extent: {} .. {}",
            format_vector(world(lev, lev.domain.lo)),
            format_vector(world(lev, lev.domain.hi))
        );
    }
    let _ = writeln!(out, "bricks: {}", file.num_bricks());
    let _ = writeln!(out, "cells: {}", cells.iter().sum::<u64>());
    let _ = writeln!(out, "fields: {}", file.fields().len());
    let width = file
        .fields()
        .iter()
        .map(|f| f.name.len())
        .max()
        .unwrap_or(0);
    for f in file.fields() {
        let _ = writeln!(
            out,
            "  {:<width$}  min {:>11}  max {:>11}{}",
            f.name,
            format_value(f64::from(f.min)),
            format_value(f64::from(f.max)),
            if f.compressed { " (zstd)" } else { "" }
        );
    }
    let all: Vec<_> = (0..file.fields().len())
        .map(|i| {
            FieldPercentiles::of_reading_ahead(file, i, |r| read_ahead(file, r.iter().copied()))
        })
        .collect();
    let over = match all.iter().flatten().any(|p| p.subsampled) {
        true => format!(
            "over {} runs of {SAMPLE_RUN} cells spread evenly over every level; p0 and p100 are \
             the field's min and max",
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
    for (f, p) in file.fields().iter().zip(&all) {
        let row: Vec<String> = match p {
            Ok(p) => TABLE
                .iter()
                .map(|&q| {
                    let v = match (p.subsampled, q) {
                        (true, 0.0) => f64::from(f.min),
                        (true, 1.0) => f64::from(f.max),
                        _ => p.at(q),
                    };
                    format!("{:>11}", format_value(v))
                })
                .collect(),
            Err(e) => vec![format!("unreadable: {e}")],
        };
        let _ = writeln!(out, "  {:<width$} {}", f.name, row.join(" "));
    }
    let _ = writeln!(out, "kd nodes: {}", file.tree().num_nodes());
    let _ = writeln!(out, "kd leaves: {}", file.num_leaves());
    let _ = writeln!(out, "kd depth: {}", file.tree_depth());
    let _ = writeln!(out, "sections (bytes):");
    for (name, bytes) in file.section_sizes() {
        let _ = writeln!(out, "  {name}: {bytes}");
    }
    out
}

/// The world position of the corner of `lev`'s cell index `i`.
fn world(lev: &LevelInfo, i: [i64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|a| lev.origin[a] + i[a] as f64 * lev.cell_size[a])
}
