//! Point sampling with the four reconstructions: `nearest`, `current` and `finest` (Wald et al.
//! 2017) and `octant` (Wang et al., section 3.2).

use crate::error::Result as RenderResult;

use super::grid::axes;
use super::interp::trilinear;
use super::recent::SampleScratch;
use super::sampler::{LeafCell, Locate, Sampler, VertexMemo};

/// How cell values are reconstructed between cell centres: the one reconstruction type of the
/// renderer, for sampling, extraction and tracing alike.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Reconstruction {
    /// The value of the leaf cell holding the point.
    Nearest,
    /// Trilinear on the dual cell of the leaf cell's level; each corner takes the value of the
    /// leaf cell at its position. Discontinuous at level boundaries.
    Current,
    /// Trilinear on the dual cell of the file's finest level; each corner takes the value of the
    /// leaf cell at its position. Blocky in coarse regions.
    Finest,
    /// Trilinear in the octant of the leaf cell holding the point, with vertex values stitched
    /// across level boundaries: continuous everywhere.
    #[default]
    Octant,
}

impl Reconstruction {
    /// Every reconstruction, coarse to fine in quality.
    pub const ALL: [Reconstruction; 4] = [
        Reconstruction::Nearest,
        Reconstruction::Current,
        Reconstruction::Finest,
        Reconstruction::Octant,
    ];

    /// The name used on command lines, in statistics and in file headers.
    pub fn name(self) -> &'static str {
        match self {
            Reconstruction::Nearest => "nearest",
            Reconstruction::Current => "current",
            Reconstruction::Finest => "finest",
            Reconstruction::Octant => "octant",
        }
    }

    /// True when its active voxels can be extracted and traced exactly (all but `finest`, which
    /// is for point sampling).
    pub fn is_traceable(self) -> bool {
        self != Reconstruction::Finest
    }
}

impl std::fmt::Display for Reconstruction {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Reconstruction {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        Reconstruction::ALL
            .into_iter()
            .find(|r| r.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| {
                format!("unknown reconstruction '{s}' (octant, current, nearest, finest)")
            })
    }
}

impl<'f, D: AsRef<[u8]>> Sampler<'f, D> {
    /// The reconstruction at doubled point `p`; on an exact boundary the point is nudged toward
    /// `+`. `None` outside the domain or where no brick covers the cells involved.
    pub fn sample(&self, p: [f64; 3], method: Reconstruction) -> RenderResult<Option<f32>> {
        let mut memo = VertexMemo::with_octant_bits(0);
        Ok(self.sample_in(self, p, method, &mut memo)?.map(|s| s.0))
    }

    /// [`Self::sample`] and the level of the leaf cell holding `p`, through `scratch`, which
    /// remembers what nearby samples share (the same values, computed faster).
    pub fn sample_with(
        &self,
        p: [f64; 3],
        method: Reconstruction,
        scratch: &mut SampleScratch,
    ) -> RenderResult<Option<(f32, u32)>> {
        let (loc, memo) = scratch.bind(self);
        self.sample_in(&loc, p, method, memo)
    }

    /// [`Self::sample`] and the leaf cell's level, locating through `loc` and remembering
    /// vertex values and octant corners in `memo`.
    #[inline]
    pub fn sample_in<L: Locate>(
        &self,
        loc: &L,
        p: [f64; 3],
        method: Reconstruction,
        memo: &mut VertexMemo,
    ) -> RenderResult<Option<(f32, u32)>> {
        let ext = self.grid().extent();
        if (0..3).any(|a| !(p[a] >= 0.0 && p[a] <= 2.0 * ext[a] as f64)) {
            return Ok(None);
        }
        let finest = axes(|a| ((p[a] * 0.5).floor() as i64).min(ext[a] - 1));
        let Some(c) = loc.locate_cell(finest)? else {
            return Ok(None);
        };
        let value = match method {
            Reconstruction::Nearest => Some(c.value),
            Reconstruction::Octant => self.sample_octant(loc, p, &c, memo)?,
            Reconstruction::Current => self.sample_dual(loc, p, c.level)?,
            Reconstruction::Finest => {
                self.sample_dual(loc, p, self.grid().num_levels() as u32 - 1)?
            }
        };
        Ok(value.map(|v| (v, c.level)))
    }

    /// [`Self::sample`] at a world position.
    pub fn sample_world(&self, x: [f64; 3], method: Reconstruction) -> RenderResult<Option<f32>> {
        self.sample(self.grid().to_doubled(x), method)
    }

    fn sample_octant<L: Locate>(
        &self,
        loc: &L,
        p: [f64; 3],
        c: &LeafCell,
        memo: &mut VertexMemo,
    ) -> RenderResult<Option<f32>> {
        let centre = self.grid().centre(c.level, c.cell);
        let s = self.grid().scale(c.level);
        let mut octant = 0u8;
        for a in 0..3 {
            if p[a] >= centre[a] as f64 {
                octant |= 1 << a;
            }
        }
        let Some(corners) = self.leaf_octant_corners_in(loc, c, octant, memo)? else {
            return Ok(None);
        };
        let t = axes(|a| {
            let lo = if octant >> a & 1 == 1 {
                centre[a]
            } else {
                centre[a] - s[a]
            };
            ((p[a] - lo as f64) / s[a] as f64).clamp(0.0, 1.0) as f32
        });
        Ok(Some(trilinear(&corners, t)))
    }

    fn sample_dual<L: Locate>(
        &self,
        loc: &L,
        p: [f64; 3],
        level: u32,
    ) -> RenderResult<Option<f32>> {
        let s = self.grid().scale(level);
        let o = self.grid().offset();
        let first = [0, 1, 2]
            .map(|a| (((p[a] - s[a] as f64) * 0.5 + o[a] as f64) / s[a] as f64).floor() as i64);
        let base = self.grid().centre(level, first);
        let finest_of = |n: usize| {
            let cell = axes(|a| first[a] + (n >> a & 1) as i64);
            self.grid().finest_cell(self.grid().centre(level, cell), 7)
        };
        let corners = match loc.block_of_level(finest_of(0), finest_of(7), level) {
            Some(block) => block,
            None => {
                let mut corners = [0f32; 8];
                for (n, slot) in corners.iter_mut().enumerate() {
                    match loc.locate_cell(finest_of(n))? {
                        Some(c) => *slot = c.value,
                        None => return Ok(None),
                    }
                }
                corners
            }
        };
        let t = axes(|a| ((p[a] - base[a] as f64) / (2 * s[a]) as f64).clamp(0.0, 1.0) as f32);
        Ok(Some(trilinear(&corners, t)))
    }
}
