//! Stability stress: seeded random hierarchies, placements (large offsets, tiny cells), value
//! scales from 1e-30 to 1e30 and random cameras, traced by the hybrid (octant) tracer.
//!
//! The field is `scale * (1 + |p - c| - r)` with the isovalue `scale`, so the true surface is the
//! sphere of [`Case::Sphere`] whatever the scale. Half the rays start inside the sphere (every one
//! must hit: a miss is a leak); half start outside and are compared with a float64 ray-sphere
//! intersection (a miss is counted where the reference passes at least half a finest cell inside
//! the sphere's silhouette, a false hit where it passes half a cell outside).

use std::fmt::Write as _;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use amr_render::bvh::BvhBuilder;
use amr_render::mapping::open_mapped;
use amr_render::trace::{FieldSource, GridRay, HybridTracer, Surface, Tracer, VoxelSource};
use amr_render::Reconstruction;
use amr_synth::fields::{SPHERE_CENTRE, SPHERE_RADIUS};
use amr_synth::{build_hierarchy_by, near_surface, AnalyticField, Case, SynthParams};
use rayon::prelude::*;

use super::common::{hash2, write_dataset, Rng};
use super::Ctx;

/// Seed of every case.
const SEED: u64 = 0x57AE_5500;

/// `scale * (1 + sphere distance)`.
struct Scaled {
    scale: f64,
}

impl AnalyticField for Scaled {
    fn value(&self, p: [f64; 3]) -> f64 {
        self.scale * (1.0 + Case::Sphere.value(p))
    }
    fn gradient(&self, p: [f64; 3]) -> [f64; 3] {
        Case::Sphere.gradient(p).map(|g| g * self.scale)
    }
    fn default_iso(&self) -> f64 {
        self.scale
    }
}

#[derive(Default)]
struct Totals {
    rays: u64,
    inside_rays: u64,
    leaks: u64,
    outside_rays: u64,
    misses: u64,
    false_hits: u64,
    worst_hit: f64,
    worst_case: String,
}

/// Runs the section.
pub fn run(ctx: &Ctx) -> anyhow::Result<String> {
    let quick = ctx.cfg.quick;
    let cases: u64 = if quick { 6 } else { 40 };
    let rays_per_case: u64 = if quick { 30_000 } else { 250_000 };
    let mut tot = Totals::default();
    let mut lines = Vec::new();
    let start = Instant::now();
    for case in 0..cases {
        let mut r = Rng::new(SEED + case);
        let p = SynthParams {
            levels: 2 + (r.next_u64() % 3) as u32,
            ratio: 2,
            base: [8, 12, 16][(r.next_u64() % 3) as usize],
            brick: [4, 8][(r.next_u64() % 2) as usize],
            size: 10f64.powf(r.range(-6.0, 2.0)),
            origin: [0.0; 3],
        };
        let nf = p.cells_per_axis(p.levels - 1).unwrap_or(1) as f64;
        let finest_world = p.size / nf;
        // Offsets up to 1e10 finest cells, where a float64 world position still resolves a
        // millionth of a cell; beyond that a camera position itself cannot be represented.
        let max_off = (finest_world * 1e10).min(1e8);
        let origin = [0, 1, 2].map(|_| {
            let m = 10f64.powf(r.range(0.0, max_off.log10().max(0.0)));
            if r.f64() < 0.5 {
                -m
            } else {
                m
            }
        });
        let scale = 10f64.powf(r.range(-30.0, 30.0));
        let p = SynthParams { origin, ..p };
        let field = Scaled { scale };
        let rseed = SEED ^ (case << 20);
        let spec = build_hierarchy_by(&p, vec!["f".into()], |b| {
            let key =
                (b.cells.lo[0] as u64) << 42 ^ (b.cells.lo[1] as u64) << 21 ^ b.cells.lo[2] as u64;
            near_surface(&Case::Sphere, 0.0, b)
                && !hash2(rseed + u64::from(b.level), key).is_multiple_of(4)
        })?;
        let path = ctx.scratch.join(format!("stress-{case}.amrk"));
        write_dataset(&path, spec, &field)?;
        let file = open_mapped(&path)?;
        let src = FieldSource::new(&file, 0, Reconstruction::Octant)?;
        let iso = scale as f32;
        let refs = src.extract(iso)?.refs;
        let mut b = BvhBuilder::new();
        let surf = [Surface::build(&src, iso, &refs, &mut b)];
        let tracer = HybridTracer {
            src: &src,
            surfaces: &surf,
            sources: &[],
            smooth_normals: false,
        };
        let frame = src.frame();
        let to_world = |u: [f64; 3]| [0, 1, 2].map(|a| origin[a] + p.size * u[a]);
        let leaks = AtomicU64::new(0);
        let misses = AtomicU64::new(0);
        let false_hits = AtomicU64::new(0);
        let worst = (0..rays_per_case)
            .into_par_iter()
            .map(|k| {
                let mut r = Rng::new(rseed ^ k.wrapping_mul(0x9E37_79B9));
                let inside = k % 2 == 0;
                let (o, d) = if inside {
                    let rad = SPHERE_RADIUS * 0.9 * r.f64().cbrt();
                    let v = r.unit_vector();
                    (
                        [0, 1, 2].map(|a| SPHERE_CENTRE[a] + rad * v[a]),
                        r.unit_vector(),
                    )
                } else {
                    let v = r.unit_vector();
                    let dist = r.range(0.45, 3.0);
                    let o = [0, 1, 2].map(|a| SPHERE_CENTRE[a] + dist * v[a]);
                    let t = [0, 1, 2].map(|a| SPHERE_CENTRE[a] + r.range(-0.35, 0.35));
                    let d = [0, 1, 2].map(|a| t[a] - o[a]);
                    let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                    (o, d.map(|x| x / l))
                };
                let ray = GridRay::from_world(&frame, to_world(o), d);
                let hit = tracer.next_hit(0, &ray, 0.0, f64::INFINITY);
                // Reference in unit-cube coordinates: impact parameter and entry.
                let oc = [0, 1, 2].map(|a| o[a] - SPHERE_CENTRE[a]);
                let bq = oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2];
                let c2 = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2];
                let impact = (c2 - bq * bq).max(0.0).sqrt();
                // Unrefined bricks leave parts of the surface on level 0, whose reconstruction error is
                // a fraction of a level-0 cell: the margin is half of one.
                let margin = 0.5 / f64::from(p.base);
                if inside {
                    if hit.is_none() {
                        leaks.fetch_add(1, Ordering::Relaxed);
                    }
                } else {
                    let ahead = bq < 0.0;
                    match &hit {
                        None if ahead && impact < SPHERE_RADIUS - margin => {
                            misses.fetch_add(1, Ordering::Relaxed);
                        }
                        Some(_) if !ahead || impact > SPHERE_RADIUS + margin => {
                            false_hits.fetch_add(1, Ordering::Relaxed);
                        }
                        _ => {}
                    }
                }
                hit.map_or(0.0, |h| {
                    // Grid (doubled finest) coordinates to the unit cube.
                    let u = h.pos.map(|g| g / (2.0 * nf));
                    let rr = (0..3)
                        .map(|a| (u[a] - SPHERE_CENTRE[a]).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    (rr - SPHERE_RADIUS).abs() * nf
                })
            })
            .reduce(|| 0.0, f64::max);
        let (l, m, fh) = (
            leaks.into_inner(),
            misses.into_inner(),
            false_hits.into_inner(),
        );
        tot.rays += rays_per_case;
        tot.inside_rays += rays_per_case.div_ceil(2);
        tot.outside_rays += rays_per_case / 2;
        tot.leaks += l;
        tot.misses += m;
        tot.false_hits += fh;
        let desc = format!(
            "{} levels, base {}, brick {}, cell {:.1e}, origin ({:.1e}, {:.1e}, {:.1e}), values x{:.1e}",
            file.levels().len(),
            p.base,
            p.brick,
            finest_world,
            origin[0],
            origin[1],
            origin[2],
            scale
        );
        if worst > tot.worst_hit {
            tot.worst_hit = worst;
            tot.worst_case = desc.clone();
        }
        lines.push(format!(
            "| {case} | {desc} | {} | {l} | {m} | {fh} | {worst:.4} |",
            refs.len()
        ));
        drop(src);
        drop(file);
        let _ = std::fs::remove_file(&path);
    }
    let secs = start.elapsed().as_secs_f64();
    let mut s = String::new();
    writeln!(s, "## Stability stress\n")?;
    s.push_str(&ctx.provenance());
    writeln!(
        s,
        "\n{cases} seeded random hierarchies (2 to 4 levels, bricks of 4 or 8, refined around the \
         surface except on a random quarter of the candidate bricks), physical size 1e-6 to 1e2, \
         offsets up to min(1e8, 1e10 finest cells) on each axis, values `scale * (1 + d)` with \
         scale 1e-30 to 1e30 and isovalue `scale` (d: signed distance to the sphere). \
         {rays_per_case} rays per case, half from inside the sphere (leak test), half from \
         random outside cameras (compared with a float64 ray-sphere intersection; margin half a \
         level-0 cell, since a random quarter of the surface stays on coarse levels and its \
         reconstruction differs from the sphere by a fraction of a coarse cell). Hybrid tracer, octant method. {secs:.0} s in all.\n"
    )?;
    writeln!(
        s,
        "| rays | inside rays | leaks | outside rays | misses vs float64 | false hits vs float64 | worst hit error (finest cells) |"
    )?;
    writeln!(s, "|---|---|---|---|---|---|---|")?;
    writeln!(
        s,
        "| {} | {} | {} | {} | {} | {} | {:.4} |\n",
        tot.rays,
        tot.inside_rays,
        tot.leaks,
        tot.outside_rays,
        tot.misses,
        tot.false_hits,
        tot.worst_hit
    )?;
    writeln!(
        s,
        "Goal 0 leaks for octant: {}. Worst hit error in case: {}.\n",
        if tot.leaks == 0 { "met" } else { "NOT met" },
        tot.worst_case
    )?;
    writeln!(s, "<details><summary>Per case</summary>\n")?;
    writeln!(s, "| case | hierarchy, placement, scale | active octants | leaks | misses | false hits | worst hit error |")?;
    writeln!(s, "|---|---|---|---|---|---|---|")?;
    for l in lines {
        writeln!(s, "{l}")?;
    }
    writeln!(s, "\n</details>\n")?;
    Ok(s)
}
