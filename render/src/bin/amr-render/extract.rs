//! `amr-render extract FILE --iso [FIELD=]V...`: active-voxel extraction for one or more
//! isovalues, of one or more fields, of one open file, with one line of statistics per run.

use std::io::Write;
use std::path::PathBuf;

use amr_render::extract::{ExtractStats, Extractor, Region};
use amr_render::mapping::{open_mapped, PageRelease};
use amr_render::reconstruct::Grid;
use amr_render::scene::field_named;
use amr_render::trace::GridFrame;
use amr_render::ClipBox;
use anyhow::{bail, Context};
use serde::Serialize;

use crate::iso_value::IsoValue;
use crate::outputs::{is_stdout, write_json};
use crate::render_args::MAX_THREADS;
use crate::surface_arg::split_field;

/// Arguments of `amr-render extract`.
#[derive(clap::Args, Debug, Clone)]
pub struct ExtractArgs {
    /// The .amrk file.
    pub file: PathBuf,
    /// The field to extract from (default: the file's first field).
    #[arg(long)]
    pub field: Option<String>,
    /// An isovalue, `V` of `--field` or `FIELD=V` of another field, `V` a number or pQ (the
    /// field's Q-th percentile over every cell); repeat for several (the file is opened once,
    /// each isovalue re-runs only the extraction).
    #[arg(
        long = "iso",
        required = true,
        allow_hyphen_values = true,
        value_name = "[FIELD=]V"
    )]
    pub iso: Vec<ExtractIso>,
    /// Runs per isovalue; the statistics of each run are reported.
    #[arg(long, default_value_t = 1,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=100_000))]
    pub runs: usize,
    /// Budget of the decompressed-brick cache in MiB, per field extracted (compressed files
    /// only).
    #[arg(long, default_value_t = 2048)]
    pub cache_mib: usize,
    /// Extracts only the voxels that meet this box (world coordinates), as `--clip` of a render.
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", allow_hyphen_values = true)]
    pub clip: Option<String>,
    /// Writes the statistics of every run as a JSON array to this file (`-`: to standard
    /// output, the lines for people then going to standard error).
    #[arg(long)]
    pub stats_json: Option<PathBuf>,
    /// Worker threads (default: all cores), as `--threads` of a render.
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
}

/// An isovalue of `amr-render extract`: `V`, or `FIELD=V` for another field than `--field`;
/// `V` a number or a percentile (`p99`).
#[derive(Clone, Debug, PartialEq)]
pub struct ExtractIso {
    /// The field's name, as typed before `=`.
    pub field: Option<String>,
    /// The isovalue as typed.
    pub value: IsoValue,
}

impl std::str::FromStr for ExtractIso {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let (field, rest) = split_field(s)?;
        Ok(ExtractIso {
            field,
            value: rest.parse()?,
        })
    }
}

/// One run's statistics with the rates derived from them.
#[derive(Serialize)]
struct ExtractRecord<'a> {
    #[serde(flatten)]
    stats: &'a ExtractStats,
    cells_per_core_second: f64,
    active_per_second: f64,
}

/// Opens the file once and extracts every isovalue in turn, on `--threads` workers.
pub fn run(args: &ExtractArgs) -> anyhow::Result<()> {
    match args.threads {
        Some(n) if n == 0 || n > MAX_THREADS => {
            bail!("--threads {n} must be between 1 and {MAX_THREADS}")
        }
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()?
            .install(|| extract_all(args)),
        None => extract_all(args),
    }
}

/// [`run`] on the current thread pool.
fn extract_all(args: &ExtractArgs) -> anyhow::Result<()> {
    let clip = match &args.clip {
        Some(text) => Some(
            text.parse::<ClipBox>()
                .map_err(|e| anyhow::anyhow!("--clip: {e}"))?,
        ),
        None => None,
    };
    if let Some(out) = args.stats_json.as_ref().filter(|p| !is_stdout(p)) {
        amr_format::output::check_output(out, &[&args.file])?;
    }
    // With the statistics on standard output, the lines for people go to standard error.
    let json_on_stdout = args.stats_json.as_deref().is_some_and(is_stdout);
    let file = open_mapped(&args.file)?;
    let field_of = |name: Option<&String>| match name {
        None => Ok(0),
        Some(name) => field_named(&file, name).map_err(|e| e.in_file(&args.file)),
    };
    let default_field = field_of(args.field.as_ref())?;
    // Every field named is checked before the first extraction.
    let fields = args
        .iso
        .iter()
        .map(|iso| match &iso.field {
            None => Ok(default_field),
            named => field_of(named.as_ref()),
        })
        .collect::<Result<Vec<usize>, _>>()?;
    // One extractor per field, made when its first isovalue comes.
    let mut extractors: Vec<Option<Extractor<'_, _>>> = Vec::new();
    extractors.resize_with(file.fields().len(), || None);
    let frame = GridFrame::of_grid(&Grid::new(&file));
    let mut region = Region::default();
    if let Some(c) = clip {
        c.check_overlaps(&frame)
            .map_err(|e| e.in_file(&args.file))?;
        region.bounds = Some(c.to_grid(&frame));
    }
    let mut all: Vec<ExtractStats> = Vec::new();
    for (iso, &field) in args.iso.iter().zip(&fields) {
        let extractor = match &mut extractors[field] {
            Some(made) => made,
            slot => {
                let mut made = Extractor::new(&file, field, args.cache_mib << 20)
                    .map_err(|e| e.in_file(&args.file))?;
                made.set_page_release(PageRelease::new(&file));
                slot.insert(made)
            }
        };
        let iso = iso.value.resolve(&file, &args.file, field)?;
        for _ in 0..args.runs {
            let result = extractor
                .extract_in(iso, &region)
                .map_err(|e| e.in_file(&args.file))
                .with_context(|| format!("extracting iso {iso}"))?;
            match json_on_stdout {
                true => eprintln!("{}", result.stats),
                false => writeln!(std::io::stdout(), "{}", result.stats)?,
            }
            all.push(result.stats);
        }
    }
    if let Some(path) = &args.stats_json {
        let records: Vec<ExtractRecord> = all
            .iter()
            .map(|stats| ExtractRecord {
                stats,
                cells_per_core_second: stats.cells_per_core_second(),
                active_per_second: stats.active_per_second(),
            })
            .collect();
        write_json(path, &records)?;
    }
    Ok(())
}
