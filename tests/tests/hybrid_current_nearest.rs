//! The hybrid tracer with the `current` and `nearest` reconstructions, on seeded random
//! hierarchies (2, 3 and 9 levels, ratio 2 and 4):
//!
//! - the extractions equal a brute-force reference that visits every dual cell (current) or
//!   every face (nearest) of every kd-tree leaf, without the leaf ranges or neighbour tables;
//! - decoded voxels carry the sampler's field: the trilinear interpolant of a current voxel
//!   equals `Sampler::sample(p, Reconstruction::Current)` inside it, a nearest face slab has the two
//!   cells' values on its two sides;
//! - along random rays the hybrid's first hit is a real change of side of the sampler's field,
//!   and comes no later than the first change a fine march finds (for `current`, a march bracket
//!   inside one kd-tree leaf: across a level boundary the field jumps without a surface).
//!
//! Failures name their seed.

use std::collections::{BTreeMap, BTreeSet};

use crate::support::hierarchy::{build, standard_cases, Rng};
use amr_format::AmrkFile;
use amr_render::bvh::BvhBuilder;
use amr_render::extract::current::CurrentVoxels;
use amr_render::extract::nearest::NearestFaces;
use amr_render::reconstruct::{Reconstruction, Sampler};
use amr_render::trace::traverse::Surface;
use amr_render::trace::FieldSource;
use amr_render::trace::{GridRay, HybridTracer, Tracer, VoxelSource};

fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a * (1.0 - t) + b * t
}

fn trilinear(v: &[f32; 8], t: [f64; 3]) -> f64 {
    let c = v.map(f64::from);
    let x = [0, 2, 4, 6].map(|i| lerp(c[i], c[i + 1], t[0]));
    lerp(lerp(x[0], x[1], t[1]), lerp(x[2], x[3], t[1]), t[2])
}

fn straddles(lo: f32, hi: f32, iso: f32) -> bool {
    lo < iso && iso <= hi
}

/// Every clipped dual cell of every leaf: `(leaf, dual index) -> corner values`.
fn all_current(s: &Sampler<'_, Vec<u8>>) -> BTreeMap<(u32, [i64; 3]), [f32; 8]> {
    let g = s.grid();
    let mut out = BTreeMap::new();
    for leaf in 0..s.file().num_leaves() as u32 {
        let Some((_, level)) = s.leaf_top(leaf) else {
            continue;
        };
        let b = s.file().tree().leaf_box(leaf);
        let sc = g.scale(level);
        let cells = g.level_box(level, &b);
        for z in cells.lo[2] - 1..cells.hi[2] {
            for y in cells.lo[1] - 1..cells.hi[1] {
                for x in cells.lo[0] - 1..cells.hi[0] {
                    let i = [x, y, z];
                    let base = g.centre(level, i);
                    let lo = [0, 1, 2].map(|a| base[a].max(2 * b.lo[a]));
                    let hi = [0, 1, 2].map(|a| (base[a] + 2 * sc[a]).min(2 * b.hi[a]));
                    if (0..3).any(|a| hi[a] <= lo[a]) {
                        continue;
                    }
                    let dual: [f32; 8] = std::array::from_fn(|n| {
                        let c = [0, 1, 2].map(|a| i[a] + (n >> a & 1) as i64);
                        let at = g.finest_cell(g.centre(level, c), 7);
                        s.locate(at)
                            .unwrap()
                            .expect("level 0 covers the domain")
                            .value
                    });
                    let t = |p: [i64; 3]| {
                        [0, 1, 2].map(|a| (p[a] - base[a]) as f64 / (2 * sc[a]) as f64)
                    };
                    let (t0, t1) = (t(lo), t(hi));
                    let values = std::array::from_fn(|n| {
                        let u = [0, 1, 2].map(|a| if n >> a & 1 == 1 { t1[a] } else { t0[a] });
                        trilinear(&dual, u) as f32
                    });
                    assert!(out.insert((leaf, i), values).is_none());
                }
            }
        }
    }
    out
}

/// Faces by rectangle (lo, hi in finest cells) and axis: the values below and above.
type Faces = BTreeMap<([i64; 3], [i64; 3], usize), (f32, f32)>;

/// Every face between two leaf cells, once: `(face rectangle lo, hi in finest cells, axis) ->
/// (value below, value above)`. Visits every leaf cell's six faces; a face whose far side holds
/// finer cells (any of four probes just across its corners) is left to those cells.
fn all_faces(s: &Sampler<'_, Vec<u8>>) -> Faces {
    let g = s.grid();
    let ext = g.extent();
    let mut out = BTreeMap::new();
    for leaf in 0..s.file().num_leaves() as u32 {
        let Some((_, level)) = s.leaf_top(leaf) else {
            continue;
        };
        let cells = g.level_box(level, &s.file().tree().leaf_box(leaf));
        for z in cells.lo[2]..cells.hi[2] {
            for y in cells.lo[1]..cells.hi[1] {
                for x in cells.lo[0]..cells.hi[0] {
                    let fb = g.finest_box(level, [x, y, z]);
                    let own = s.locate(fb.lo).unwrap().unwrap();
                    assert_eq!(own.level, level);
                    for a in 0..3 {
                        for up in [false, true] {
                            let across = if up { fb.hi[a] } else { fb.lo[a] - 1 };
                            if across < 0 || across >= ext[a] {
                                continue;
                            }
                            let probes: Vec<_> = (0..4)
                                .map(|k| {
                                    let mut p = [0, 1, 2].map(|b| {
                                        let hi_side = if b == (a + 1) % 3 { k & 1 } else { k >> 1 };
                                        if hi_side == 1 {
                                            fb.hi[b] - 1
                                        } else {
                                            fb.lo[b]
                                        }
                                    });
                                    p[a] = across;
                                    s.locate(p).unwrap().unwrap()
                                })
                                .collect();
                            if probes.iter().any(|c| c.level > level) {
                                continue;
                            }
                            assert!(probes.iter().all(|c| c.cell == probes[0].cell));
                            let n = probes[0];
                            let mut lo = fb.lo;
                            let mut hi = fb.hi;
                            let plane = if up { fb.hi[a] } else { fb.lo[a] };
                            lo[a] = plane;
                            hi[a] = plane;
                            let v = if up {
                                (own.value, n.value)
                            } else {
                                (n.value, own.value)
                            };
                            out.insert((lo, hi, a), v);
                        }
                    }
                }
            }
        }
    }
    out
}

fn check_current(file: &AmrkFile<Vec<u8>>, field: usize, isos: &[f32], ctx: &str) {
    let sampler = Sampler::new(file, field, 64 << 20).unwrap();
    let cv = CurrentVoxels::new(&sampler);
    let s = &sampler;
    let all = all_current(s);
    let mut rng = Rng(0xC0FFEE);
    for &iso in isos {
        let want: BTreeSet<(u32, [i64; 3])> = all
            .iter()
            .filter(|(_, v)| {
                let lo = v.iter().copied().fold(f32::INFINITY, f32::min);
                let hi = v.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                straddles(lo, hi, iso)
            })
            .map(|(k, _)| *k)
            .collect();
        let refs = cv.extract(iso).unwrap();
        assert!(
            refs.windows(2).all(|w| w[0] < w[1]),
            "{ctx} iso {iso}: refs not increasing"
        );
        let mut got = BTreeSet::new();
        for &r in &refs {
            let v = cv
                .decode(r)
                .unwrap_or_else(|e| panic!("{ctx} iso {iso}: {e}"));
            let leaf = (r >> 32) as u32;
            let sc = s.grid().scale(v.level);
            // The dual index from the box: the unclipped lower corner is the centre of level
            // cell `i`, `2 (i s - o) + s`, and the clipped one lies less than `2 s` above it.
            let o = s.grid().offset();
            let i = [0, 1, 2].map(|a| (v.lo_doubled()[a] + 2 * o[a] - sc[a]).div_euclid(2 * sc[a]));
            let key = (leaf, i);
            let vals = all.get(&key).unwrap_or_else(|| {
                panic!("{ctx} iso {iso}: ref {r:#x} {v:?} not in the reference")
            });
            assert_eq!(*vals, v.values, "{ctx} iso {iso}: ref {r:#x} values");
            assert!(
                want.contains(&key),
                "{ctx} iso {iso}: ref {r:#x} is inactive"
            );
            assert!(got.insert(key), "{ctx} iso {iso}: {key:?} emitted twice");
            // The interpolant equals the sampler's `current` field inside the voxel.
            for _ in 0..4 {
                let u = [0, 1, 2].map(|_| 0.02 + 0.96 * rng.f64());
                let p = [0, 1, 2]
                    .map(|a| lerp(v.lo_doubled()[a] as f64, v.hi_doubled()[a] as f64, u[a]));
                let f = s.sample(p, Reconstruction::Current).unwrap().unwrap();
                let mine = trilinear(&v.values, u);
                let scale = v
                    .values
                    .iter()
                    .fold(1.0f64, |m, x| m.max(f64::from(x.abs())));
                assert!(
                    (f64::from(f) - mine).abs() <= 1e-5 * scale,
                    "{ctx} iso {iso}: ref {r:#x} gives {mine} at {p:?}, the sampler {f}"
                );
            }
        }
        assert_eq!(got, want, "{ctx} iso {iso}: active sets differ");
    }
}

fn check_nearest(file: &AmrkFile<Vec<u8>>, field: usize, isos: &[f32], ctx: &str) {
    let sampler = Sampler::new(file, field, 64 << 20).unwrap();
    let nf = NearestFaces::new(&sampler);
    let s = &sampler;
    let all = all_faces(s);
    for &iso in isos {
        let want: BTreeSet<_> = all
            .iter()
            .filter(|(_, (b, a))| straddles(b.min(*a), b.max(*a), iso))
            .map(|(k, _)| *k)
            .collect();
        let refs = nf.extract(iso).unwrap();
        assert!(
            refs.windows(2).all(|w| w[0] < w[1]),
            "{ctx} iso {iso}: refs not increasing"
        );
        let mut got = BTreeSet::new();
        for &r in &refs {
            let v = nf
                .decode(r)
                .unwrap_or_else(|e| panic!("{ctx} iso {iso}: {e}"));
            let a = (0..3)
                .find(|&a| v.values[0] != v.values[1 << a])
                .unwrap_or_else(|| panic!("{ctx} iso {iso}: ref {r:#x} has one value"));
            // The slab's face, in finest cells.
            let mut lo = [0, 1, 2].map(|b| v.lo_doubled()[b] / 2);
            let mut hi = [0, 1, 2].map(|b| v.hi_doubled()[b] / 2);
            let plane = (v.lo_doubled()[a] + v.hi_doubled()[a]) / 4;
            lo[a] = plane;
            hi[a] = plane;
            let key = (lo, hi, a);
            let (below, above) = all
                .get(&key)
                .unwrap_or_else(|| panic!("{ctx} iso {iso}: ref {r:#x} {key:?} is no face"));
            assert_eq!(
                (v.values[0], v.values[1 << a]),
                (*below, *above),
                "{ctx} iso {iso}: ref {r:#x} values"
            );
            assert!(got.insert(key), "{ctx} iso {iso}: {key:?} emitted twice");
        }
        let missing: Vec<_> = want.difference(&got).collect();
        assert!(
            missing.is_empty(),
            "{ctx} iso {iso}: {} faces missing, e.g. {:?}",
            missing.len(),
            missing.first()
        );
        assert_eq!(got, want, "{ctx} iso {iso}: active sets differ");
    }
}

fn isovalues(rng: &mut Rng, file: &AmrkFile<Vec<u8>>, field: usize) -> Vec<f32> {
    let f = &file.fields()[field];
    let mut out = vec![0.0, 0.125, -0.375];
    for _ in 0..2 {
        out.push(f.min + (f.max - f.min) * rng.f64() as f32);
    }
    out
}

#[test]
fn current_extraction_equals_brute_force() {
    for case in standard_cases(2) {
        let (_, file) = build(&case);
        let mut rng = Rng(case.seed ^ 0x51);
        for field in 0..2 {
            let isos = isovalues(&mut rng, &file, field);
            check_current(
                &file,
                field,
                &isos,
                &format!("seed {} ({case:?}) field {field}", case.seed),
            );
        }
    }
}

#[test]
fn nearest_extraction_equals_brute_force() {
    for case in standard_cases(2) {
        let (_, file) = build(&case);
        let mut rng = Rng(case.seed ^ 0x52);
        for field in 0..2 {
            let isos = isovalues(&mut rng, &file, field);
            check_nearest(
                &file,
                field,
                &isos,
                &format!("seed {} ({case:?}) field {field}", case.seed),
            );
        }
    }
}

/// Which side of `iso` the sampler's field is on at `p`, the kd-tree leaf there and the width of
/// its cells (doubled units, smallest axis).
fn side(s: &Sampler<'_, Vec<u8>>, m: Reconstruction, p: [f64; 3], iso: f32) -> (bool, u32, f64) {
    let v = s.sample(p, m).unwrap().unwrap();
    let ext = s.grid().extent();
    let f = [0, 1, 2].map(|a| ((p[a] * 0.5).floor() as i64).clamp(0, ext[a] - 1));
    let c = s.locate(f).unwrap().unwrap();
    let w = s
        .grid()
        .scale(c.level)
        .iter()
        .fold(i64::MAX, |m, &x| m.min(x));
    (v >= iso, c.leaf, 2.0 * w as f64)
}

fn check_rays(
    file: &AmrkFile<Vec<u8>>,
    field: usize,
    recon: Reconstruction,
    iso: f32,
    seed: u64,
    ctx: &str,
) -> usize {
    let src = FieldSource::new(file, field, recon).unwrap();
    let refs = src.extract(iso).unwrap().refs;
    let surf = [Surface::build(&src, iso, &refs, &mut BvhBuilder::new())];
    let tracer = HybridTracer {
        src: &src,
        surfaces: &surf,
        sources: &[],
        smooth_normals: false,
    };
    let m = recon;
    let s = src.sampler();
    let ext = src.frame().extent;
    let mut rng = Rng(seed);
    let mut hits = 0;
    for k in 0..60 {
        // From outside the domain to a random point inside; unit direction in grid units.
        let target = ext.map(|e| e * (0.05 + 0.9 * rng.f64()));
        let dir = {
            let d = [0, 1, 2].map(|_| rng.f64() - 0.5);
            let n = d.iter().map(|x| x * x).sum::<f64>().sqrt();
            d.map(|x| x / n)
        };
        let diag = ext.iter().map(|e| e * e).sum::<f64>().sqrt();
        let o = [0, 1, 2].map(|a| target[a] - dir[a] * diag);
        let ray = GridRay { o, d: dir };
        let hit = tracer.next_hit(0, &ray, 0.0, f64::INFINITY);
        let Some((t0, t1)) = ray.clip([0.0; 3], ext, 0.0, f64::INFINITY) else {
            continue;
        };
        // March a sixteenth of the local cell width (coarse steps can skip a thin finer cell:
        // that only makes the march's first change later, never a false failure).
        let inside = |t: f64| ray.at(t).map(|x| x.clamp(0.0, f64::MAX));
        let mut prev = side(s, m, inside(t0 + 1e-9), iso);
        let mut first: Option<(f64, f64)> = None;
        let mut t = t0 + 1e-9;
        while t < t1 - 1e-9 {
            let tn = (t + prev.2 / 16.0).min(t1 - 1e-9);
            let cur = side(s, m, inside(tn), iso);
            if cur.0 != prev.0 && (m == Reconstruction::Nearest || cur.1 == prev.1) {
                first = Some((t, tn));
                break;
            }
            prev = cur;
            t = tn;
        }
        if let Some(h) = hit {
            hits += 1;
            // A real change of side at the hit.
            let d = 1e-6;
            let (a, b) = (
                side(s, m, ray.at(h.t - d), iso).0,
                side(s, m, ray.at(h.t + d), iso).0,
            );
            if m == Reconstruction::Nearest {
                assert!(
                    a != b,
                    "{ctx} ray {k}: nearest hit at t {} is no face crossing",
                    h.t
                );
            } else {
                let vox = src.voxel(h.r);
                let c = [0, 1, 2].map(|a| 0.5 * (vox.lo[a] + vox.hi[a]));
                let p = [0, 1, 2].map(|a| h.pos[a] + 1e-7 * (c[a] - h.pos[a]));
                let f = f64::from(s.sample(p, m).unwrap().unwrap());
                let scale = vox
                    .values
                    .iter()
                    .fold(1.0f64, |m, x| m.max(f64::from(x.abs())));
                assert!(
                    (f - f64::from(iso)).abs() <= 1e-4 * scale,
                    "{ctx} ray {k}: current hit at t {} has value {f}, iso {iso}",
                    h.t
                );
            }
        }
        if let Some((_, tb)) = first {
            let h = hit.unwrap_or_else(|| {
                panic!("{ctx} ray {k}: the march changes side by t {tb}, the hybrid misses")
            });
            // Corner values rounded to f32 move a crossing by ~1e-7 of the voxel's size.
            assert!(
                h.t <= tb + 1e-6 + 1e-5 * h.size,
                "{ctx} ray {k}: hybrid hit at t {} after the march's change by {tb}",
                h.t
            );
        }
    }
    hits
}

#[test]
fn hybrid_hits_agree_with_the_sampler_along_rays() {
    let mut hits = 0;
    for case in standard_cases(1) {
        let (_, file) = build(&case);
        for field in 0..2 {
            for (i, iso) in [0.0f32, 0.3].into_iter().enumerate() {
                for recon in [Reconstruction::Current, Reconstruction::Nearest] {
                    let ctx = format!(
                        "seed {} ({case:?}) field {field} {recon:?} iso {iso}",
                        case.seed
                    );
                    hits += check_rays(&file, field, recon, iso, case.seed ^ i as u64, &ctx);
                }
            }
        }
    }
    assert!(hits > 100, "only {hits} hits: the test proves little");
}
