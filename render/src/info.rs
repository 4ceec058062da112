//! `amr-render info`: what a file holds, as plain integers a script can read.

use std::fmt::Write;

use amr_format::AmrkFile;

/// A human-readable description of an open file: levels, bricks, cells, fields and their
/// ranges, tree depth and leaves, and bytes by section.
pub fn describe<D: AsRef<[u8]>>(file: &AmrkFile<D>) -> String {
    let mut out = String::new();
    let nl = file.levels().len();
    let mut bricks = vec![0u64; nl];
    let mut cells = vec![0u64; nl];
    for b in 0..file.num_bricks() {
        let info = file.brick(b);
        bricks[info.level as usize] += 1;
        cells[info.level as usize] += info.cells.num_cells().unwrap_or(0);
    }
    let _ = writeln!(out, "file bytes: {}", file.bytes().len());
    match (file.simulation_time(), file.simulation_step()) {
        (None, None) => {}
        (time, step) => {
            let show = |v: Option<String>| v.unwrap_or_else(|| "not recorded".into());
            let _ = writeln!(
                out,
                "simulation: time {} step {}",
                show(time.map(|t| t.to_string())),
                show(step.map(|n| n.to_string()))
            );
        }
    }
    let _ = writeln!(out, "levels: {nl}");
    for (l, lev) in file.levels().iter().enumerate() {
        let _ = writeln!(
            out,
            "  level {l}: bricks {} cells {} domain {:?}..{:?} cell size {:?} origin {:?} ratio to next {:?}",
            bricks[l], cells[l], lev.domain.lo, lev.domain.hi, lev.cell_size, lev.origin, lev.ratio_to_next
        );
    }
    let _ = writeln!(out, "bricks: {}", file.num_bricks());
    let _ = writeln!(out, "cells: {}", cells.iter().sum::<u64>());
    let _ = writeln!(out, "fields: {}", file.fields().len());
    for f in file.fields() {
        let _ = writeln!(
            out,
            "  {}: min {} max {}{}",
            f.name,
            f.min,
            f.max,
            if f.compressed { " (zstd)" } else { "" }
        );
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
