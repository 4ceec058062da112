//! The brick hierarchy of a synthetic dataset: metadata only, built level by level in integer
//! index space.
//!
//! Level 0 is the whole domain cut into bricks. A candidate brick of level `l + 1` is one of the
//! brick-sized blocks that tile a level-`l` brick refined by the ratio; it is kept when a
//! criterion accepts it. Candidates come only from existing bricks, so every fine brick lies inside
//! one coarser brick (proper nesting) and bricks of one level never overlap, for any brick size
//! and ratio.

use amr_format::{BrickSpec, FormatError, HierarchySpec, IBox};
use rayon::prelude::*;

use crate::fields::AnalyticField;
use crate::params::SynthParams;

/// Sample points per axis used by [`near_surface`].
const SAMPLES: usize = 5;
/// Slack on the sampling radius in [`near_surface`], for curvature between samples.
const SAFETY: f64 = 1.5;

/// A candidate brick, as a refinement criterion sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Block {
    /// The level the brick would belong to (at least 1).
    pub level: u32,
    /// Its cells in that level's index space.
    pub cells: IBox,
    /// Lower corner in unit-cube coordinates.
    pub lo: [f64; 3],
    /// Upper corner in unit-cube coordinates.
    pub hi: [f64; 3],
    /// Edge of one cell of the parent level, in unit-cube coordinates.
    pub parent_cell: f64,
}

/// The hierarchy of `field` (on the unit cube), refined around its default isosurface.
///
/// The single field is named after `name`.
pub fn build_hierarchy<F>(
    field: &F,
    name: &str,
    params: &SynthParams,
) -> Result<HierarchySpec, FormatError>
where
    F: AnalyticField + Sync,
{
    let iso = field.default_iso();
    build_hierarchy_by(params, vec![name.to_owned()], |b| {
        near_surface(field, iso, b)
    })
}

/// The hierarchy whose level-`l + 1` bricks are the candidates `refine` accepts.
///
/// Requested levels that end up without bricks are dropped, so the finest level has bricks.
/// Bricks are listed level by level, in the order their parents were.
pub fn build_hierarchy_by<R>(
    params: &SynthParams,
    fields: Vec<String>,
    refine: R,
) -> Result<HierarchySpec, FormatError>
where
    R: Fn(&Block) -> bool + Sync,
{
    let mut levels = params.level_specs()?;
    let mut bricks = Vec::new();
    let used = walk_levels(params, &refine, |level, boxes| {
        bricks.extend(boxes.iter().map(|&cells| BrickSpec { level, cells }));
        true
    });
    levels.truncate(used as usize);
    if let Some(last) = levels.last_mut() {
        last.ratio_to_next = [1; 3];
    }
    Ok(HierarchySpec {
        levels,
        fields,
        bricks,
    })
}

/// True when the isosurface `iso` of `field` passes through or near `block`.
///
/// The field is sampled on a `5^3` grid over the block grown by one parent cell; the block is
/// near the surface when the samples straddle `iso` or one of them lies within the sampling
/// radius of it, by the field's [`AnalyticField::distance_estimate`]. A block that the field's
/// [`AnalyticField::distance_lower_bound`] at its centre puts beyond that reach is rejected after
/// one evaluation.
pub fn near_surface<F: AnalyticField + ?Sized>(field: &F, iso: f64, block: &Block) -> bool {
    let lo = block.lo.map(|x| x - block.parent_cell);
    let hi = block.hi.map(|x| x + block.parent_cell);
    let step = [0, 1, 2].map(|a| (hi[a] - lo[a]) / (SAMPLES - 1) as f64);
    let radius = SAFETY * 0.5 * length(step);
    let centre = [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a]));
    let half_diagonal = 0.5 * length([0, 1, 2].map(|a| hi[a] - lo[a]));
    if field.distance_lower_bound(centre, iso) > half_diagonal + radius {
        return false;
    }
    let mut side = None;
    for k in 0..SAMPLES {
        for j in 0..SAMPLES {
            for i in 0..SAMPLES {
                let p = [
                    lo[0] + i as f64 * step[0],
                    lo[1] + j as f64 * step[1],
                    lo[2] + k as f64 * step[2],
                ];
                let above = field.value(p) > iso;
                if *side.get_or_insert(above) != above || field.distance_estimate(p, iso) <= radius
                {
                    return true;
                }
            }
        }
    }
    false
}

fn length(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Builds the levels in turn, handing each level's brick boxes to `visit`; stops when a level
/// has no bricks or `visit` returns false. Returns the number of levels visited.
pub(crate) fn walk_levels<R, V>(params: &SynthParams, refine: &R, mut visit: V) -> u32
where
    R: Fn(&Block) -> bool + Sync,
    V: FnMut(u32, &[IBox]) -> bool,
{
    let b = i64::from(params.brick);
    let r = i64::from(params.ratio);
    let n0 = i64::from(params.base);
    let mut current = IBox::new([0; 3], [n0; 3]).split([b; 3]);
    if !visit(0, &current) {
        return 1;
    }
    for level in 1..params.levels {
        let n = params.cells_per_axis(level).expect("validated") as f64;
        let children: Vec<IBox> = current
            .par_iter()
            .flat_map_iter(|parent| {
                let fine = parent
                    .refine([r; 3])
                    .expect("validated: the finest level fits in i64");
                fine.split([b; 3]).into_iter().filter(|&cells| {
                    let block = Block {
                        level,
                        cells,
                        lo: cells.lo.map(|i| i as f64 / n),
                        hi: cells.hi.map(|i| i as f64 / n),
                        parent_cell: r as f64 / n,
                    };
                    refine(&block)
                })
            })
            .collect();
        if children.is_empty() {
            return level;
        }
        current = children;
        if !visit(level, &current) {
            return level + 1;
        }
    }
    params.levels
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fields::Case;
    use std::collections::HashMap;

    fn params(levels: u32, ratio: u32, base: u32, brick: u32) -> SynthParams {
        SynthParams {
            levels,
            ratio,
            base,
            brick,
            ..SynthParams::default()
        }
    }

    /// Asserts that level 0 tiles the domain, that no two bricks of a level overlap, and that every
    /// finer brick lies inside one brick of the level above.
    ///
    /// Bricks must start on multiples of the brick size and be no larger: then distinct lower
    /// corners mean no overlap, and a brick's parent is found from its corner.
    fn check_structure(spec: &HierarchySpec, brick: i64) {
        spec.validate().unwrap();
        let nl = spec.levels.len();
        let mut by_level: Vec<HashMap<[i64; 3], IBox>> = vec![HashMap::new(); nl];
        for b in &spec.bricks {
            let c = b.cells;
            assert!(
                c.lo.iter().all(|x| x % brick == 0) && c.extent().iter().all(|&e| e <= brick),
                "unaligned {c:?}"
            );
            assert!(
                by_level[b.level as usize].insert(c.lo, c).is_none(),
                "level {}: two bricks at {:?}",
                b.level,
                c.lo
            );
        }
        let level0: u64 = by_level[0].values().map(|b| b.num_cells().unwrap()).sum();
        assert_eq!(level0, spec.levels[0].domain.num_cells().unwrap());
        for l in 1..nl {
            assert!(!by_level[l].is_empty(), "level {l} has no bricks");
            let r = spec.levels[l - 1].ratio_to_next.map(i64::from);
            for b in by_level[l].values() {
                let inside = b.coarsen(r);
                let corner = inside.lo.map(|x| x.div_euclid(brick) * brick);
                let parent = by_level[l - 1].get(&corner);
                assert!(
                    parent.is_some_and(|p| p.contains_box(&inside)),
                    "level {l} brick {b:?} is not inside one level-{} brick",
                    l - 1
                );
            }
        }
    }

    #[test]
    fn nested_without_overlap_for_ratios_2_and_4() {
        for case in Case::ALL {
            for (levels, ratio, base, brick) in [
                (3, 2, 32, 8),
                (4, 4, 8, 8),
                (3, 4, 12, 6),
                (3, 3, 20, 7),
                (2, 2, 16, 16),
            ] {
                let p = params(levels, ratio, base, brick);
                let spec = build_hierarchy(&case, case.name(), &p).unwrap();
                assert_eq!(spec.levels.len(), levels as usize, "{case} {p:?}");
                check_structure(&spec, i64::from(brick));
            }
        }
    }

    #[test]
    fn nine_levels() {
        let spec = build_hierarchy(&Case::Sphere, "sphere", &params(9, 2, 4, 4)).unwrap();
        assert_eq!(spec.levels.len(), 9);
        check_structure(&spec, 4);
        let target = [0.3, 0.7, 0.41];
        for ratio in [2, 3, 4] {
            let spec = build_hierarchy_by(&params(9, ratio, 8, 4), vec!["v".into()], |b| {
                (0..3).all(|a| {
                    b.lo[a] - b.parent_cell <= target[a] && target[a] <= b.hi[a] + b.parent_cell
                })
            })
            .unwrap();
            assert_eq!(spec.levels.len(), 9);
            check_structure(&spec, 4);
        }
    }

    #[test]
    fn refined_only_near_the_surface() {
        for case in Case::ALL {
            let p = params(4, 2, 32, 8);
            let spec = build_hierarchy(&case, case.name(), &p).unwrap();
            let iso = case.default_iso();
            for b in spec.bricks.iter().filter(|b| b.level > 0) {
                let n = spec.levels[b.level as usize].domain.hi[0] as f64;
                let reach = (b.cells.extent()[0] + 2) as f64 / n;
                let (lo, hi) = (
                    b.cells.lo.map(|x| x as f64 / n - reach),
                    b.cells.hi.map(|x| x as f64 / n + reach),
                );
                let m = 8;
                let side = |i: usize, j: usize, k: usize| {
                    let t = [i, j, k].map(|x| x as f64 / m as f64);
                    case.value([0, 1, 2].map(|a| lo[a] + t[a] * (hi[a] - lo[a]))) > iso
                };
                let first = side(0, 0, 0);
                let crosses =
                    (0..=m).any(|i| (0..=m).any(|j| (0..=m).any(|k| side(i, j, k) != first)));
                assert!(
                    crosses,
                    "{case}: level {} brick {:?} is far from the surface",
                    b.level, b.cells
                );
            }
            let finest = spec.levels.len() - 1;
            let fine_cells: u64 = spec
                .bricks
                .iter()
                .filter(|b| b.level as usize == finest)
                .map(|b| b.cells.num_cells().unwrap())
                .sum();
            let fraction =
                fine_cells as f64 / spec.levels[finest].domain.num_cells().unwrap() as f64;
            assert!(
                fraction < 0.5,
                "{case}: {fraction} of the finest level is refined"
            );
        }
    }

    #[test]
    fn every_surface_crossing_is_refined() {
        for case in Case::ALL {
            let spec = build_hierarchy(&case, case.name(), &params(3, 2, 16, 4)).unwrap();
            let finest = spec.levels.len() - 1;
            let n = spec.levels[finest].domain.hi[0];
            let fine: Vec<IBox> = spec
                .bricks
                .iter()
                .filter(|b| b.level as usize == finest)
                .map(|b| b.cells)
                .collect();
            let iso = case.default_iso();
            let above = |c: [i64; 3]| case.value(c.map(|x| (x as f64 + 0.5) / n as f64)) > iso;
            let covered = |c: [i64; 3]| fine.iter().any(|b| b.contains_cell(c));
            for c in IBox::new([0; 3], [n; 3])
                .split([1; 3])
                .into_iter()
                .map(|b| b.lo)
            {
                for a in 0..3 {
                    let mut d = c;
                    d[a] += 1;
                    if d[a] < n && above(c) != above(d) {
                        assert!(
                            covered(c) && covered(d),
                            "{case}: crossing between {c:?} and {d:?} is not refined"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn arbitrary_criteria_stay_nested() {
        for seed in 0..20u64 {
            let ratio = 2 + (seed % 3) as u32;
            let brick = 4 + (seed % 2) as u32 * 4;
            let p = params(
                2 + (seed % 6) as u32,
                ratio,
                8 + 4 * (seed % 3) as u32,
                brick,
            );
            let spec = build_hierarchy_by(&p, vec!["v".into()], |b| {
                let h = (b.cells.lo[0] as u64 * 73856093)
                    ^ (b.cells.lo[1] as u64 * 19349663)
                    ^ (b.cells.lo[2] as u64 * 83492791);
                ((h ^ seed).wrapping_mul(0x9E3779B97F4A7C15) >> 32) % u64::from(ratio.pow(3)) < 2
            })
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
            check_structure(&spec, i64::from(brick));
        }
    }

    #[test]
    fn empty_finer_levels_are_dropped() {
        let spec =
            build_hierarchy_by(&params(5, 2, 16, 8), vec!["v".into()], |b| b.level < 2).unwrap();
        assert_eq!(spec.levels.len(), 2);
        assert_eq!(spec.levels[1].ratio_to_next, [1; 3]);
    }

    #[test]
    fn bad_parameters_are_named() {
        let e = build_hierarchy(&Case::Blobs, "blobs", &params(3, 1, 16, 8)).unwrap_err();
        assert!(e.to_string().contains("--ratio"), "{e}");
        let e = build_hierarchy(&Case::Blobs, "blobs", &params(30, 4, 16, 8)).unwrap_err();
        assert!(e.to_string().contains("finest"), "{e}");
    }
}
