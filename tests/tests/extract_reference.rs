//! Extraction equals a brute-force reference that evaluates every octant of every leaf; every
//! active voxel's corners lie in its leaf's stored range; the result does not depend on the run
//! or the number of threads; compressed files decode each brick once. Failures name their seed.

use std::collections::{HashMap, HashSet};

use crate::support::hierarchy::{build, standard_cases, Case, Rng};
use amr_format::AmrkFile;
use amr_render::extract::{split_ref, Extractor, LocalVoxel};
use amr_render::reconstruct::{Octant, Sampler, VertexMemo};

/// Every octant of every leaf, once (owned by the leaf holding its lowest finest cell), with its
/// corner values.
fn all_octants(s: &Sampler<'_, Vec<u8>>) -> HashMap<Octant, [f32; 8]> {
    let mut out = HashMap::new();
    for_each_octant(s, |_, o, v| {
        assert!(out.insert(o, v).is_none(), "octant {o:?} owned twice");
    });
    out
}

/// Calls `f` with every octant of every leaf, its owning leaf and its corner values.
fn for_each_octant(s: &Sampler<'_, Vec<u8>>, mut f: impl FnMut(u32, Octant, [f32; 8])) {
    let file = s.file();
    let mut memo = VertexMemo::default();
    for leaf in 0..file.num_leaves() as u32 {
        let Some((_, level)) = s.leaf_top(leaf) else {
            continue;
        };
        let lb = file.tree().leaf_box(leaf);
        let cells = s.grid().level_box(level, &lb);
        for z in cells.lo[2]..cells.hi[2] {
            for y in cells.lo[1]..cells.hi[1] {
                for x in cells.lo[0]..cells.hi[0] {
                    for octant in 0..8u8 {
                        let o = Octant {
                            level,
                            cell: [x, y, z],
                            octant,
                        };
                        let (lo, _) = s.octant_box(&o);
                        if !lb.contains_cell(lo.map(|v| v.div_euclid(2))) {
                            continue;
                        }
                        let v = s
                            .octant_values_memo(&o, &mut memo)
                            .unwrap()
                            .expect("level 0 covers the domain");
                        f(leaf, o, v);
                    }
                }
            }
        }
    }
}

/// Every corner of every octant a leaf owns lies in the leaf's stored tight range, when the
/// file stores them (layout version 3); returns how many corners were checked.
fn check_stored_tight_ranges(s: &Sampler<'_, Vec<u8>>, name: &str) -> u64 {
    let file = s.file();
    let field = s.field();
    let mut checked = 0;
    for_each_octant(s, |leaf, o, v| {
        let Some((lo, hi)) = file.tight_range(field, leaf) else {
            return;
        };
        for c in v {
            assert!(
                lo <= c && c <= hi,
                "{name} field {field}: {o:?} (leaf {leaf}) has corner value {c} outside the \
                 stored tight range {lo}..{hi}"
            );
            checked += 1;
        }
    });
    checked
}

fn straddles(v: &[f32; 8], iso: f32) -> bool {
    let lo = v.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = v.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    lo < iso && iso <= hi
}

/// Isovalues: random ones in the field's range, corner values of random octants (cell values
/// among them), and the field's extremes.
fn isovalues(
    rng: &mut Rng,
    octants: &HashMap<Octant, [f32; 8]>,
    file: &AmrkFile<Vec<u8>>,
    field: usize,
) -> Vec<f32> {
    let info = &file.fields()[field];
    let values: Vec<[f32; 8]> = octants.values().copied().collect();
    let mut out = vec![];
    for _ in 0..3 {
        out.push(info.min + (info.max - info.min) * rng.f64() as f32);
        // A corner value: the edge of some voxel's range, where culling bounds are tightest.
        let v = values[rng.below(values.len() as u64) as usize];
        out.push(v[rng.below(8) as usize]);
    }
    out.push(info.min);
    out.push(info.max);
    out
}

/// Checks every isovalue of `case`; returns how many boundary cells extraction culled, how
/// many leaves it skipped by their tight range and how many boundary octants it culled.
fn check_case(case: &Case) -> (u64, u64, u64) {
    let (culled, skipped, _, octants) = check_case_parts(case);
    (culled, skipped, octants)
}

/// [`check_case`], also returning how many parts of large leaves extraction skipped (third).
fn check_case_parts(case: &Case) -> (u64, u64, u64, u64) {
    let (_, file) = build(case);
    check_file(&file, case.seed, &format!("seed {} ({case:?})", case.seed))
}

/// Checks random isovalues (from `seed`) of every field of `file`, naming it `name` in failures;
/// returns how many boundary cells extraction culled, how many leaves it skipped, how many parts
/// of leaves it skipped and how many boundary octants it culled.
fn check_file(file: &AmrkFile<Vec<u8>>, seed: u64, name: &str) -> (u64, u64, u64, u64) {
    let mut parts = 0;
    let mut octants_culled = 0;
    let mut culled = 0;
    let mut skipped = 0;
    let mut rng = Rng(seed ^ 0x1234);
    let nb = file.num_bricks() as u64;
    for field in 0..file.fields().len() {
        let ex = Extractor::new(file, field, 64 << 20).unwrap();
        let s = ex.sampler();
        let octants = all_octants(s);
        if file.has_tight_ranges() {
            assert!(
                check_stored_tight_ranges(s, name) > 0,
                "{name}: no corner checked"
            );
        }
        for iso in isovalues(&mut rng, &octants, file, field) {
            let ctx = format!("{name} field {field} iso {iso}");
            let result = ex.extract(iso).unwrap_or_else(|e| panic!("{ctx}: {e}"));
            culled += result.stats.culled_cells;
            octants_culled += result.stats.culled_octants;
            skipped += result.stats.leaves_skipped;
            parts += result.stats.parts_skipped;
            let refs = &result.refs;
            let want: HashSet<Octant> = octants
                .iter()
                .filter(|(_, v)| straddles(v, iso))
                .map(|(o, _)| *o)
                .collect();
            let mut boxes = Vec::new();
            ex.voxel_boxes(refs, |b| {
                boxes.push(b.unwrap_or_else(|e| panic!("{ctx}: {e}")))
            });
            for (&r, b) in refs.iter().zip(&boxes) {
                assert_eq!(
                    ex.voxel_box(r).unwrap_or_else(|e| panic!("{ctx}: {e}")),
                    *b,
                    "{ctx}: ref {r:#x}: voxel_boxes and voxel_box differ"
                );
            }
            assert_eq!(boxes.len(), refs.len(), "{ctx}: a box per ref");
            let mut covered: HashSet<Octant> = HashSet::new();
            let mut last: Option<u64> = None;
            for &r in refs {
                assert!(
                    last.is_none_or(|l| l < r),
                    "{ctx}: refs not strictly increasing at {r:#x}"
                );
                last = Some(r);
                let (leaf, local) = split_ref(r);
                let dual = matches!(local, LocalVoxel::Dual { .. });
                let vox = ex.decode(r).unwrap_or_else(|e| panic!("{ctx}: {e}"));
                assert_eq!(
                    ex.voxel_box(r).unwrap_or_else(|e| panic!("{ctx}: {e}")),
                    (vox.lo_doubled(), vox.hi_doubled()),
                    "{ctx}: ref {r:#x}: the box from the reference alone differs from the decoded one"
                );
                assert!(
                    straddles(&vox.values, iso),
                    "{ctx}: ref {r:#x} decodes to inactive {vox:?}"
                );
                if let Some((tlo, thi)) = file.tight_range(field, leaf) {
                    assert!(
                        vox.values.iter().all(|&v| tlo <= v && v <= thi),
                        "{ctx}: ref {r:#x} (leaf {leaf}) has a corner outside the stored tight \
                         range {tlo}..{thi}"
                    );
                }
                let (rlo, rhi) = file.leaf_range(field, leaf);
                for v in vox.values {
                    assert!(
                        rlo <= v && v <= rhi,
                        "{ctx}: ref {r:#x} (leaf {leaf}) has corner value {v} outside the stored leaf range \
                         {rlo}..{rhi}: amr-format/src/kdtree/ranges.rs is not conservative"
                    );
                }
                let s_l = s.grid().scale(vox.level);
                let parts: Vec<(Octant, f32)> = if dual {
                    (0..8)
                        .map(|j| {
                            let centre = [0, 1, 2].map(|a| {
                                vox.lo_doubled()[a] + if j >> a & 1 == 1 { 2 * s_l[a] } else { 0 }
                            });
                            let cell = s
                                .locate(s.grid().finest_cell(centre, 7))
                                .unwrap()
                                .unwrap()
                                .cell;
                            (
                                Octant {
                                    level: vox.level,
                                    cell,
                                    octant: 7 - j as u8,
                                },
                                vox.values[j],
                            )
                        })
                        .collect()
                } else {
                    let at = s.grid().finest_cell(
                        [0, 1, 2].map(|a| {
                            vox.lo_doubled()[a] + s_l[a].min(1) - 1
                                + (vox.hi_doubled()[a] - vox.lo_doubled()[a]) / 2
                        }),
                        7,
                    );
                    let c = s.locate(at).unwrap().unwrap();
                    let centre = s.grid().centre(c.level, c.cell);
                    let octant = (0..3)
                        .map(|a| u8::from(vox.lo_doubled()[a] == centre[a]) << a)
                        .sum();
                    let o = Octant {
                        level: c.level,
                        cell: c.cell,
                        octant,
                    };
                    assert_eq!(
                        octants.get(&o),
                        Some(&vox.values),
                        "{ctx}: ref {r:#x} values differ from the reference"
                    );
                    assert!(
                        want.contains(&o),
                        "{ctx}: ref {r:#x} is {o:?}, inactive in the reference"
                    );
                    vec![(o, vox.values[0])]
                };
                if dual {
                    assert!(
                        parts.iter().any(|(o, _)| want.contains(o)),
                        "{ctx}: dual {r:#x} has no active octant"
                    );
                    for (o, centre_value) in &parts {
                        let v = octants
                            .get(o)
                            .unwrap_or_else(|| panic!("{ctx}: dual {r:#x} names unknown {o:?}"));
                        assert_eq!(
                            v[7 - o.octant as usize],
                            *centre_value,
                            "{ctx}: dual {r:#x} corner of {o:?}"
                        );
                    }
                }
                for (o, _) in parts {
                    assert!(covered.insert(o), "{ctx}: octant {o:?} emitted twice");
                }
            }
            let missing: Vec<&Octant> = want.iter().filter(|o| !covered.contains(o)).collect();
            assert!(
                missing.is_empty(),
                "{ctx}: {} active octants not emitted, e.g. {:?}",
                missing.len(),
                missing[0]
            );
            assert_eq!(result.stats.active, refs.len() as u64);
            assert!(result.stats.decompressions <= nb);
        }
    }
    (culled, skipped, parts, octants_culled)
}

#[test]
fn extraction_equals_brute_force() {
    let (mut culled, mut skipped, mut octants) = (0, 0, 0);
    for case in standard_cases(3) {
        let (c, s, o) = check_case(&case);
        culled += c;
        skipped += s;
        octants += o;
    }
    assert!(
        culled > 0,
        "no boundary cell was culled: the test does not exercise culling"
    );
    assert!(
        octants > 0,
        "no boundary octant was culled: the test does not exercise culling them"
    );
    assert!(
        skipped > 0,
        "no leaf was skipped by its tight range: the test does not exercise it"
    );
}

/// The blobs field on the small boxes of `params` (`amr_synth::boxes`), written to `path` with
/// the tight ranges stored when `stored`, and opened.
fn small_boxes_file(
    path: &std::path::Path,
    params: &amr_synth::BoxParams,
    stored: bool,
) -> AmrkFile<Vec<u8>> {
    small_boxes_file_joined(path, params, stored, None)
}

/// [`small_boxes_file`] with runs of consecutive boxes joined into bricks of at most `join`
/// cells per axis, as `amr-convert` joins a dump's small boxes.
fn small_boxes_file_joined(
    path: &std::path::Path,
    params: &amr_synth::BoxParams,
    stored: bool,
    join: Option<i64>,
) -> AmrkFile<Vec<u8>> {
    use amr_synth::{build_box_hierarchy, write_spec, Case as Synth};
    let mut spec = build_box_hierarchy(&Synth::Blobs, "blobs", params).unwrap();
    if let Some(n) = join {
        spec.bricks = amr_format::box_join::join_bricks(
            &spec.bricks,
            n,
            amr_format::box_join::max_open(n, 1),
        );
    }
    let opts = match stored {
        false => Default::default(),
        true => amr_render::extract::writer_options(Default::default()),
    };
    write_spec(
        path,
        spec,
        &Synth::Blobs,
        opts,
        &amr_format::progress::NoProgress,
    )
    .unwrap();
    AmrkFile::open(std::fs::read(path).unwrap()).unwrap()
}

/// Many small irregular boxes with mixed ratios (`amr_synth::boxes`): the leaf tree, the block
/// ranges and the coarse bands meet leaves next to much coarser ones.
#[test]
fn extraction_equals_brute_force_on_small_irregular_boxes() {
    use amr_synth::BoxParams;
    let dir = tempfile::tempdir().unwrap();
    let (mut culled, mut skipped) = (0, 0);
    // Whether small leaves took their neighbourhoods from tiles of cells
    // (`extract::cell_tiles`), which the smaller boxes of some seeds turn on: both ways are met.
    let mut tiled = std::collections::BTreeSet::new();
    // Seed 4 cuts larger boxes into pieces after the levels are laid out, so that fine boxes
    // straddle coarse ones.
    for seed in 1..=4u64 {
        let params = BoxParams {
            base: 6,
            ratios: if seed == 3 { vec![2, 2] } else { vec![2, 4] },
            sizes: match seed {
                3 => (1, 2),
                4 => (4, 8),
                _ => (1, 5),
            },
            seed,
            pieces: (seed == 4).then_some((1, 3)),
        };
        // Without stored tight ranges (computed as the extraction goes) and with them, and
        // with runs of boxes joined into bricks as `amr-convert` joins them.
        let mut unjoined_bricks = usize::MAX;
        for (stored, join) in [(false, None), (true, None), (true, Some(8))] {
            let path = dir
                .path()
                .join(format!("boxes{seed}-{stored}-{join:?}.amrk"));
            let file = small_boxes_file_joined(&path, &params, stored, join);
            match join {
                None => unjoined_bricks = file.num_bricks(),
                Some(_) => assert!(file.num_bricks() < unjoined_bricks, "nothing joined"),
            }
            assert_eq!(file.has_tight_ranges(), stored);
            tiled.insert(
                Extractor::new(&file, 0, 64 << 20)
                    .unwrap()
                    .uses_cell_tiles(),
            );
            let name =
                format!("small boxes {params:?}, stored tight ranges {stored}, joined {join:?}");
            let (c, s, _, _) = check_file(&file, seed, &name);
            culled += c;
            skipped += s;
        }
    }
    assert!(
        culled > 0 && skipped > 0,
        "culled {culled}, skipped {skipped}"
    );
    assert_eq!(tiled.len(), 2, "tiles used: {tiled:?}");
}

/// Small boxes whose leaves take their neighbourhoods from the cell tiles, which the threads
/// share: the refs and counts are the same on one thread, and on more threads than the pool the
/// extractor was made in (threads then share their lists of leaves met), run after run.
#[test]
fn shared_cell_tiles_give_the_same_refs_on_any_thread_count() {
    use amr_synth::BoxParams;
    let dir = tempfile::tempdir().unwrap();
    let params = BoxParams {
        base: 6,
        ratios: vec![2, 2],
        sizes: (1, 2),
        seed: 3,
        pieces: None,
    };
    let file = small_boxes_file(&dir.path().join("boxes.amrk"), &params, true);
    let ex = Extractor::new(&file, 0, 64 << 20).unwrap();
    let cells = ex.extract(0.0).unwrap().stats.file_cells;
    assert!(
        ex.uses_cell_tiles(),
        "{cells} cells in {} leaves: the tiles are not used",
        file.num_leaves()
    );
    let on = |threads: usize, iso: f32| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let out = pool.install(|| ex.extract(iso).unwrap());
        let s = out.stats;
        let counts = (
            s.active_duals,
            s.evaluated,
            s.culled_cells,
            s.culled_octants,
            s.leaves_skipped,
        );
        (out.refs, counts)
    };
    let info = &file.fields()[0];
    for t in [0.3f32, 0.5, 0.7] {
        let iso = info.min + (info.max - info.min) * t;
        let one = on(1, iso);
        assert!(!one.0.is_empty(), "iso {iso}: no active voxel");
        for threads in [2, 3, 7] {
            assert!(
                on(threads, iso) == one,
                "iso {iso}: {threads} threads differ from one"
            );
        }
    }
}

/// Bricks of 12 and 16 cells: leaves larger than a part of [`amr_render::extract::parts`], so
/// that parts whose stored block ranges exclude the isovalue are skipped (blocks of 4 cells cut
/// short at 12).
#[test]
fn extraction_equals_brute_force_on_large_leaves() {
    let mut parts = 0;
    for brick in [12, 16] {
        for mut case in standard_cases(2).into_iter().filter(|c| c.levels <= 3) {
            case.brick = brick;
            case.zstd = case.seed % 2 == 1;
            parts += check_case_parts(&case).2;
        }
    }
    assert!(
        parts > 0,
        "no part of a leaf was skipped: the test does not exercise it"
    );
}

#[test]
fn extraction_equals_brute_force_compressed() {
    for mut case in standard_cases(1) {
        case.zstd = true;
        let _ = check_case(&case);
    }
}

#[test]
fn extraction_is_deterministic_across_runs_and_threads() {
    for case in standard_cases(2) {
        let (_, file) = build(&case);
        let ex = Extractor::new(&file, 1, 64 << 20).unwrap();
        for iso in [0.0f32, 0.125, -0.3, 0.7] {
            let a = ex.extract(iso).unwrap().refs;
            let b = ex.extract(iso).unwrap().refs;
            let one = rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .build()
                .unwrap();
            let c = one.install(|| ex.extract(iso).unwrap().refs);
            let many = rayon::ThreadPoolBuilder::new()
                .num_threads(5)
                .build()
                .unwrap();
            let d = many.install(|| ex.extract(iso).unwrap().refs);
            assert!(
                a == b && a == c && a == d,
                "seed {} ({case:?}) iso {iso}: results differ",
                case.seed
            );
        }
    }
}

#[test]
fn compressed_bricks_are_decoded_once_per_extraction() {
    let mut case = Case::new(77, 3, 2);
    case.zstd = true;
    case.brick = 8;
    let (_, file) = build(&case);
    assert!(
        file.fields()[1].compressed,
        "seed 77: the file holds no compressed brick"
    );
    let ex = Extractor::new(&file, 1, 1 << 30).unwrap();
    let first = ex.extract(0.3).unwrap();
    assert!(
        first.stats.decompressions > 0 && first.stats.decompressions <= file.num_bricks() as u64
    );
    let again = ex.extract(0.3).unwrap();
    assert_eq!(
        again.stats.decompressions, 0,
        "a second extraction finds every brick in the cache"
    );
    assert_eq!(first.refs, again.refs);
    let tiny = Extractor::new(&file, 1, 0).unwrap();
    assert_eq!(
        tiny.extract(0.3).unwrap().refs,
        first.refs,
        "a cache too small for one brick still works"
    );
}

/// An extraction taken in chunks (its file's pages released) runs the refs check after each
/// chunk with the refs found so far, stops with the check's error, and gives the same refs as
/// one without a check when the check passes.
#[test]
fn the_refs_check_runs_after_each_chunk_and_can_stop_the_extraction() {
    use amr_render::mapping::{open_mapped, PageRelease};
    use amr_render::RenderError;
    use amr_synth::BoxParams;
    use std::sync::{Arc, Mutex};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("boxes.amrk");
    let params = BoxParams {
        base: 32,
        ratios: vec![2, 2],
        sizes: (1, 2),
        seed: 5,
        pieces: None,
    };
    small_boxes_file(&path, &params, true);
    let file = open_mapped(&path).unwrap();
    let plain = Extractor::new(&file, 0, 64 << 20).unwrap();
    let iso = 10.0;
    let expected = plain.extract(iso).unwrap();
    assert!(
        expected.stats.leaves_visited > 4096,
        "{} leaves visited: too few for two chunks of 4096",
        expected.stats.leaves_visited
    );
    let seen = Arc::new(Mutex::new(Vec::new()));
    let mut checked = Extractor::new(&file, 0, 64 << 20).unwrap();
    checked.set_page_release(PageRelease::with_floor(&file, 0));
    let log = Arc::clone(&seen);
    checked.set_refs_check(Box::new(move |at, n| {
        log.lock().unwrap().push((at, n));
        Ok(())
    }));
    assert_eq!(checked.extract(iso).unwrap().refs, expected.refs);
    let seen = seen.lock().unwrap().clone();
    assert!(seen.len() >= 2, "checked {} times", seen.len());
    assert!(seen.iter().all(|&(at, _)| at == iso));
    assert!(
        seen.windows(2).all(|w| w[0].1 <= w[1].1) && seen.last().unwrap().1 <= expected.refs.len(),
        "{seen:?}"
    );

    let mut stopped = Extractor::new(&file, 0, 64 << 20).unwrap();
    stopped.set_page_release(PageRelease::with_floor(&file, 0));
    stopped.set_refs_check(Box::new(|_, n| match n {
        0 => Ok(()),
        _ => Err(RenderError::Invalid(format!("{n} refs: too many"))),
    }));
    let err = stopped.extract(iso).unwrap_err().to_string();
    assert!(err.contains("refs: too many"), "{err}");
}
