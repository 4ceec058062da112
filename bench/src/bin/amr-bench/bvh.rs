//! `amr-bench bvh FILE --iso V`: the BVH in chunks against one BVH over all refs, side by side.

use std::path::PathBuf;

use amr_bench::bvh::{compare, table, BvhBenchConfig};
use amr_render::bvh::BuildMethod;
use clap::Args;

/// Arguments of `amr-bench bvh`.
#[derive(Args, Debug)]
pub struct BvhArgs {
    /// The .amrk file (its first field is used).
    file: PathBuf,
    /// The isovalue.
    #[arg(long, allow_negative_numbers = true)]
    iso: f32,
    /// Refs per chunk of each variant, comma-separated; 0 is one BVH over all refs.
    #[arg(long, value_delimiter = ',', default_value = "0,65536")]
    chunks: Vec<usize>,
    /// Build methods of each chunk size, comma-separated: `morton` (the renderer's), `ploc`
    /// (obvhs's PLOC and CWBVH conversion).
    #[arg(long, value_delimiter = ',', default_value = "morton,ploc", value_parser = parse_method)]
    methods: Vec<BuildMethod>,
    /// Frames per variant (the variants take turns).
    #[arg(long, default_value_t = 5)]
    runs: usize,
    /// Image size.
    #[arg(long, value_name = "WxH", default_value = "512x512", value_parser = parse_size)]
    size: (u32, u32),
    /// Cast shadow rays.
    #[arg(long)]
    shadows: bool,
    /// Ambient-occlusion rays per hit.
    #[arg(long, default_value_t = 0)]
    ao: u32,
}

/// A build method's name.
fn parse_method(s: &str) -> Result<BuildMethod, String> {
    match s.trim() {
        "morton" => Ok(BuildMethod::Morton),
        "ploc" => Ok(BuildMethod::Ploc),
        _ => Err(format!("build method '{s}' is not morton or ploc")),
    }
}

/// An image size `WxH`.
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("size '{s}' is not WxH");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    match (w.trim().parse(), h.trim().parse()) {
        (Ok(w), Ok(h)) => Ok((w, h)),
        _ => Err(bad()),
    }
}

/// Measures the variants and prints the table.
pub fn run(args: &BvhArgs) -> anyhow::Result<()> {
    if !args.iso.is_finite() {
        anyhow::bail!("isovalue {} is not a finite number", args.iso);
    }
    let cfg = BvhBenchConfig {
        chunks: args
            .chunks
            .iter()
            .map(|&c| if c == 0 { usize::MAX } else { c })
            .collect(),
        methods: args.methods.clone(),
        runs: args.runs,
        size: args.size,
        shadows: args.shadows,
        ao: args.ao,
    };
    print!("{}", table(&compare(&args.file, args.iso, &cfg)?));
    Ok(())
}
