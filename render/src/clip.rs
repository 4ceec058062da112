//! A clip box: the world box a scene's isosurfaces are cut to, for cut-away views. Only the
//! voxels that meet it are extracted, and a ray accepts a surface hit only inside it, so the
//! surfaces behind the cut show through the opening (see [`crate::trace::clipped`]).

use std::str::FromStr;

use crate::error::{RenderError, Result};
use crate::trace::GridFrame;

/// A closed axis-aligned box in world coordinates (those of the camera), `lo < hi` on each axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClipBox {
    /// Lower corner.
    pub lo: [f64; 3],
    /// Upper corner.
    pub hi: [f64; 3],
}

impl ClipBox {
    /// The box `[lo, hi]`: every coordinate finite and `lo < hi` on each axis.
    pub fn new(lo: [f64; 3], hi: [f64; 3]) -> Result<ClipBox> {
        if lo.iter().chain(&hi).any(|v| !v.is_finite()) {
            return Err(RenderError::Invalid(format!(
                "clip box {lo:?}..{hi:?}: every coordinate must be a finite number"
            )));
        }
        if let Some(a) = (0..3).find(|&a| lo[a] >= hi[a]) {
            return Err(RenderError::Invalid(format!(
                "clip box {lo:?}..{hi:?}: on the {} axis the lower bound {} is not below the upper bound {}",
                ["x", "y", "z"][a],
                lo[a],
                hi[a]
            )));
        }
        Ok(ClipBox { lo, hi })
    }

    /// The box in grid coordinates of `frame`.
    pub fn to_grid(&self, frame: &GridFrame) -> ([f64; 3], [f64; 3]) {
        let (a, b) = (frame.to_grid(self.lo), frame.to_grid(self.hi));
        (
            [0, 1, 2].map(|k| a[k].min(b[k])),
            [0, 1, 2].map(|k| a[k].max(b[k])),
        )
    }

    /// Fails unless the box and the domain of `frame` share some volume.
    pub fn check_overlaps(&self, frame: &GridFrame) -> Result<()> {
        let (lo, hi) = frame.world_bounds();
        if (0..3).all(|a| self.lo[a] < hi[a] && self.hi[a] > lo[a]) {
            return Ok(());
        }
        Err(RenderError::Invalid(format!(
            "clip box {:?}..{:?} does not overlap the domain {lo:?}..{hi:?}: it would keep nothing",
            self.lo, self.hi
        )))
    }
}

impl FromStr for ClipBox {
    type Err = String;

    /// Parses `X0,Y0,Z0,X1,Y1,Z1`.
    fn from_str(s: &str) -> std::result::Result<ClipBox, String> {
        let parts: Vec<&str> = s.split(',').collect();
        if parts.len() != 6 {
            return Err(format!(
                "clip box '{s}' has {} numbers; give six, X0,Y0,Z0,X1,Y1,Z1",
                parts.len()
            ));
        }
        let mut v = [0.0f64; 6];
        for (o, p) in v.iter_mut().zip(&parts) {
            *o = p
                .trim()
                .parse::<f64>()
                .map_err(|_| format!("'{p}' in clip box '{s}' is not a number"))?;
        }
        ClipBox::new([v[0], v[1], v[2]], [v[3], v[4], v[5]]).map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_six_numbers_and_refuses_the_rest() {
        let c: ClipBox = "0, 0,0,0.5,1,1".parse().unwrap();
        assert_eq!(c.hi, [0.5, 1.0, 1.0]);
        for bad in ["0,0,0,1,1", "0,0,0,1,1,1,1", "0,0,0,1,x,1", "0,0,0,1,nan,1"] {
            assert!(bad.parse::<ClipBox>().is_err(), "{bad}");
        }
        let e = "0,0.6,0,1,0.5,1".parse::<ClipBox>().unwrap_err();
        assert!(e.contains("y axis"), "{e}");
        let frame = GridFrame {
            origin: [0.0; 3],
            unit: [0.5; 3],
            extent: [2.0; 3],
        };
        assert!(c.check_overlaps(&frame).is_ok());
        let away = ClipBox::new([2.0; 3], [3.0; 3]).unwrap();
        assert!(away.check_overlaps(&frame).is_err());
        assert_eq!(c.to_grid(&frame), ([0.0; 3], [1.0, 2.0, 2.0]));
    }
}
