//! Point samples through a per-thread [`SampleScratch`] (remembered kd-tree leaves, shared
//! octant corners, the one-level corner rule) equal fresh samples bit for bit, for every
//! reconstruction; octant corners equal the per-vertex rule; a scratch handed to another sampler
//! forgets the first; the field source's gradient equals central differences of fresh samples.

use amr_render::reconstruct::{Octant, Reconstruction, SampleScratch, Sampler, VertexMemo};
use amr_render::trace::tracer::central_difference_of;
use amr_render::trace::{FieldSource, VoxelSource};

use crate::support::hierarchy::{build, standard_cases, Case, Rng};

/// Random doubled points: clusters (each point near the last), a third snapped onto the
/// integer lattice where faces, edges and vertices lie.
fn points(s: &Sampler<'_, Vec<u8>>, seed: u64, n: usize) -> Vec<[f64; 3]> {
    let ext = s.grid().extent().map(|e| 2.0 * e as f64);
    let mut rng = Rng(seed);
    let mut p = [0.0; 3];
    (0..n)
        .map(|i| {
            for a in 0..3 {
                p[a] = if i % 8 == 0 {
                    rng.f64() * ext[a]
                } else {
                    (p[a] + (rng.f64() - 0.5) * 4.0).clamp(0.0, ext[a])
                };
                if i % 3 == 0 {
                    p[a] = p[a].round();
                }
            }
            p
        })
        .collect()
}

fn cases() -> Vec<Case> {
    let mut cases = standard_cases(2);
    let mut zstd = Case::new(77, 3, 2);
    zstd.zstd = true;
    cases.push(zstd);
    cases
}

#[test]
fn samples_through_a_scratch_equal_fresh_samples() {
    for case in cases() {
        let (_, file) = build(&case);
        let s = Sampler::new(&file, 0, 64 << 20).unwrap();
        let ext = s.grid().extent();
        let mut scratch = SampleScratch::default();
        for p in points(&s, case.seed ^ 0x5eed, 2000) {
            for m in Reconstruction::ALL {
                let fresh = s.sample(p, m).unwrap();
                let kept = s.sample_with(p, m, &mut scratch).unwrap();
                assert_eq!(
                    fresh.map(f32::to_bits),
                    kept.map(|k| k.0.to_bits()),
                    "{case:?}: {m} at {p:?}"
                );
                if let Some((_, level)) = kept {
                    let finest = [0, 1, 2].map(|a| ((p[a] * 0.5).floor() as i64).min(ext[a] - 1));
                    assert_eq!(
                        level,
                        s.locate(finest).unwrap().unwrap().level,
                        "{case:?}: {p:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn octant_corners_equal_the_per_vertex_rule() {
    for case in cases() {
        let (_, file) = build(&case);
        let s = Sampler::new(&file, 0, 64 << 20).unwrap();
        let mut memo = VertexMemo::default();
        let mut checked = 0u64;
        for leaf in 0..file.num_leaves() as u32 {
            let Some((_, level)) = s.leaf_top(leaf) else {
                continue;
            };
            let cells = s.grid().level_box(level, &s.leaf_box(leaf));
            let cell = cells.lo;
            for octant in 0..8u8 {
                let o = Octant {
                    level,
                    cell,
                    octant,
                };
                let Some(got) = s.octant_values_memo(&o, &mut memo).unwrap() else {
                    continue;
                };
                let (lo, _) = s.octant_box(&o);
                let sc = s.grid().scale(level);
                let centre = s.grid().centre(level, cell);
                for (n, &g) in got.iter().enumerate() {
                    let v = [0, 1, 2].map(|a| lo[a] + (n >> a & 1) as i64 * sc[a]);
                    let want = if v == centre {
                        let at = s.grid().finest_cell(centre, 7);
                        s.locate(at).unwrap().unwrap().value
                    } else {
                        s.vertex_value(v, level, &mut VertexMemo::default())
                            .unwrap()
                            .unwrap()
                    };
                    assert_eq!(g.to_bits(), want.to_bits(), "{case:?}: {o:?} corner {n}");
                    checked += 1;
                }
            }
        }
        assert!(checked > 0, "{case:?}: no octant checked");
    }
}

#[test]
fn a_scratch_handed_to_another_sampler_forgets_the_first() {
    let (_, a) = build(&Case::new(5, 3, 2));
    let (_, b) = build(&Case::new(6, 3, 4));
    let sa = Sampler::new(&a, 0, 64 << 20).unwrap();
    let sb = Sampler::new(&b, 1, 64 << 20).unwrap();
    let mut scratch = SampleScratch::default();
    let pa = points(&sa, 1, 300);
    let pb = points(&sb, 2, 300);
    for (p, q) in pa.iter().zip(&pb) {
        for (s, x) in [(&sa, p), (&sb, q), (&sb, p), (&sa, q)] {
            let fresh = s.sample(*x, Reconstruction::Octant).unwrap();
            let kept = s
                .sample_with(*x, Reconstruction::Octant, &mut scratch)
                .unwrap();
            assert_eq!(
                fresh.map(f32::to_bits),
                kept.map(|k| k.0.to_bits()),
                "at {x:?}"
            );
        }
    }
}

#[test]
fn field_source_gradients_equal_central_differences_of_fresh_samples() {
    for case in cases().into_iter().take(6) {
        let (_, file) = build(&case);
        for m in [
            Reconstruction::Octant,
            Reconstruction::Current,
            Reconstruction::Nearest,
        ] {
            let src = FieldSource::new(&file, 0, m).unwrap();
            let s = src.sampler();
            for (i, p) in points(s, case.seed, 500).into_iter().enumerate() {
                let h = [[0.25; 3], [0.5, 1.0, 2.0], [1.0; 3], [2.0, 0.5, 0.25]][i % 4];
                let fresh = central_difference_of(|q| s.sample(q, m).unwrap(), p, h);
                let got = src.gradient(p, h);
                assert_eq!(
                    fresh.map(|g| g.map(f64::to_bits)),
                    got.map(|g| g.map(f64::to_bits)),
                    "{case:?}: {m} at {p:?}, h {h:?}"
                );
            }
            assert!(src.take_failure().is_none());
        }
    }
}
