//! The extraction's leaf tree, in the kd-tree's shape and split at medians alike, finds the
//! leaves a scan of every leaf finds, and the coarsest level among them, on seeded random
//! hierarchies. Failures name their seed.

use crate::support::hierarchy::{build, standard_cases, Rng};
use amr_format::IBox;
use amr_render::extract::leaf_tree::{LeafTree, Met};
use amr_render::reconstruct::Sampler;

#[test]
fn leaf_tree_queries_equal_a_scan_of_every_leaf() {
    let mut leaves_seen = 0;
    for case in standard_cases(2) {
        let (_, file) = build(&case);
        let sampler = Sampler::new(&file, 0, 1 << 20).unwrap();
        let trees = [
            ("kd-tree shape", LeafTree::new(&sampler)),
            ("median splits", LeafTree::median(&sampler)),
        ];
        let tree = file.tree();
        let n = tree.num_leaves() as u32;
        leaves_seen += n;
        let extent = tree.domain.extent();
        let mut rng = Rng(case.seed ^ 0x5eed);
        for q in 0..300 {
            // Boxes of every size, some flat (a face), some past the domain.
            let lo = extent.map(|e| rng.range(-2, e + 1));
            let hi = [0, 1, 2].map(|a| lo[a] + rng.range(0, extent[a] / (1 + q % 4) + 2));
            let region = IBox::new(lo, hi);
            let scan = |test: &dyn Fn(&IBox) -> bool| -> Vec<u32> {
                (0..n).filter(|&l| test(&tree.leaf_box(l))).collect()
            };
            let touching = scan(&|b: &IBox| b.touches(&region));
            let overlapping = scan(&|b: &IBox| b.overlaps(&region));
            let coarsest = touching
                .iter()
                .filter_map(|&l| sampler.leaf_top(l).map(|(_, level)| level))
                .min();
            for (name, t) in &trees {
                let what = format!("seed {}, {name}, region {region:?}", case.seed);
                let mut got = Vec::new();
                t.for_each_leaf_touching(&region, |l| got.push(l));
                got.sort_unstable();
                assert_eq!(got, touching, "touching: {what}");
                got.clear();
                t.for_each_leaf_overlapping(&region, |l| got.push(l));
                got.sort_unstable();
                assert_eq!(got, overlapping, "overlapping: {what}");
                assert_eq!(
                    t.coarsest_touching(&sampler, &region),
                    coarsest,
                    "coarsest: {what}"
                );
                for l in 0..n {
                    assert_eq!(t.leaf_box(l), tree.leaf_box(l), "leaf box {l}: {what}");
                }
            }
        }
    }
    assert!(
        leaves_seen > 1000,
        "only {leaves_seen} leaves over all cases"
    );
}

/// `LeafTree::exact_range_over` (the coarse-cell bounds of small cells) gives the range a scan
/// of every leaf's cells inside the region gives, NaNs left out, or `None` exactly when a leaf
/// with data coarser than the level asked overlaps the region; asked twice, so that the
/// second answer comes from the kept leaf and node ranges.
#[test]
fn exact_range_over_equals_a_scan_of_every_leaf() {
    use amr_render::extract::blocks::{level_box, BlockRanges};
    let (mut ranges, mut coarser) = (0, 0);
    for case in standard_cases(2) {
        let (_, file) = build(&case);
        let sampler = Sampler::new(&file, 0, 1 << 20).unwrap();
        let blocks = BlockRanges::new(&file);
        let grid = sampler.grid();
        let trees = [
            ("kd-tree shape", LeafTree::new(&sampler)),
            ("median splits", LeafTree::median(&sampler)),
        ];
        let tree = file.tree();
        let n = tree.num_leaves() as u32;
        let extent = tree.domain.extent();
        let levels = grid.num_levels() as i64;
        let mut rng = Rng(case.seed ^ 0xe4ac7);
        for q in 0..200 {
            let lo = extent.map(|e| rng.range(-2, e + 1));
            let hi = [0, 1, 2].map(|a| lo[a] + rng.range(1, extent[a] / (1 + q % 4) + 2));
            let region = IBox::new(lo, hi);
            let level = rng.range(0, levels) as u32;
            let mut want = Some((f32::INFINITY, f32::NEG_INFINITY));
            for l in 0..n {
                let leaf_box = tree.leaf_box(l);
                let Some((brick, lv)) = sampler.leaf_top(l) else {
                    continue;
                };
                if !leaf_box.overlaps(&region) {
                    continue;
                }
                if lv < level {
                    want = None;
                    break;
                }
                let bc = sampler.brick_cells(brick);
                let cells = level_box(grid, lv, &leaf_box.intersect(&region)).intersect(&bc);
                let values = sampler.values(brick).unwrap();
                let w = want.as_mut().unwrap();
                for z in cells.lo[2]..cells.hi[2] {
                    for y in cells.lo[1]..cells.hi[1] {
                        for x in cells.lo[0]..cells.hi[0] {
                            let v = values[bc.linear_index([x, y, z])];
                            if v < w.0 {
                                w.0 = v;
                            }
                            if v > w.1 {
                                w.1 = v;
                            }
                        }
                    }
                }
            }
            match want {
                Some(_) => ranges += 1,
                None => coarser += 1,
            }
            for (name, t) in &trees {
                let what = format!(
                    "seed {}, {name}, region {region:?}, level {level}",
                    case.seed
                );
                for pass in ["first", "second"] {
                    let got = t
                        .exact_range_over(&sampler, &blocks, &region, level)
                        .unwrap();
                    assert_eq!(got, want, "{pass} ask: {what}");
                }
            }
        }
    }
    assert!(
        ranges > 100 && coarser > 100,
        "{ranges} ranges and {coarser} coarser answers over all cases"
    );
}

/// `around_block` (the bounds around a block of coarse cells, computed together) gives for
/// each cell of the block what `LeafTree::exact_range_over` gives for the 27 cells around
/// it, at every level: the same range, or `None` exactly where a coarser leaf cell lies there.
#[test]
fn block_bounds_equal_the_exact_range_around_each_cell() {
    use amr_render::extract::around_block::{around_block, BLOCK};
    use amr_render::extract::blocks::BlockRanges;
    let (mut ranges, mut coarser) = (0, 0);
    for case in standard_cases(2) {
        let (_, file) = build(&case);
        let sampler = Sampler::new(&file, 0, 1 << 20).unwrap();
        let blocks = BlockRanges::new(&file);
        let grid = sampler.grid();
        let leaves = LeafTree::new(&sampler);
        let mut touching = Vec::new();
        let mut rng = Rng(case.seed ^ 0xb10c);
        for _ in 0..40 {
            let level = rng.range(0, grid.num_levels() as i64) as u32;
            let (s, o) = (grid.scale(level), grid.offset());
            let domain = file.tree().domain;
            // Cells of the level over the domain, and one beyond.
            let c = [0, 1, 2].map(|a| {
                rng.range(
                    (domain.lo[a] + o[a]).div_euclid(s[a]) - 1,
                    (domain.hi[a] + o[a]).div_euclid(s[a]) + 2,
                )
            });
            let cells = IBox::new(c, c.map(|v| v + BLOCK));
            let got =
                around_block((&sampler, &blocks, &leaves), level, &cells, &mut touching).unwrap();
            for z in cells.lo[2]..cells.hi[2] {
                for y in cells.lo[1]..cells.hi[1] {
                    for x in cells.lo[0]..cells.hi[0] {
                        let p = [x, y, z];
                        let finest = IBox::new(
                            [0, 1, 2].map(|a| (p[a] - 1) * s[a] - o[a]),
                            [0, 1, 2].map(|a| (p[a] + 2) * s[a] - o[a]),
                        );
                        let want = leaves
                            .exact_range_over(&sampler, &blocks, &finest, level)
                            .unwrap();
                        match want {
                            Some(_) => ranges += 1,
                            None => coarser += 1,
                        }
                        assert_eq!(
                            got[cells.linear_index(p)],
                            want,
                            "seed {}, level {level}, block {cells:?}, cell {p:?}",
                            case.seed
                        );
                    }
                }
            }
        }
    }
    assert!(
        ranges > 100 && coarser > 100,
        "{ranges} ranges and {coarser} coarser answers over all cases"
    );
}

/// `LeafTree::for_each_overlapping_grouped` hands over the leaves `for_each_leaf_overlapping`
/// finds, in the same order, with some runs of them as one node: a node inside the region, for
/// which the test held with its box (the union of its leaves'), its leaves' coarsest level with
/// data and whether all have data, and whose kept exact range is the union of its leaves'.
#[test]
fn grouped_walk_gives_the_overlapping_leaves_in_order() {
    let mut nodes_met = 0;
    for case in standard_cases(2) {
        let (_, file) = build(&case);
        let sampler = Sampler::new(&file, 0, 1 << 20).unwrap();
        let trees = [
            ("kd-tree shape", LeafTree::new(&sampler)),
            ("median splits", LeafTree::median(&sampler)),
        ];
        let tree = file.tree();
        let extent = tree.domain.extent();
        let mut rng = Rng(case.seed ^ 0x960e);
        for q in 0..200 {
            let lo = extent.map(|e| rng.range(-2, e + 1));
            let hi = [0, 1, 2].map(|a| lo[a] + rng.range(1, extent[a] / (1 + q % 4) + 2));
            let region = IBox::new(lo, hi);
            // Nodes up to this many cells are taken whole.
            let most = rng.range(1, 4096);
            for (name, t) in &trees {
                let what = format!("seed {}, {name}, region {region:?}", case.seed);
                let mut want = Vec::new();
                t.for_each_leaf_overlapping(&region, |l| want.push(l));
                let asked = std::cell::RefCell::new(Vec::new());
                let whole = |b: &IBox, coarsest: u32, complete: bool| {
                    let take = b.num_cells().is_some_and(|c| c <= most as u64);
                    if take {
                        asked.borrow_mut().push((*b, coarsest, complete));
                    }
                    take
                };
                let mut got = Vec::new();
                t.for_each_overlapping_grouped(&region, whole, |m| match m {
                    Met::Leaf(l) => got.push(l),
                    Met::Node(n) => {
                        nodes_met += 1;
                        let leaves = t.node_leaves(n);
                        let b = t.node_box(n);
                        assert!(region.contains_box(&b), "node inside: {what}");
                        let union = leaves
                            .iter()
                            .map(|&l| tree.leaf_box(l))
                            .reduce(|a, c| a.union(&c))
                            .unwrap();
                        assert_eq!(b, union, "node box: {what}");
                        let levels: Vec<Option<u32>> = leaves
                            .iter()
                            .map(|&l| sampler.leaf_top(l).map(|(_, lv)| lv))
                            .collect();
                        let coarsest = levels.iter().flatten().min().copied().unwrap_or(u32::MAX);
                        let complete = levels.iter().all(Option::is_some);
                        assert!(
                            asked.borrow().contains(&(b, coarsest, complete)),
                            "node asked about with its box, level and completeness: {what}"
                        );
                        let mut range = (f32::INFINITY, f32::NEG_INFINITY);
                        for &l in leaves {
                            let (a, z) = t.exact_range(&sampler, l).unwrap();
                            range = (range.0.min(a), range.1.max(z));
                        }
                        let kept = t.exact_node_range(&sampler, n).unwrap();
                        assert_eq!(kept, range, "node range: {what}");
                        got.extend_from_slice(leaves);
                    }
                });
                assert_eq!(got, want, "leaves in order: {what}");
            }
        }
    }
    assert!(nodes_met > 100, "only {nodes_met} nodes taken whole");
}
