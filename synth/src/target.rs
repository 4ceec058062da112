//! Choosing the level-0 resolution (and, if free, the brick size) that gives a requested total
//! number of cells.
//!
//! The hierarchy is metadata only, so candidates are simply built and counted; counting stops as
//! soon as a partial total passes the limit, which keeps a search up to 1e10 cells to seconds.

use amr_format::FormatError;

use crate::fields::AnalyticField;
use crate::params::SynthParams;
use crate::refine::{near_surface, walk_levels};

/// Brick sizes tried, largest first, when the caller leaves the brick size free.
const FREE_BRICKS: [u32; 4] = [32, 16, 8, 4];
/// The most cells a fit may give per cell asked for: when even the smallest level 0 refines to
/// more, the levels asked for are too many for the target.
const MAX_OVERSHOOT: u64 = 1000;
/// A fit within this factor of the target is good enough to stop trying smaller bricks.
const GOOD_ENOUGH: f64 = 1.5;

/// Total cells of the hierarchy of `field` under `params`, or some count above `limit` as soon
/// as the partial total exceeds it.
pub fn count_cells<F>(field: &F, params: &SynthParams, limit: u64) -> Result<u64, FormatError>
where
    F: AnalyticField + Sync,
{
    params.validate()?;
    let iso = field.default_iso();
    let mut total = 0u64;
    walk_levels(params, &|b| near_surface(field, iso, b), |_, boxes| {
        total = boxes.iter().fold(total, |t, b| {
            t.saturating_add(b.num_cells().unwrap_or(u64::MAX))
        });
        total <= limit
    });
    Ok(total)
}

/// `params` with `base` (a multiple of the brick size) chosen so that the total cell count is as
/// close as possible to `target`, by ratio; returns the parameters and their exact total.
///
/// With `free_brick`, brick sizes 32, 16, 8 and 4 are tried in turn until the fit is within a factor
/// 1.5, since a large brick cannot make a small dataset. Levels, ratio and placement are kept.
/// No count goes past `limit` cells nor [`MAX_OVERSHOOT`] times the target (counting stops
/// there): a fit above that, when even the smallest level 0 refines past it, is an error.
pub fn fit_cells<F>(
    field: &F,
    params: &SynthParams,
    target: u64,
    free_brick: bool,
    limit: u64,
) -> Result<(SynthParams, u64), FormatError>
where
    F: AnalyticField + Sync,
{
    if target > limit {
        return Err(FormatError::InvalidHierarchy(format!(
            "{target} cells asked for, more than the {limit} allowed"
        )));
    }
    // Counting a hierarchy far larger than the target costs time for nothing: past this the
    // fit is refused.
    let limit = limit.min(target.max(1).saturating_mul(MAX_OVERSHOOT));
    let bricks: Vec<u32> = if free_brick {
        FREE_BRICKS.to_vec()
    } else {
        vec![params.brick]
    };
    let mut best: Option<(SynthParams, u64)> = None;
    for brick in bricks {
        let fit = fit_base(
            field,
            &SynthParams {
                brick,
                ..params.clone()
            },
            target.max(1),
            limit,
        )?;
        if best
            .as_ref()
            .is_none_or(|b| misfit(fit.1, target) < misfit(b.1, target))
        {
            best = Some(fit);
        }
        if best
            .as_ref()
            .is_some_and(|b| misfit(b.1, target) <= GOOD_ENOUGH.ln())
        {
            break;
        }
    }
    let best = best.expect("at least one brick size is tried");
    if best.1 > limit {
        return Err(FormatError::InvalidHierarchy(format!(
            "{} levels refined by {}: every level 0 tried gives more than {limit} cells; ask \
             for fewer levels or more cells",
            params.levels, params.ratio
        )));
    }
    Ok(best)
}

/// The best multiple of `params.brick` as `base`: doubling the multiple until the total reaches
/// the target, then bisecting. Growing from below keeps every count cheap: a level is only
/// refined while the levels above it hold fewer cells than the target.
fn fit_base<F>(
    field: &F,
    params: &SynthParams,
    target: u64,
    limit: u64,
) -> Result<(SynthParams, u64), FormatError>
where
    F: AnalyticField + Sync,
{
    let with = |k: u64| SynthParams {
        base: (k * u64::from(params.brick)).min(u64::from(u32::MAX)) as u32,
        ..params.clone()
    };
    let total = |k: u64, limit: u64| count_cells(field, &with(k), limit);
    with(1).validate()?;
    let (mut lo, mut hi) = (0, 1);
    while total(hi, target)? < target {
        if with(2 * hi).validate().is_err() {
            return Ok((with(hi), total(hi, limit)?));
        }
        (lo, hi) = (hi, 2 * hi);
    }
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if total(mid, target)? >= target {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let above = total(hi, limit)?;
    if lo == 0 {
        return Ok((with(hi), above));
    }
    let below = total(lo, limit)?;
    Ok(
        if above > limit || misfit(below, target) < misfit(above, target) {
            (with(lo), below)
        } else {
            (with(hi), above)
        },
    )
}

/// How far `total` is from `target`, as the absolute log of their ratio.
fn misfit(total: u64, target: u64) -> f64 {
    (total.max(1) as f64 / target.max(1) as f64).ln().abs()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fields::Case;
    use crate::refine::build_hierarchy;

    /// A target past the limit, and levels too many for the target, are refused at once (no
    /// count runs to the end of a hierarchy of 20 levels).
    #[test]
    fn fits_past_the_limit_are_refused() {
        let p = SynthParams::default();
        assert!(fit_cells(&Case::Blobs, &p, 1_000_000, true, 999_999).is_err());
        let deep = SynthParams {
            levels: 20,
            ..SynthParams::default()
        };
        let err = fit_cells(&Case::Blobs, &deep, 1000, true, u64::MAX).unwrap_err();
        assert!(err.to_string().contains("fewer levels"), "{err}");
        // A fit within both limits is kept.
        let (_, total) = fit_cells(&Case::Blobs, &p, 100_000, true, 10_000_000).unwrap();
        assert!(total <= 10_000_000);
    }

    #[test]
    fn counts_match_the_built_hierarchy() {
        let p = SynthParams {
            base: 24,
            brick: 8,
            ..SynthParams::default()
        };
        for case in Case::ALL {
            let spec = build_hierarchy(&case, case.name(), &p).unwrap();
            assert_eq!(
                count_cells(&case, &p, u64::MAX).unwrap(),
                spec.total_cells()
            );
            assert!(count_cells(&case, &p, 1000).unwrap() > 1000);
        }
    }

    #[test]
    fn fits_targets_from_1e5_to_1e8_within_a_factor_2() {
        for case in Case::ALL {
            for (target, ratios) in [
                (100_000u64, &[2][..]),
                (1_000_000, &[2, 4]),
                (100_000_000, &[2, 4]),
            ] {
                for &ratio in ratios {
                    let p = SynthParams {
                        ratio,
                        ..SynthParams::default()
                    };
                    let (fit, total) = fit_cells(&case, &p, target, true, u64::MAX).unwrap();
                    assert_eq!(fit.base % fit.brick, 0);
                    assert_eq!(count_cells(&case, &fit, u64::MAX).unwrap(), total);
                    let m = misfit(total, target).exp();
                    assert!(
                        m < 2.0,
                        "{case} ratio {ratio} target {target}: {total} cells with {fit:?}"
                    );
                }
            }
        }
    }
}
