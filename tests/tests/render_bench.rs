//! Measurements for docs/benchmarks-render.md (ignored by default; run with
//! `cargo test --release -p amr-tests --test tests render_bench -- --ignored --nocapture`).

use std::time::Instant;

use crate::support::render::{render_grid_sampled, sphere_grid};
use amr_render::bvh::BvhBuilder;
use amr_render::render::render_surfaces;
use amr_render::shade::IsoSpec;
use amr_render::trace::Surface;
use amr_render::{CameraPlacement, View};

fn isos() -> Vec<IsoSpec> {
    vec![
        "0:gold".parse::<IsoSpec>().unwrap(),
        "0.45:#4080ff:0.35".parse::<IsoSpec>().unwrap(),
    ]
}

fn view(step: Option<f64>, ao_rays: u32) -> View {
    View {
        camera: Some(CameraPlacement {
            pos: [9.0, -5.0, 6.5],
            look_at: Some([2.0, 2.0, 2.0]),
            up: None,
        }),
        fov_deg: 30.0,
        size: (1024, 768),
        ao_rays,
        sample_step: step,
        ..View::default()
    }
}

/// Peak resident set of this process (`VmHWM`), kB as `/proc/self/status` gives it.
fn peak_rss() -> Option<String> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    Some(s.lines().find(|l| l.starts_with("VmHWM:"))?.to_string())
}

#[test]
#[ignore]
fn frame_times_and_memory() {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let t = Instant::now();
    let grid = sphere_grid(5, 3, 4, 1.3, [0.0; 3], 1.0);
    eprintln!(
        "grid: {} voxels, built in {:.2} s",
        grid.voxels().len(),
        t.elapsed().as_secs_f64()
    );
    let t = Instant::now();
    let mut builder = BvhBuilder::new();
    let surfaces: Vec<Surface> = isos()
        .iter()
        .map(|s| Surface::build_owned(&grid, s.value, grid.active(s.value), &mut builder))
        .collect();
    let bvh_time = t.elapsed();
    let active: u64 = surfaces.iter().map(|s| s.bvh.len() as u64).sum();
    let refs_bytes: u64 = surfaces.iter().map(|s| s.bvh.refs_bytes() as u64).sum();
    let bvh_bytes: u64 = surfaces.iter().map(|s| s.bvh.bvh_bytes() as u64).sum();
    let hybrid = render_surfaces(&grid, &surfaces, &isos(), &view(None, 0), &|_| {}).unwrap();
    let r = &hybrid.stats;
    let per = (refs_bytes + bvh_bytes) as f64 / active as f64;
    eprintln!(
        "hybrid 1024x768 shadows: {:.1} ms, {} ray queries, {:.2} M rays/s/core, {active} active voxels, \
         refs {refs_bytes} B + bvh {bvh_bytes} B = {per:.2} B/voxel, build scratch {} B ({:.1} B/voxel), bvh {:.2} ms",
        r.render.as_secs_f64() * 1e3,
        r.rays,
        r.rays as f64 / r.render.as_secs_f64() / threads as f64 / 1e6,
        builder.last_scratch_bytes,
        builder.last_scratch_bytes as f64 / active as f64,
        bvh_time.as_secs_f64() * 1e3
    );
    let ao = render_surfaces(&grid, &surfaces, &isos(), &view(None, 4), &|_| {}).unwrap();
    eprintln!(
        "hybrid 1024x768 shadows + 4 AO rays: {:.1} ms, {} ray queries",
        ao.stats.render.as_secs_f64() * 1e3,
        ao.stats.rays
    );
    for step in [0.1, 0.05, 0.02, 0.01, 0.005, 0.002] {
        let s = render_grid_sampled(&grid, &isos(), &view(Some(step), 0));
        let (a, b) = (&hybrid.frame, &s.frame);
        let mut coverage = 0;
        let mut zerr = 0.0f64;
        let mut n = 0;
        let mut worst = 0.0f64;
        for i in 0..a.len() {
            if (a.alpha[i] > 0.0) != (b.alpha[i] > 0.0) {
                coverage += 1;
            } else if a.alpha[i] > 0.0 {
                let e = f64::from((a.z[i] - b.z[i]).abs());
                zerr += e;
                worst = worst.max(e);
                n += 1;
            }
        }
        eprintln!(
            "sample step {step} (finest voxel 1/16 = 0.0625): {:.1} ms, coverage mismatches {coverage}, \
             mean |dZ| {:.2e}, max |dZ| {:.2e}",
            s.stats.render.as_secs_f64() * 1e3,
            zerr / n.max(1) as f64,
            worst
        );
    }
    eprintln!("peak RSS {:?}", peak_rss());
}

#[test]
#[ignore]
fn bvh_build_rate() {
    // Active voxels of sin(kx)sin(ky)sin(kz) = 0.3 on a 192^3 grid: refs are voxel indices.
    let n = 192u64;
    let k = 4.0 * std::f64::consts::PI / n as f64;
    let f =
        |i: u64, j: u64, l: u64| (k * i as f64).sin() * (k * j as f64).sin() * (k * l as f64).sin();
    let mut refs = Vec::new();
    for l in 0..n {
        for j in 0..n {
            for i in 0..n {
                let mut lo = f64::INFINITY;
                let mut hi = f64::NEG_INFINITY;
                for c in 0..8 {
                    let v = f(i + (c & 1), j + (c >> 1 & 1), l + (c >> 2));
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
                if lo <= 0.3 && 0.3 <= hi {
                    refs.push(i + n * (j + n * l));
                }
            }
        }
    }
    let bounds = move |r: u64| {
        let p = [r % n, (r / n) % n, r / (n * n)].map(|x| x as f64);
        (p, p.map(|x| x + 1.0))
    };
    let mut builder = BvhBuilder::new();
    for round in 0..3 {
        let rss0 = peak_rss();
        let t = Instant::now();
        let bvh = builder.build(&refs, 1e-3, bounds);
        let s = t.elapsed().as_secs_f64();
        eprintln!(
            "round {round}: {} voxels in {:.1} ms: {:.2} M voxels/s on {} threads; resident {:.2} B/voxel \
             (refs {} + nodes {}); scratch {:.1} B/voxel; peak RSS {:?} -> {:?}",
            refs.len(),
            s * 1e3,
            refs.len() as f64 / s / 1e6,
            std::thread::available_parallelism().map_or(1, |n| n.get()),
            (bvh.refs_bytes() + bvh.bvh_bytes()) as f64 / refs.len() as f64,
            bvh.refs_bytes(),
            bvh.bvh_bytes(),
            builder.last_scratch_bytes as f64 / refs.len() as f64,
            rss0,
            peak_rss()
        );
    }
}
