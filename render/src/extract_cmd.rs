//! `amr-render extract`: active-voxel extraction for one or more isovalues, with statistics.

use std::path::PathBuf;

use anyhow::{bail, Context};
use clap::Args;

use crate::extract::{ExtractStats, Extractor};
use crate::mapping::{open_mapped, PageRelease};

/// Arguments of `amr-render extract`.
#[derive(Args, Debug, Clone)]
pub struct ExtractArgs {
    /// The .amrk file.
    pub file: PathBuf,
    /// The field to extract from (default: the file's first field).
    #[arg(long)]
    pub field: Option<String>,
    /// An isovalue; repeat for several (the file is opened once, each isovalue re-runs only the
    /// extraction).
    #[arg(long = "iso", required = true, allow_negative_numbers = true)]
    pub iso: Vec<f32>,
    /// Runs per isovalue; the statistics of each run are reported.
    #[arg(long, default_value_t = 1)]
    pub runs: usize,
    /// Budget of the decompressed-brick cache in MiB (compressed files only).
    #[arg(long, default_value_t = 2048)]
    pub cache_mib: usize,
    /// Writes the statistics of every run as a JSON array to this file.
    #[arg(long)]
    pub stats_json: Option<PathBuf>,
}

/// Opens the file once and extracts every isovalue in turn, printing one line of statistics
/// per run.
pub fn run_extract(args: &ExtractArgs) -> anyhow::Result<()> {
    crate::output::check_outputs(&args.file, &[args.stats_json.as_deref()])?;
    let file = open_mapped(&args.file)?;
    let field = match &args.field {
        None => 0,
        Some(name) => match file.field_index(name) {
            Some(i) => i,
            None => {
                let names: Vec<&str> = file.fields().iter().map(|f| f.name.as_str()).collect();
                bail!(
                    "{}: no field '{name}' (fields: {})",
                    args.file.display(),
                    names.join(", ")
                )
            }
        },
    };
    if let Some(bad) = args.iso.iter().find(|v| !v.is_finite()) {
        bail!("isovalue {bad} is not a finite number");
    }
    let pages = PageRelease::new(&file);
    let mut extractor = Extractor::new(&file, field, args.cache_mib << 20)
        .with_context(|| format!("preparing {}", args.file.display()))?;
    extractor.set_page_release(&pages);
    let mut all: Vec<ExtractStats> = Vec::new();
    for &iso in &args.iso {
        for _ in 0..args.runs.max(1) {
            let result = extractor
                .extract(iso)
                .with_context(|| format!("extracting iso {iso}"))?;
            println!("{}", result.stats);
            all.push(result.stats);
        }
    }
    if let Some(path) = &args.stats_json {
        let body: Vec<String> = all.iter().map(|s| s.to_json()).collect();
        std::fs::write(path, format!("[\n{}\n]\n", body.join(",\n")))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
