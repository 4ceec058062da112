//! `amr-render demo`: synthesizes a small multi-level dataset (two merging blobs on three
//! levels, and a second field `swirl`), writes it to a temporary `.amrk` file and renders what
//! the tool does: the blobs' surface coloured by `swirl`, a transparent outer surface, the AMR
//! boxes of every level, and a PNG preview with its legend beside the EXR frame.

use std::path::PathBuf;

use amr_format::Compression;
use amr_render::output::exr_file::ExrCompression;
use amr_render::shade::IsoSpec;
use amr_render::{ColorBy, Outline, Reconstruction, SceneOptions, TraceMethod, View};
use amr_synth::{build_hierarchy, write_fields, AnalyticField, Case, SynthParams};
use anyhow::Context;

use crate::animation::Animation;
use crate::frames::render_all;
use crate::render_args::{Outputs, RenderRequest};
use crate::surface_arg::SurfaceArg;

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
    let mut spec = build_hierarchy(&Case::Blobs, "blobs", &params)?;
    spec.fields = vec!["blobs".into(), "swirl".into()];
    let blobs = |p: [f64; 3]| Case::Blobs.value(p);
    let swirl = |p: [f64; 3]| swirl(p);
    write_fields(
        &path,
        spec,
        &[&blobs, &swirl],
        amr_render::extract::writer_options(Compression::None),
    )
    .with_context(|| format!("cannot write {}", path.display()))?;
    let iso = Case::Blobs.default_iso() as f32;
    let preview = args.output.with_extension("png");
    let request = RenderRequest {
        files: vec![path],
        scene: SceneOptions {
            field: Some("blobs".into()),
            reconstruction: Reconstruction::Octant,
            method: TraceMethod::Hybrid,
            release_pages: true,
        },
        isos: vec![
            SurfaceArg::of_scene_field(IsoSpec {
                value: iso,
                color: Some([0.85, 0.62, 0.35]),
                opacity: 1.0,
                field: None,
            }),
            SurfaceArg::of_scene_field(IsoSpec {
                value: 0.6 * iso,
                color: Some([0.35, 0.55, 0.85]),
                opacity: 0.3,
                field: None,
            }),
        ],
        no_isosurface: false,
        view: View {
            fov_deg: 35.0,
            size: (800, 600),
            outline: Outline::Boxes,
            ..View::default()
        },
        outputs: Outputs {
            exr: args.output.clone(),
            preview: Some(preview.clone()),
            legend: true,
            exr_compression: ExrCompression::default(),
            print_stats: false,
            stats_json: None,
            summary: true,
            movie: None,
        },
        threads: None,
        animation: Animation::new(1, None, None, Vec::new())?,
        color_by: vec![Some(ColorBy::Field("swirl".into())), None],
        slices: Vec::new(),
        slice_field: None,
        frame_domain: false,
        series_color_range: false,
        clip: None,
        extract_in_view: false,
    };
    render_all(&request)
}

/// The demo's second field: a flow swirling about the z axis through the domain's centre, faster
/// away from the axis and upwards.
fn swirl(p: [f64; 3]) -> f64 {
    let (x, y) = (p[0] - 0.5, p[1] - 0.5);
    (x * x + y * y).sqrt() * (1.0 + 2.0 * p[2]) * (1.0 + 0.3 * (6.0 * y.atan2(x)).sin())
}
