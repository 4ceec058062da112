//! The sampler's shortcuts (point location through the leaf grid, octant corners gathered
//! around the octant's outer corner) give the general rules' answers bit for bit: every leaf
//! cell located, every octant's corners, and samples of every reconstruction at random points,
//! most of them near level boundaries, fresh and through a scratch; every failure names its
//! seed.

use amr_format::AmrkFile;
use amr_render::reconstruct::{Octant, Reconstruction, SampleScratch, Sampler, VertexMemo};

use crate::support::hierarchy::{build, standard_cases, Case, Rng};

/// The standard cases, a compressed one, and ratio 3 (cell widths that are not powers of two).
fn cases() -> Vec<Case> {
    let mut cases = standard_cases(3);
    let mut zstd = Case::new(91, 4, 2);
    zstd.zstd = true;
    cases.push(zstd);
    cases.push(Case::new(33, 3, 3));
    cases.push(Case::new(34, 4, 3));
    cases
}

/// Random doubled points: a quarter uniform in the domain, the rest within one cell of the
/// finest level at which the levels on either side differ, and a third of all snapped onto the
/// integer lattice where faces, edges and vertices lie.
fn points(s: &Sampler<'_, Vec<u8>>, seed: u64, n: usize) -> Vec<[f64; 3]> {
    let ext = s.grid().extent();
    let span = ext.map(|e| 2.0 * e as f64);
    let mut rng = Rng(seed);
    let level_at = |p: [f64; 3]| {
        let f = [0, 1, 2].map(|a| ((p[a] * 0.5).floor() as i64).clamp(0, ext[a] - 1));
        s.locate(f).unwrap().map(|c| c.level)
    };
    let mut out = Vec::with_capacity(n);
    let mut tries = 0;
    while out.len() < n {
        tries += 1;
        let mut p = [0, 1, 2].map(|a| rng.f64() * span[a]);
        if out.len() % 4 != 0 && tries < 200 * n {
            // Keep only points with another level within one cell of their own.
            let Some(level) = level_at(p) else { continue };
            let w = s.grid().scale(level).map(|x| 2.0 * x as f64);
            let other = (0..27).any(|d| {
                let q = [d % 3, d / 3 % 3, d / 9].map(|k| k as f64 - 1.0);
                let q = [0, 1, 2].map(|a| (p[a] + q[a] * w[a]).clamp(0.0, span[a]));
                level_at(q).is_some_and(|l| l != level)
            });
            if !other {
                continue;
            }
        }
        if out.len() % 3 == 0 {
            p = p.map(f64::round);
        }
        out.push(p);
    }
    out
}

/// Two samplers of field `field` of `file`: with the shortcuts (the default) and without.
fn fast_and_general<D: AsRef<[u8]>>(
    file: &AmrkFile<D>,
    field: usize,
) -> (Sampler<'_, D>, Sampler<'_, D>) {
    let fast = Sampler::new(file, field, 64 << 20).unwrap();
    let general = Sampler::new(file, field, 64 << 20)
        .unwrap()
        .with_shortcuts(false);
    (fast, general)
}

#[test]
fn shortcut_locates_equal_tree_walks() {
    for case in cases() {
        let (_, file) = build(&case);
        let (fast, general) = fast_and_general(&file, 0);
        let ext = fast.grid().extent();
        let mut rng = Rng(case.seed ^ 0x10c8);
        for _ in 0..4000 {
            // Mostly inside, sometimes one cell outside the domain.
            let f = [0, 1, 2].map(|a| rng.range(-1, ext[a] + 1));
            assert_eq!(
                fast.locate(f).unwrap(),
                general.locate(f).unwrap(),
                "{case:?}: finest cell {f:?}"
            );
        }
    }
}

/// Per kd-tree leaf with cells, its eight corner cells (level and cell): where its neighbours,
/// often of other levels, meet.
fn leaf_corner_cells(s: &Sampler<'_, Vec<u8>>) -> Vec<(u32, [i64; 3])> {
    let mut out = Vec::new();
    for leaf in 0..s.file().num_leaves() as u32 {
        let Some((_, level)) = s.leaf_top(leaf) else {
            continue;
        };
        let cells = s.grid().level_box(level, &s.leaf_box(leaf));
        for corner in 0..8 {
            let cell = [0, 1, 2].map(|a| {
                if corner >> a & 1 == 1 {
                    cells.hi[a] - 1
                } else {
                    cells.lo[a]
                }
            });
            out.push((level, cell));
        }
    }
    out
}

#[test]
fn gathered_octant_corners_equal_the_general_rule() {
    let mut stitched = 0u64;
    for case in cases() {
        let (_, file) = build(&case);
        for field in 0..2 {
            let (fast, general) = fast_and_general(&file, field);
            for (level, cell) in leaf_corner_cells(&fast) {
                for octant in 0..8u8 {
                    let o = Octant {
                        level,
                        cell,
                        octant,
                    };
                    let got = fast.octant_values(&o).unwrap();
                    let want = general.octant_values(&o).unwrap();
                    assert_eq!(
                        got.map(|v| v.map(f32::to_bits)),
                        want.map(|v| v.map(f32::to_bits)),
                        "{case:?}, field {field}: {o:?}"
                    );
                    // Corners that are not means of their eight cells: stitched ones.
                    let (lo, _) = general.octant_box(&o);
                    let sc = general.grid().scale(level);
                    for n in 0..8 {
                        let v = [0, 1, 2].map(|a| lo[a] + (n >> a & 1) as i64 * sc[a]);
                        let Some(cells) = general.around(v).unwrap() else {
                            continue;
                        };
                        if cells.iter().any(|c| c.level < level) {
                            stitched += 1;
                        }
                    }
                }
            }
        }
    }
    assert!(stitched > 1000, "only {stitched} stitched corners checked");
}

/// Octants asked for through one memo that computes a cell's octants together (as the
/// extraction's does) have the general rule's corners: both the octant asked for and the ones
/// computed with it and found in the memo's table later. Every octant of the cells at and
/// beside each leaf's corners, in an order that often asks a cell's octants one after another.
#[test]
fn octants_computed_together_equal_the_general_rule() {
    let mut from_table = 0u64;
    for case in cases() {
        let (_, file) = build(&case);
        let (fast, general) = fast_and_general(&file, 0);
        let mut memo = VertexMemo::default().with_octants_together();
        for (level, cell) in leaf_corner_cells(&fast) {
            for octant in (0..8u8).rev() {
                let o = Octant {
                    level,
                    cell,
                    octant,
                };
                from_table += u64::from(memo.knows_octant(&o));
                let got = fast.octant_values_memo(&o, &mut memo).unwrap();
                let want = general.octant_values(&o).unwrap();
                assert_eq!(
                    got.map(|v| v.map(f32::to_bits)),
                    want.map(|v| v.map(f32::to_bits)),
                    "{case:?}: {o:?}"
                );
            }
        }
    }
    assert!(
        from_table > 1000,
        "only {from_table} octants from the table"
    );
}

/// The leaf cells around a vertex are the cells located at its eight sides, and a vertex's
/// value is the same whatever a memo kept from the vertices before (the kd-tree leaves it
/// remembers): vertices near level boundaries, at every level, through one memo.
#[test]
fn vertex_sides_and_values_do_not_depend_on_the_leaves_remembered() {
    for case in cases() {
        let (_, file) = build(&case);
        let (fast, general) = fast_and_general(&file, 0);
        let grid = general.grid();
        let mut memo = VertexMemo::default();
        for p in points(&fast, case.seed ^ 0x7e11, 1500) {
            let v = p.map(|x| x.round() as i64);
            let sides: Vec<_> = (0..8u8)
                .map(|n| general.locate(grid.finest_cell(v, n)).unwrap())
                .collect();
            let want = sides
                .iter()
                .all(Option::is_some)
                .then(|| sides.iter().map(|c| c.unwrap()).collect::<Vec<_>>());
            let got = fast.around(v).unwrap().map(|c| c.to_vec());
            assert_eq!(got, want, "{case:?}: around {v:?}");
            for level in 0..grid.num_levels() as u32 {
                let want = general
                    .vertex_value(v, level, &mut VertexMemo::default())
                    .unwrap();
                let got = fast.vertex_value(v, level, &mut memo).unwrap();
                assert_eq!(
                    got.map(f32::to_bits),
                    want.map(f32::to_bits),
                    "{case:?}: vertex {v:?} seen from level {level}"
                );
            }
        }
    }
}

#[test]
fn shortcut_samples_equal_general_samples_near_level_boundaries() {
    for case in cases() {
        let (_, file) = build(&case);
        for field in 0..2 {
            let (fast, general) = fast_and_general(&file, field);
            let mut scratch = SampleScratch::default();
            for p in points(&fast, case.seed ^ 0x5a3b ^ field as u64, 1500) {
                for m in Reconstruction::ALL {
                    let want = general.sample(p, m).unwrap();
                    let got = fast.sample(p, m).unwrap();
                    let kept = fast.sample_with(p, m, &mut scratch).unwrap();
                    assert_eq!(
                        got.map(f32::to_bits),
                        want.map(f32::to_bits),
                        "{case:?}, field {field}: {m} at {p:?}"
                    );
                    assert_eq!(
                        kept.map(|k| k.0.to_bits()),
                        want.map(f32::to_bits),
                        "{case:?}, field {field}: {m} at {p:?} through a scratch"
                    );
                }
            }
        }
    }
}
