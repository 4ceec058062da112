//! Hierarchies of many small, irregular boxes with mixed refinement ratios, as AMReX, Chombo and
//! Enzo runs produce: the stress case for extraction, where leaves are many and small.
//!
//! Each level is cut into boxes whose extents along each axis are drawn (deterministically, from
//! a seed) between a smallest and a largest size, so boxes are not aligned to any brick grid. A
//! box of level `l + 1` is one of the pieces that cut a level-`l` box refined by that level's
//! ratio, kept when it lies near the isosurface ([`near_surface`]) and when the cells of level `l`
//! within one cell of it are all covered by level `l` (proper nesting with a buffer of one cell,
//! as AMReX keeps it): fine boxes lie inside one coarser box and boxes of a level never overlap.

use amr_format::{BrickSpec, FormatError, HierarchySpec, IBox, LevelSpec};
use rayon::prelude::*;

use crate::fields::AnalyticField;
use crate::refine::{near_surface, Block};

/// The layout of a hierarchy of irregular boxes on the unit cube.
#[derive(Clone, Debug, PartialEq)]
pub struct BoxParams {
    /// Cells per axis of level 0.
    pub base: u32,
    /// The refinement ratio from each level to the next: one entry per level past the first.
    pub ratios: Vec<u32>,
    /// The smallest and largest box extent along an axis, in cells of the box's level.
    pub sizes: (u32, u32),
    /// Seed of the box extents.
    pub seed: u64,
    /// When set, every box is cut afterwards into pieces of these extents (smallest, largest;
    /// cells of the box's level, rounded up to whole parent cells): the same levels and cells,
    /// so the same field on the same refined region, in more and smaller boxes.
    pub pieces: Option<(u32, u32)>,
}

impl BoxParams {
    /// Checks every parameter, naming the one at fault.
    pub fn validate(&self) -> Result<(), FormatError> {
        let bad = |m: String| Err(FormatError::InvalidHierarchy(m));
        for (what, (lo, hi)) in [("box sizes", Some(self.sizes)), ("box pieces", self.pieces)]
            .into_iter()
            .filter_map(|(what, s)| Some((what, s?)))
        {
            if lo == 0 || lo > hi || i64::from(hi) > amr_format::hierarchy::MAX_BRICK_EXTENT {
                return bad(format!("{what} {lo}..{hi} (need 1 <= min <= max <= 1024)"));
            }
        }
        if self.base == 0 {
            return bad("base 0 (must be at least 1)".into());
        }
        if let Some(r) = self.ratios.iter().find(|&&r| r < 2) {
            return bad(format!("ratio {r} (must be at least 2)"));
        }
        if self.ratios.len() + 1 > amr_format::hierarchy::MAX_LEVELS {
            return bad(format!("{} levels is too many", self.ratios.len() + 1));
        }
        match self.cells_per_axis(self.ratios.len()) {
            Some(n) if n <= amr_format::hierarchy::MAX_FINEST_EXTENT => Ok(()),
            _ => bad("the finest level has too many cells per axis".into()),
        }
    }

    /// Cells per axis of level `level`, or `None` if it overflows.
    fn cells_per_axis(&self, level: usize) -> Option<i64> {
        self.ratios[..level]
            .iter()
            .try_fold(i64::from(self.base), |n, &r| n.checked_mul(i64::from(r)))
    }
}

/// The hierarchy of irregular boxes of `params`, refined around `field`'s default isosurface;
/// its one field is named `name`. Levels left without boxes are dropped. With
/// [`BoxParams::pieces`], each box is then cut into pieces, after the levels are laid out.
pub fn build_box_hierarchy<F: AnalyticField + Sync>(
    field: &F,
    name: &str,
    params: &BoxParams,
) -> Result<HierarchySpec, FormatError> {
    params.validate()?;
    let iso = field.default_iso();
    let n = |l: usize| params.cells_per_axis(l).expect("validated");
    let mut current = cut(
        &IBox::new([0; 3], [n(0); 3]),
        params.sizes,
        params.seed,
        0,
        1,
    );
    let mut bricks: Vec<BrickSpec> = current
        .iter()
        .map(|&cells| BrickSpec { level: 0, cells })
        .collect();
    let mut levels = 1;
    for (l, &ratio) in params.ratios.iter().enumerate() {
        let level = l + 1;
        let cells_per_axis = n(level) as f64;
        let r = i64::from(ratio);
        let children: Vec<IBox> = current
            .par_iter()
            .flat_map_iter(|parent| {
                let fine = parent.refine([r; 3]).expect("validated");
                cut(&fine, params.sizes, params.seed, level as u64, r)
                    .into_iter()
                    .filter(move |&cells| {
                        let block = Block {
                            level: level as u32,
                            cells,
                            lo: cells.lo.map(|i| i as f64 / cells_per_axis),
                            hi: cells.hi.map(|i| i as f64 / cells_per_axis),
                            parent_cell: r as f64 / cells_per_axis,
                        };
                        near_surface(field, iso, &block)
                    })
            })
            .collect();
        let covered = Coverage::new(&current, n(l))?;
        let children: Vec<IBox> = children
            .into_par_iter()
            .filter(|c| covered.holds(&c.coarsen([r; 3]).grow([1; 3])))
            .collect();
        if children.is_empty() {
            break;
        }
        bricks.extend(children.iter().map(|&cells| BrickSpec {
            level: level as u32,
            cells,
        }));
        current = children;
        levels += 1;
    }
    let specs = (0..levels)
        .map(|l| {
            let cells = n(l);
            let ratio = if l + 1 < levels { params.ratios[l] } else { 1 };
            LevelSpec {
                cell_size: [1.0 / cells as f64; 3],
                origin: [0.0; 3],
                ratio_to_next: [ratio; 3],
                domain: IBox::new([0; 3], [cells; 3]),
            }
        })
        .collect();
    if let Some(pieces) = params.pieces {
        // Another seed than the layout's, so the pieces' cuts do not repeat the boxes' own.
        let seed = !params.seed;
        bricks = bricks
            .iter()
            .flat_map(|b| {
                let unit = match b.level {
                    0 => 1,
                    l => i64::from(params.ratios[l as usize - 1]),
                };
                cut(&b.cells, pieces, seed, u64::from(b.level), unit)
                    .into_iter()
                    .map(|cells| BrickSpec {
                        level: b.level,
                        cells,
                    })
            })
            .collect();
    }
    Ok(HierarchySpec {
        levels: specs,
        fields: vec![name.to_owned()],
        bricks,
    })
}

/// The cells of one level covered by its boxes, one bit per cell of the level's domain.
struct Coverage {
    n: i64,
    bits: Vec<u64>,
}

impl Coverage {
    /// The cells of `boxes` in a domain of `n` cells per axis.
    fn new(boxes: &[IBox], n: i64) -> Result<Self, FormatError> {
        let cells = n.checked_pow(3).filter(|&c| c <= 1 << 33).ok_or_else(|| {
            FormatError::InvalidHierarchy(format!(
                "{n} cells per axis is too many for the nesting map of the box generator"
            ))
        })?;
        let mut bits = vec![0u64; (cells as usize).div_ceil(64)];
        for b in boxes {
            for z in b.lo[2]..b.hi[2] {
                for y in b.lo[1]..b.hi[1] {
                    for x in b.lo[0]..b.hi[0] {
                        let i = ((z * n + y) * n + x) as usize;
                        bits[i / 64] |= 1 << (i % 64);
                    }
                }
            }
        }
        Ok(Self { n, bits })
    }

    /// True when every cell of `b` inside the domain is covered.
    fn holds(&self, b: &IBox) -> bool {
        let n = self.n;
        let b = b.intersect(&IBox::new([0; 3], [n; 3]));
        (b.lo[2]..b.hi[2]).all(|z| {
            (b.lo[1]..b.hi[1]).all(|y| {
                (b.lo[0]..b.hi[0]).all(|x| {
                    let i = ((z * n + y) * n + x) as usize;
                    self.bits[i / 64] >> (i % 64) & 1 == 1
                })
            })
        })
    }
}

/// `region` cut into boxes whose extents along each axis are drawn from `sizes` and rounded up
/// to a multiple of `unit` (the ratio to the parent level, so that every box is made of whole
/// parent cells); the cuts along an axis depend on the seed, the level, the axis and the
/// region's position.
fn cut(region: &IBox, sizes: (u32, u32), seed: u64, level: u64, unit: i64) -> Vec<IBox> {
    let spans: [Vec<(i64, i64)>; 3] = std::array::from_fn(|a| {
        let key = seed ^ level << 56 ^ (a as u64) << 48 ^ region.lo[a] as u64;
        spans(region.lo[a], region.hi[a], sizes, unit, key)
    });
    let mut out = Vec::with_capacity(spans.iter().map(Vec::len).product());
    for &(z0, z1) in &spans[2] {
        for &(y0, y1) in &spans[1] {
            for &(x0, x1) in &spans[0] {
                out.push(IBox::new([x0, y0, z0], [x1, y1, z1]));
            }
        }
    }
    out
}

/// `lo..hi` cut into consecutive spans of `min..=max` cells rounded up to a multiple of `unit`
/// (the last may be shorter), the lengths drawn from a hash of `key`.
fn spans(lo: i64, hi: i64, (min, max): (u32, u32), unit: i64, key: u64) -> Vec<(i64, i64)> {
    let mut out = Vec::new();
    let mut at = lo;
    let mut state = key;
    while at < hi {
        state = splitmix(state);
        let len = i64::from(min) + (state % u64::from(max - min + 1)) as i64;
        let len = (len + unit - 1) / unit * unit;
        let end = (at + len).min(hi);
        out.push((at, end));
        at = end;
    }
    out
}

/// One step of the splitmix64 generator.
fn splitmix(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fields::Case;

    #[test]
    fn pieces_hold_the_same_cells_in_more_boxes() {
        let whole = BoxParams {
            base: 16,
            ratios: vec![2, 4],
            sizes: (8, 8),
            seed: 1,
            pieces: None,
        };
        let cut = BoxParams {
            pieces: Some((1, 3)),
            ..whole.clone()
        };
        let a = build_box_hierarchy(&Case::Blobs, "blobs", &whole).unwrap();
        let b = build_box_hierarchy(&Case::Blobs, "blobs", &cut).unwrap();
        b.validate().unwrap();
        assert_eq!(a.levels, b.levels);
        assert!(
            b.bricks.len() > 4 * a.bricks.len(),
            "{} boxes",
            b.bricks.len()
        );
        for level in 0..a.levels.len() as u32 {
            let cells = |s: &HierarchySpec| {
                let mut v: Vec<[i64; 3]> = s
                    .bricks
                    .iter()
                    .filter(|b| b.level == level)
                    .flat_map(|b| {
                        let c = b.cells;
                        (c.lo[2]..c.hi[2]).flat_map(move |z| {
                            (c.lo[1]..c.hi[1])
                                .flat_map(move |y| (c.lo[0]..c.hi[0]).map(move |x| [x, y, z]))
                        })
                    })
                    .collect();
                v.sort_unstable();
                v
            };
            let (ca, cb) = (cells(&a), cells(&b));
            assert_eq!(ca, cb, "level {level}");
            assert!(
                cb.windows(2).all(|w| w[0] != w[1]),
                "level {level} overlaps"
            );
        }
        let extents: std::collections::BTreeSet<i64> =
            b.bricks.iter().flat_map(|b| b.cells.extent()).collect();
        assert!(extents.iter().all(|&e| e <= 4), "{extents:?}");
    }

    #[test]
    fn boxes_nest_do_not_overlap_and_vary_in_size() {
        let params = BoxParams {
            base: 16,
            ratios: vec![2, 4],
            sizes: (2, 7),
            seed: 1,
            pieces: None,
        };
        let spec = build_box_hierarchy(&Case::Blobs, "blobs", &params).unwrap();
        spec.validate().unwrap();
        assert_eq!(spec.levels.len(), 3);
        assert_eq!(spec.levels[0].ratio_to_next, [2; 3]);
        assert_eq!(spec.levels[1].ratio_to_next, [4; 3]);
        let level0: u64 = spec
            .bricks
            .iter()
            .filter(|b| b.level == 0)
            .map(|b| b.cells.num_cells().unwrap())
            .sum();
        assert_eq!(level0, 16 * 16 * 16);
        let extents: std::collections::BTreeSet<i64> =
            spec.bricks.iter().flat_map(|b| b.cells.extent()).collect();
        assert!(extents.len() >= 5, "{extents:?}");
        assert!(extents.iter().all(|&e| (1..=8).contains(&e)));
        for level in 1..3u32 {
            let r = i64::from(params.ratios[level as usize - 1]);
            let parents: Vec<IBox> = spec
                .bricks
                .iter()
                .filter(|b| b.level == level - 1)
                .map(|b| b.cells.refine([r; 3]).unwrap())
                .collect();
            let fine: Vec<IBox> = spec
                .bricks
                .iter()
                .filter(|b| b.level == level)
                .map(|b| b.cells)
                .collect();
            assert!(!fine.is_empty());
            for (i, f) in fine.iter().enumerate() {
                assert!(
                    (0..3).all(|a| f.lo[a] % r == 0 && f.hi[a] % r == 0),
                    "{f:?} is not made of whole parent cells"
                );
                assert_eq!(parents.iter().filter(|p| p.intersect(f) == *f).count(), 1);
                assert!(fine[i + 1..].iter().all(|g| g.intersect(f).is_empty()));
            }
        }
    }
}
