//! Scale: synthetic `blobs` files of growing cell count; synthesis, open, extraction, BVH build
//! and frame time, peak RSS and the resident bytes of the map, against cell count.
//!
//! Each file is rendered by a child process ([`super::scale_render`]), so that its peak RSS
//! (`VmHWM`) belongs to that render alone. At the 1e8
//! size (the largest, with `--quick`) the BVH built in chunks is also compared with one BVH over
//! all refs ([`crate::bvh`]).

use std::fmt::Write as _;
use std::time::Instant;

use amr_format::progress::NoProgress;
use amr_format::WriterOptions;
use amr_render::bvh::{BuildMethod, CHUNK_REFS};
use amr_synth::{fit_cells, write_synth, Case, SynthParams};

use super::plot::{loglog, Series};
use super::scale_render::{self, CHILD_COMMAND};
use super::{img_link, Ctx};
use crate::bvh::{compare, table, BvhBenchConfig};
use crate::open::open_time;

/// The isovalue rendered at every size.
const ISO: f32 = 10.0;

/// One measured size.
struct Point {
    cells: u64,
    file_bytes: u64,
    synth_s: f64,
    open_ms: f64,
    stats: Vec<(String, f64)>,
}

impl Point {
    fn get(&self, k: &str) -> f64 {
        self.stats
            .iter()
            .find(|(n, _)| n == k)
            .map_or(f64::NAN, |(_, v)| *v)
    }
}

/// The cell counts measured: the default sizes up to `max_cells`, plus `max_cells` itself when
/// it is larger than all of them.
fn targets(quick: bool, max_cells: Option<u64>) -> Vec<u64> {
    let mut t: Vec<u64> = if quick {
        vec![300_000, 1_000_000]
    } else {
        vec![1_000_000, 10_000_000, 100_000_000, 1_000_000_000]
    };
    if let Some(max) = max_cells {
        t.retain(|&c| c <= max);
        if t.last().is_none_or(|&c| c < max) {
            t.push(max);
        }
    }
    t
}

/// Runs the section.
pub fn run(ctx: &Ctx) -> anyhow::Result<String> {
    let start = Instant::now();
    let targets = targets(ctx.cfg.quick, ctx.cfg.max_cells);
    let compare_at = if ctx.cfg.quick {
        targets.last().copied()
    } else {
        targets.iter().copied().find(|&c| c == 100_000_000)
    };
    let bvh_cfg = BvhBenchConfig {
        chunks: vec![usize::MAX, CHUNK_REFS],
        methods: vec![BuildMethod::Morton, BuildMethod::Ploc],
        runs: if ctx.cfg.quick { 3 } else { 7 },
        size: (256, 256),
        shadows: true,
        ao: 2,
    };
    let mut points = Vec::new();
    let mut bvh_table = None;
    for &target in &targets {
        let base = SynthParams::default();
        let (params, cells) = fit_cells(&Case::Blobs, &base, target, true, u64::MAX)?;
        if points.last().is_some_and(|p: &Point| p.cells == cells) {
            continue;
        }
        let path = ctx.scratch.join(format!("scale-{target}.amrk"));
        eprintln!("bench suite: scale: synthesizing {target} cells");
        let sum = write_synth(
            &path,
            Case::Blobs,
            &params,
            WriterOptions::default(),
            &NoProgress,
        )
        .map_err(|e| e.in_file(&path))?;
        let (open, _, _) = open_time(&path, 5)?;
        eprintln!("bench suite: scale: rendering {target} cells");
        let stats = scale_render::measure(ctx.cfg.render_exe.as_deref(), &path, ISO)?;
        if compare_at == Some(target) {
            eprintln!("bench suite: scale: BVH in chunks against one BVH at {target} cells");
            bvh_table = Some((sum.write.cells, table(&compare(&path, ISO, &bvh_cfg)?)));
        }
        points.push(Point {
            cells: sum.write.cells,
            file_bytes: sum.write.file_bytes,
            synth_s: sum.seconds,
            open_ms: open.as_secs_f64() * 1e3,
            stats,
        });
        let _ = std::fs::remove_file(&path);
    }
    // What the peak RSS holds beside the refs and the BVH. The model's constant is the rest at
    // the second-largest size, so that the largest size tests the model.
    let rest = |p: &Point| p.get("peak_rss_bytes") - p.get("refs_bytes") - p.get("bvh_bytes");
    let constant = points
        .iter()
        .rev()
        .nth(1)
        .or(points.last())
        .map_or(f64::NAN, rest);

    let xs = |f: &dyn Fn(&Point) -> f64| -> Vec<(f64, f64)> {
        points.iter().map(|p| (p.cells as f64, f(p))).collect()
    };
    loglog(
        &ctx.img.join("scale-time.png"),
        "blobs: cost against cell count",
        "cells",
        "seconds",
        &[
            Series {
                label: "synthesis".into(),
                points: xs(&|p| p.synth_s),
            },
            Series {
                label: "open (median of 5)".into(),
                points: xs(&|p| p.open_ms / 1e3),
            },
            Series {
                label: "extraction".into(),
                points: xs(&|p| p.get("extract_ms") / 1e3),
            },
            Series {
                label: "BVH build".into(),
                points: xs(&|p| p.get("bvh_ms") / 1e3),
            },
            Series {
                label: "frame 256x256".into(),
                points: xs(&|p| p.get("render_ms") / 1e3),
            },
        ],
    )?;
    loglog(
        &ctx.img.join("scale-memory.png"),
        "blobs: memory against cell count",
        "cells",
        "bytes",
        &[
            Series {
                label: "file".into(),
                points: xs(&|p| p.file_bytes as f64),
            },
            Series {
                label: "peak RSS of the render".into(),
                points: xs(&|p| p.get("peak_rss_bytes")),
            },
            Series {
                label: "refs + BVH + constant (rest at the second-largest size)".into(),
                points: xs(&|p| p.get("refs_bytes") + p.get("bvh_bytes") + constant),
            },
            Series {
                label: "peak resident bytes of the map".into(),
                points: xs(&|p| p.get("mapped_resident_peak_bytes")),
            },
            Series {
                label: "refs + BVH".into(),
                points: xs(&|p| p.get("refs_bytes") + p.get("bvh_bytes")),
            },
        ],
    )?;

    let (renderer, process) = match ctx.cfg.render_exe {
        Some(_) => (
            format!("a child `amr-bench {CHILD_COMMAND} FILE --iso {ISO}`"),
            "the child's",
        ),
        None => (
            "the suite's own process (no child executable given)".to_owned(),
            "the whole suite process's",
        ),
    };
    let mut s = String::new();
    writeln!(s, "## Scale\n")?;
    s.push_str(&ctx.provenance());
    writeln!(
        s,
        "\nThe `blobs` case fitted to each cell count (`amr-convert synth blobs --cells N`, 3 \
         levels, uncompressed), written to a scratch directory, opened 5 times (median), then \
         rendered once at 256x256 (no AO, no shadows) by {renderer}, which runs the scene \
         pipeline of `amr-render FILE --iso {ISO} --size 256x256 --ao 0 --no-shadows` and whose \
         statistics (the keys of its `--stats-json`) fill the table. Extraction, BVH and frame \
         times are single runs.\n"
    )?;
    writeln!(
        s,
        "Peak RSS is {process} `VmHWM`: its anonymous memory plus the pages of the map it has \
         resident. The renderer drops the map's pages from its resident set \
         (`madvise(MADV_DONTNEED)`; they stay in the page cache) after each chunk of 4096 kd \
         leaves in the extraction, after each chunk of {CHUNK_REFS} refs in the BVH build (one BVH \
         per chunk under a top-level BVH, which bounds the build scratch), and before the frame. \
         *Map peak* is the most map bytes measured resident at one of those points \
         (`/proc/self/smaps`), *map after frame* what the frame touched. *Rest* is peak RSS minus \
         refs and BVH (8 bytes per active octant plus the nodes); the plot's model line is refs + \
         BVH + the rest at the second-largest size, so the largest size tests the model.\n"
    )?;
    writeln!(
        s,
        "| cells | file bytes | synth s | open ms | extract s | BVH s | frame s | active octants | refs+BVH bytes | peak RSS | rest | map peak | map after frame |"
    )?;
    writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|---|---|")?;
    for p in &points {
        writeln!(
            s,
            "| {} | {} | {:.2} | {:.3} | {:.3} | {:.3} | {:.3} | {} | {} | {} | {} | {} | {} |",
            p.cells,
            p.file_bytes,
            p.synth_s,
            p.open_ms,
            p.get("extract_ms") / 1e3,
            p.get("bvh_ms") / 1e3,
            p.get("render_ms") / 1e3,
            p.get("active_octants"),
            p.get("refs_bytes") + p.get("bvh_bytes"),
            p.get("peak_rss_bytes"),
            rest(p),
            p.get("mapped_resident_peak_bytes"),
            p.get("mapped_resident_bytes")
        )?;
    }
    let mem = ctx.machine.mem_bytes;
    match points.last() {
        Some(p) if mem > 0 && p.file_bytes > mem => writeln!(
            s,
            "\nThe largest file ({:.1} GiB) is larger than this machine's memory ({:.1} GiB).\n",
            p.file_bytes as f64 / f64::from(1u32 << 30),
            mem as f64 / f64::from(1u32 << 30)
        )?,
        _ => writeln!(
            s,
            "\nThe file larger than memory is left out of this run: `amr-bench suite --out \
             docs --scale-only --max-cells 8e9 --scratch DIR` adds it (about 32 GB in DIR and \
             about an hour on 2 cores).\n"
        )?,
    }
    if let Some((cells, t)) = bvh_table {
        writeln!(
            s,
            "BVH in chunks of {CHUNK_REFS} refs against one BVH over all refs, each built in \
             Morton order (the renderer's build) and with obvhs's PLOC and CWBVH conversion, on \
             the {cells}-cell file at iso {ISO}: `amr-bench bvh FILE --iso {ISO} --chunks \
             0,{CHUNK_REFS} --methods morton,ploc --runs {} --size 256x256 --shadows --ao 2` (one \
             extraction; the four BVHs render in turns, median of the runs; each BVH's first frame starts with the map's pages \
             released, as in a render, and is also shown alone; the frames are compared bit for \
             bit).\n",
            bvh_cfg.runs
        )?;
        writeln!(s, "{t}")?;
    }
    writeln!(
        s,
        "![time against cells]({})\n",
        img_link(ctx, "scale-time.png")
    )?;
    writeln!(
        s,
        "![memory against cells]({})\n",
        img_link(ctx, "scale-memory.png")
    )?;
    writeln!(
        s,
        "_Scale section: {:.0} s._\n",
        start.elapsed().as_secs_f64()
    )?;
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::targets;

    #[test]
    fn max_cells_trims_or_extends_the_sizes() {
        assert_eq!(targets(false, None).len(), 4);
        assert_eq!(
            targets(false, Some(8_000_000_000)).last(),
            Some(&8_000_000_000)
        );
        assert_eq!(targets(false, Some(8_000_000_000)).len(), 5);
        assert_eq!(
            targets(false, Some(10_000_000)),
            vec![1_000_000, 10_000_000]
        );
        assert_eq!(targets(true, Some(500_000)), vec![300_000, 500_000]);
    }
}
