//! Noise of ambient occlusion at a few rays per hit: the RMS difference of a frame's colour from
//! the same frame with 256 AO rays per hit.
//!
//! ```sh
//! cargo run --release -p amr-render --example ao_noise -- OUT_DIR [AO_RAYS[f]...]
//! ```
//!
//! Writes a small synthetic file (two blobs on three levels, an opaque and a transparent
//! surface, as the demo), renders it at 512x384 with shadows and each number of AO rays given
//! (default 1, 4, 16; `4f` is 4 rays filtered across pixels, `4` without the filter), and
//! prints the RMS and the largest colour difference from the reference (256 rays, no filter)
//! over the pixels the surfaces cover, and the ray queries of the frame.

use std::path::PathBuf;

use amr_format::progress::NoProgress;
use amr_format::WriterOptions;
use amr_render::output::png_preview::write_preview;
use amr_render::{render, CameraPlacement, IsoSpec, Rendered, Scene, SceneOptions, View};
use amr_synth::{write_synth, Case, SynthParams};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(args.next().unwrap_or_else(|| "ao-noise-out".into()));
    let counts: Vec<(u32, bool)> = args
        .map(|a| match a.strip_suffix('f') {
            Some(n) => n.parse().map(|n| (n, true)),
            None => a.parse().map(|n| (n, false)),
        })
        .collect::<Result<_, _>>()?;
    let counts = if counts.is_empty() {
        vec![(1, false), (4, false), (16, false)]
    } else {
        counts
    };
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
    let mut scene = Scene::open(&file, &SceneOptions::default())?;
    scene.set_isosurfaces(&[
        IsoSpec {
            value: 10.0,
            color: Some([0.85, 0.62, 0.35]),
            opacity: 1.0,
            field: None,
        },
        IsoSpec {
            value: 6.0,
            color: Some([0.35, 0.55, 0.85]),
            opacity: 0.3,
            field: None,
        },
    ])?;
    let view = |ao_rays: u32, ao_filter: bool| View {
        camera: Some(CameraPlacement {
            pos: [1.3, -0.2, 0.9],
            look_at: None,
            up: None,
        }),
        size: (512, 384),
        ao_rays,
        ao_filter,
        ..View::default()
    };
    let reference = render(&scene, &view(256, false), &|_| ())?;
    write_preview(
        &out.join("ao_256.png"),
        &reference.frame,
        &Default::default(),
    )?;
    for (n, filtered) in counts {
        let frame = render(&scene, &view(n, filtered), &|_| ())?;
        let name = format!("ao_{n}{}", if filtered { "f" } else { "" });
        write_preview(
            &out.join(format!("{name}.png")),
            &frame.frame,
            &Default::default(),
        )?;
        let (rms, max) = difference(&frame, &reference);
        println!(
            "{name:>5}: RMS {rms:.5}, largest {max:.4} (colour, linear), {} ray queries",
            frame.stats.rays
        );
    }
    Ok(())
}

/// RMS and largest difference of the linear colour channels over the pixels either frame covers.
fn difference(a: &Rendered, b: &Rendered) -> (f64, f64) {
    let (fa, fb) = (&a.frame, &b.frame);
    let (mut sum, mut max, mut count) = (0.0f64, 0.0f64, 0u64);
    for i in 0..fa.alpha.len() {
        if fa.alpha[i] <= 0.0 && fb.alpha[i] <= 0.0 {
            continue;
        }
        for c in 0..3 {
            let d = f64::from(fa.rgb[c][i] - fb.rgb[c][i]);
            sum += d * d;
            max = max.max(d.abs());
            count += 1;
        }
    }
    ((sum / count.max(1) as f64).sqrt(), max)
}
