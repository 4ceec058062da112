//! `amr-bench boxes -o F.amrk`: writes a hierarchy of many small irregular boxes with mixed
//! ratios (`amr_synth::boxes`), the extraction stress case.

use std::path::PathBuf;

use amr_format::box_join::{join_bricks, max_open};
use amr_format::progress::NoProgress;
use amr_format::Compression;
use amr_synth::{build_box_hierarchy, stream::cells_per_level, write_spec, BoxParams, Case};
use anyhow::Context;
use clap::Args;

/// Arguments of `amr-bench boxes`.
#[derive(Args, Debug)]
pub struct BoxesArgs {
    /// Analytic case: blobs, sphere or ripple.
    #[arg(long, default_value = "blobs")]
    case: String,
    /// Output .amrk file.
    #[arg(short, long)]
    output: PathBuf,
    /// Cells per axis of level 0.
    #[arg(long, default_value_t = 32)]
    base: u32,
    /// Refinement ratio from each level to the next, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "2,4,2")]
    ratios: Vec<u32>,
    /// Smallest and largest box extent along an axis, as MIN,MAX (cells of the box's level).
    #[arg(long, value_delimiter = ',', default_value = "2,16")]
    sizes: Vec<u32>,
    /// Seed of the box extents.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Then cut every box into pieces of MIN,MAX cells per axis: the same levels and cells in
    /// more, smaller boxes (compare with the file written without it).
    #[arg(long, value_delimiter = ',')]
    pieces: Option<Vec<u32>>,
    /// Then join runs of boxes close together in their order that fill a box of at most N cells
    /// per axis into one brick, as `amr-convert` joins a dump's boxes (N = 16 unless
    /// `--brick` is smaller; `--keep-boxes` turns it off).
    #[arg(long, value_name = "N")]
    join: Option<u32>,
}

/// Writes the file and prints a one-line summary.
pub fn run(args: &BoxesArgs) -> anyhow::Result<()> {
    let case: Case = args.case.parse().map_err(anyhow::Error::msg)?;
    let [min, max] = args.sizes[..] else {
        anyhow::bail!("--sizes takes MIN,MAX, not {:?}", args.sizes);
    };
    let pieces = match args.pieces.as_deref() {
        None => None,
        Some(&[min, max]) => Some((min, max)),
        Some(other) => anyhow::bail!("--pieces takes MIN,MAX, not {other:?}"),
    };
    let params = BoxParams {
        base: args.base,
        ratios: args.ratios.clone(),
        sizes: (min, max),
        seed: args.seed,
        pieces,
    };
    let mut spec = build_box_hierarchy(&case, case.name(), &params)?;
    if let Some(n) = args.join {
        let n = i64::from(n.max(1));
        spec.bricks = join_bricks(&spec.bricks, n, max_open(n, spec.fields.len()));
    }
    let per_level = cells_per_level(&spec);
    let finest = spec.levels.len() as u32 - 1;
    let finest_boxes = spec.bricks.iter().filter(|b| b.level == finest).count();
    let s = write_spec(
        &args.output,
        spec,
        &case,
        amr_render::extract::writer_options(Compression::None),
        &NoProgress,
    )
    .with_context(|| format!("writing {}", args.output.display()))?;
    println!(
        "{}: {case}, cells per level {per_level:?} = {} cells, {} boxes ({finest_boxes} on the finest level), {} kd leaves",
        args.output.display(),
        s.cells,
        s.bricks,
        s.leaves
    );
    Ok(())
}
