//! The parameters of a synthetic dataset and the level geometry they imply.

use amr_format::hierarchy::{MAX_BRICK_EXTENT, MAX_FINEST_EXTENT, MAX_LEVELS};
use amr_format::{FormatError, IBox, LevelSpec};

/// How a synthetic dataset is laid out: levels, resolution, bricks and physical placement.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthParams {
    /// Number of refinement levels requested (at least 1); levels left without bricks are dropped.
    pub levels: u32,
    /// Refinement ratio between consecutive levels, the same on every axis (at least 2).
    pub ratio: u32,
    /// Cells per axis of level 0, which covers the whole domain.
    pub base: u32,
    /// Cells per axis of a brick; bricks at the upper domain faces may be smaller.
    pub brick: u32,
    /// Physical position of the domain's lower corner.
    pub origin: [f64; 3],
    /// Physical edge length of the cubic domain.
    pub size: f64,
}

impl Default for SynthParams {
    fn default() -> Self {
        Self {
            levels: 3,
            ratio: 2,
            base: 64,
            brick: 32,
            origin: [0.0; 3],
            size: 1.0,
        }
    }
}

impl SynthParams {
    /// A unit cube at the origin with `levels` levels of refinement `ratio`, `base` cells per
    /// axis on level 0 and bricks of `brick` cells.
    pub fn unit_cube(levels: u32, ratio: u32, base: u32, brick: u32) -> Self {
        SynthParams {
            levels,
            ratio,
            base,
            brick,
            origin: [0.0; 3],
            size: 1.0,
        }
    }

    /// Cells per axis of level `level`, or `None` if it overflows.
    pub fn cells_per_axis(&self, level: u32) -> Option<i64> {
        let r = i64::from(self.ratio);
        (0..level).try_fold(i64::from(self.base), |n, _| n.checked_mul(r))
    }

    /// Checks every parameter, naming the one at fault.
    pub fn validate(&self) -> Result<(), FormatError> {
        let bad = |m: String| Err(FormatError::InvalidHierarchy(m));
        if self.levels == 0 || self.levels as usize > MAX_LEVELS {
            return bad(format!(
                "--levels {} (must be 1 to {MAX_LEVELS})",
                self.levels
            ));
        }
        if self.ratio < 2 {
            return bad(format!("--ratio {} (must be at least 2)", self.ratio));
        }
        if self.base == 0 {
            return bad("--base 0 (must be at least 1)".into());
        }
        if self.brick == 0 || i64::from(self.brick) > MAX_BRICK_EXTENT {
            return bad(format!(
                "--brick {} (must be 1 to {MAX_BRICK_EXTENT})",
                self.brick
            ));
        }
        if !(self.size.is_finite() && self.size > 0.0) {
            return bad(format!(
                "--size {} (must be positive and finite)",
                self.size
            ));
        }
        if self.origin.iter().any(|o| !o.is_finite()) {
            return bad(format!("--origin {:?} (must be finite)", self.origin));
        }
        match self.cells_per_axis(self.levels - 1) {
            Some(n) if n <= MAX_FINEST_EXTENT => Ok(()),
            _ => bad(format!(
                "--base {} refined {} times by {} exceeds {MAX_FINEST_EXTENT} finest cells per axis",
                self.base,
                self.levels - 1,
                self.ratio
            )),
        }
    }

    /// The geometry of every requested level, coarsest first; the finest has ratio `[1, 1, 1]`.
    pub fn level_specs(&self) -> Result<Vec<LevelSpec>, FormatError> {
        self.validate()?;
        Ok((0..self.levels)
            .map(|l| {
                let n = self.cells_per_axis(l).expect("validated");
                let ratio = if l + 1 < self.levels { self.ratio } else { 1 };
                LevelSpec {
                    cell_size: [self.size / n as f64; 3],
                    origin: self.origin,
                    ratio_to_next: [ratio; 3],
                    domain: IBox::new([0; 3], [n; 3]),
                }
            })
            .collect())
    }
}
