//! The extraction's leaf tree, in the kd-tree's shape and split at medians alike, finds the
//! leaves a scan of every leaf finds, and the coarsest level among them, on seeded random
//! hierarchies. Failures name their seed.

use crate::support::hierarchy::{build, standard_cases, Rng};
use amr_format::IBox;
use amr_render::extract::leaf_tree::LeafTree;
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
