//! The renderer as a library: one scene, several views, two isovalues.
//!
//! ```sh
//! cargo run --release -p amr-render --example views -- OUT_DIR
//! ```
//!
//! Writes a small synthetic file (two merging blobs on three levels), opens it once as a
//! [`Scene`], renders it from three cameras, changes one of its two isovalues (only that surface
//! is extracted and built again) and renders once more. Each frame is an EXR with a PNG preview;
//! the timings printed show that a new camera costs a frame and no extraction.

use std::path::PathBuf;

use amr_format::progress::NoProgress;
use amr_format::WriterOptions;
use amr_render::output::exr_file::write_exr;
use amr_render::output::header::frame_header;
use amr_render::output::png_preview::write_preview;
use amr_render::{render, CameraPlacement, IsoSpec, Scene, SceneOptions, View};
use amr_synth::{write_synth, Case, SynthParams};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "views-out".into()),
    );
    std::fs::create_dir_all(&out)?;
    let file = out.join("blobs.amrk");
    let params = SynthParams::unit_cube(3, 2, 32, 16);
    write_synth(
        &file,
        Case::Blobs,
        &params,
        WriterOptions::default(),
        &NoProgress,
    )?;

    // Open once; the scene owns the mapped file, the field and its reconstruction.
    let mut scene = Scene::open(&file, &SceneOptions::default())?;
    let gold = IsoSpec {
        value: 10.0,
        color: Some([0.85, 0.62, 0.35]),
        opacity: 1.0,
        field: None,
    };
    let glass = IsoSpec {
        value: 6.0,
        color: Some([0.35, 0.55, 0.85]),
        opacity: 0.3,
        field: None,
    };
    let stats = scene.set_isosurfaces(&[gold, glass])?;
    println!(
        "two surfaces: {} active voxels, extraction {:.1} ms, BVH {:.1} ms",
        stats.active_octants,
        stats.extract.as_secs_f64() * 1e3,
        stats.bvh.as_secs_f64() * 1e3
    );

    let cameras = [[1.3, -0.2, 0.9], [-0.1, 1.4, 0.8], [0.5, 0.5, 1.6]];
    for (k, pos) in cameras.into_iter().enumerate() {
        let view = View {
            camera: Some(CameraPlacement {
                pos,
                look_at: Some([0.5, 0.5, 0.5]),
                up: None,
            }),
            size: (480, 360),
            ..View::default()
        };
        let frame = render(&scene, &view, &|_rows| {})?;
        let name = out.join(format!("view{k}.exr"));
        write_exr(&name, &frame.frame, &frame_header(&scene, &frame, &[]))?;
        write_preview(
            &name.with_extension("png"),
            &frame.frame,
            &Default::default(),
        )?;
        println!(
            "view {k}: {:.1} ms, {} rays, {} pixels covered -> {}",
            frame.stats.render.as_secs_f64() * 1e3,
            frame.stats.rays,
            frame.stats.covered_pixels,
            name.display()
        );
    }

    // A new inner isovalue: the transparent surface is kept, the opaque one rebuilt.
    let inner = IsoSpec {
        value: 14.0,
        ..gold
    };
    let stats = scene.set_isosurfaces(&[inner, glass])?;
    println!(
        "isovalue 10 -> 14: {} surface(s) rebuilt, extraction {:.1} ms, BVH {:.1} ms",
        stats.surfaces_built,
        stats.extract.as_secs_f64() * 1e3,
        stats.bvh.as_secs_f64() * 1e3
    );
    let view = View {
        size: (480, 360),
        ..View::default()
    };
    let frame = render(&scene, &view, &|_rows| {})?;
    let name = out.join("iso14.exr");
    write_exr(&name, &frame.frame, &frame_header(&scene, &frame, &[]))?;
    write_preview(
        &name.with_extension("png"),
        &frame.frame,
        &Default::default(),
    )?;
    println!(
        "iso 14: {:.1} ms -> {}",
        frame.stats.render.as_secs_f64() * 1e3,
        name.display()
    );
    Ok(())
}
