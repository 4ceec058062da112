//! `amr-render demo`: synthesizes a small multi-level dataset (two merging blobs on three
//! levels), converts it to a temporary `.amrk` file and renders two isosurfaces of it, one
//! transparent, with a PNG preview beside the EXR frame.

use std::path::PathBuf;

use amr_format::progress::NoProgress;
use amr_format::WriterOptions;
use amr_render::shade::IsoSpec;
use amr_render::{Reconstruction, SceneOptions, TraceMethod, View};
use amr_synth::{write_synth, AnalyticField, Case, SynthParams};
use anyhow::Context;

use crate::animation::Animation;
use crate::frames::render_all;
use crate::render_args::{Outputs, RenderRequest};

/// Arguments of `amr-render demo`.
#[derive(clap::Args, Debug)]
pub struct DemoArgs {
    /// The EXR frame to write (a PNG preview is written beside it).
    #[arg(short, long, default_value = "demo.exr")]
    output: PathBuf,
}

/// Runs the demo.
pub fn run(args: &DemoArgs) -> anyhow::Result<()> {
    let dir = tempfile::Builder::new()
        .prefix("amr-render-demo-")
        .tempdir()
        .context("cannot create a temporary directory")?;
    let path = dir.path().join("demo.amrk");
    let params = SynthParams::unit_cube(3, 2, 32, 16);
    write_synth(&path, Case::Blobs, &params, WriterOptions::default(), &NoProgress)
        .with_context(|| format!("cannot write {}", path.display()))?;
    let iso = Case::Blobs.default_iso() as f32;
    let preview = args.output.with_extension("png");
    let request = RenderRequest {
        files: vec![path],
        scene: SceneOptions {
            field: None,
            reconstruction: Reconstruction::Octant,
            method: TraceMethod::Hybrid,
            release_pages: true,
        },
        isos: vec![
            IsoSpec {
                value: iso,
                color: Some([0.85, 0.62, 0.35]),
                opacity: 1.0,
            },
            IsoSpec {
                value: 0.6 * iso,
                color: Some([0.35, 0.55, 0.85]),
                opacity: 0.3,
            },
        ],
        view: View {
            fov_deg: 35.0,
            size: (800, 600),
            ..View::default()
        },
        outputs: Outputs {
            exr: args.output.clone(),
            preview: Some(preview.clone()),
            print_stats: true,
            stats_json: None,
            movie: None,
        },
        threads: None,
        animation: Animation::new(1, None, None, Vec::new())?,
    };
    render_all(&request)?;
    eprintln!("wrote {} and {}", args.output.display(), preview.display());
    Ok(())
}
