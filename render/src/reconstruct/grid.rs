//! Doubled finest-level coordinates: the integer space every location is computed in.
//!
//! A point's doubled coordinate on an axis is twice its position in finest-level cells,
//! relative to the finest domain's lower corner. Every cell face, cell centre and octant vertex
//! of every level is then an integer, whatever the refinement ratios, so locating a point on a
//! boundary is an exact integer rule: a point nudged toward `+` on an axis lies in the cell whose
//! half-open box contains it from the `+` side. World coordinates enter only in
//! [`Grid::to_doubled`] and [`Grid::to_world`].

use amr_format::{AmrkFile, IBox};

/// `[f(0), f(1), f(2)]`: a value per axis, built without a call per element.
#[inline(always)]
pub fn axes<T>(mut f: impl FnMut(usize) -> T) -> [T; 3] {
    [f(0), f(1), f(2)]
}

/// The index of cell `cell` in the x-fastest values of a brick of cells `cells` (which holds
/// `cell`): [`IBox::linear_index`], inlined.
#[inline(always)]
pub fn index_in(cells: &IBox, cell: [i64; 3]) -> usize {
    let (ex, ey) = (cells.hi[0] - cells.lo[0], cells.hi[1] - cells.lo[1]);
    let d = axes(|a| cell[a] - cells.lo[a]);
    (d[0] + ex * (d[1] + ey * d[2])) as usize
}

/// The geometry of a file's levels in doubled finest-level coordinates.
#[derive(Clone, Debug)]
pub struct Grid {
    /// Per level: the width of one cell in finest-level cells.
    scale: Vec<[i64; 3]>,
    /// Per level: log2 of `scale` when every axis is a power of two.
    shift: Vec<Option<[u32; 3]>>,
    /// Per level: the index domain.
    domains: Vec<IBox>,
    /// The finest domain's lower corner in absolute finest-level indices.
    offset: [i64; 3],
    /// The finest domain's extent in finest-level cells.
    extent: [i64; 3],
    world_origin: [f64; 3],
    world_cell: [f64; 3],
}

impl Grid {
    /// The geometry of `file`.
    pub fn new<D: AsRef<[u8]>>(file: &AmrkFile<D>) -> Self {
        let levels = file.levels();
        let finest = levels.last().expect("an open file has at least one level");
        let domain = file.finest_domain();
        Self {
            scale: levels.iter().map(|l| l.finest_scale).collect(),
            shift: levels.iter().map(|l| pow2_shift(l.finest_scale)).collect(),
            domains: levels.iter().map(|l| l.domain).collect(),
            offset: domain.lo,
            extent: domain.extent(),
            world_origin: finest.origin,
            world_cell: finest.cell_size,
        }
    }

    /// Number of levels.
    pub fn num_levels(&self) -> usize {
        self.scale.len()
    }

    /// Width of one cell of `level` in finest-level cells.
    #[inline(always)]
    pub fn scale(&self, level: u32) -> [i64; 3] {
        self.scale[level as usize]
    }

    /// The index domain of `level`.
    pub fn domain(&self, level: u32) -> IBox {
        self.domains[level as usize]
    }

    /// The finest domain's extent in finest-level cells.
    #[inline]
    pub fn extent(&self) -> [i64; 3] {
        self.extent
    }

    /// The finest domain's lower corner in absolute finest-level indices.
    #[inline]
    pub fn offset(&self) -> [i64; 3] {
        self.offset
    }

    /// The doubled coordinate of the centre of cell `cell` (absolute index) of `level`.
    #[inline(always)]
    pub fn centre(&self, level: u32, cell: [i64; 3]) -> [i64; 3] {
        let s = self.scale(level);
        axes(|a| 2 * (cell[a] * s[a] - self.offset[a]) + s[a])
    }

    /// log2 of the width of one cell of `level` in finest-level cells, when every axis is a
    /// power of two.
    #[inline(always)]
    pub fn shift(&self, level: u32) -> Option<[u32; 3]> {
        self.shift[level as usize]
    }

    /// The cell of `level` (absolute index) holding finest-level cell `finest` (relative).
    #[inline(always)]
    pub fn cell_of(&self, level: u32, finest: [i64; 3]) -> [i64; 3] {
        let abs = axes(|a| finest[a] + self.offset[a]);
        match self.shift[level as usize] {
            Some(sh) => axes(|a| abs[a] >> sh[a]),
            None => {
                let s = self.scale(level);
                axes(|a| abs[a].div_euclid(s[a]))
            }
        }
    }

    /// The finest-level cells (relative) of cell `cell` of `level`.
    #[inline]
    pub fn finest_box(&self, level: u32, cell: [i64; 3]) -> IBox {
        let s = self.scale(level);
        IBox::new(
            axes(|a| cell[a] * s[a] - self.offset[a]),
            axes(|a| (cell[a] + 1) * s[a] - self.offset[a]),
        )
    }

    /// The finest-level cells (relative) of the cells `cells` (absolute) of `level`.
    #[inline]
    pub fn level_finest_box(&self, level: u32, cells: &IBox) -> IBox {
        let s = self.scale(level);
        IBox::new(
            axes(|a| cells.lo[a] * s[a] - self.offset[a]),
            axes(|a| cells.hi[a] * s[a] - self.offset[a]),
        )
    }

    /// The cells of `level` (absolute) overlapping the finest-level box `finest` (relative).
    #[inline]
    pub fn level_box(&self, level: u32, finest: &IBox) -> IBox {
        let s = self.scale(level);
        let mut out = IBox::default();
        for a in 0..3 {
            out.lo[a] = (finest.lo[a] + self.offset[a]).div_euclid(s[a]);
            out.hi[a] = (finest.hi[a] + self.offset[a] + s[a] - 1).div_euclid(s[a]);
        }
        out
    }

    /// The finest-level cell (relative) holding doubled point `p` nudged toward `dir`
    /// (bit `a` set: toward `+` on axis `a`), clamped into the domain.
    #[inline(always)]
    pub fn finest_cell(&self, p: [i64; 3], dir: u8) -> [i64; 3] {
        axes(|a| {
            let f = if dir >> a & 1 == 1 {
                p[a].div_euclid(2)
            } else {
                (p[a] - 1).div_euclid(2)
            };
            f.clamp(0, self.extent[a] - 1)
        })
    }

    /// True when the doubled point `p` lies in the closed domain.
    pub fn contains_point(&self, p: [i64; 3]) -> bool {
        (0..3).all(|a| 0 <= p[a] && p[a] <= 2 * self.extent[a])
    }

    /// World position of a doubled point.
    pub fn to_world(&self, p: [f64; 3]) -> [f64; 3] {
        axes(|a| self.world_origin[a] + self.world_cell[a] * (0.5 * p[a] + self.offset[a] as f64))
    }

    /// Doubled coordinates of a world position.
    pub fn to_doubled(&self, x: [f64; 3]) -> [f64; 3] {
        axes(|a| 2.0 * ((x[a] - self.world_origin[a]) / self.world_cell[a] - self.offset[a] as f64))
    }
}

/// log2 of a cell width per axis, when every axis is a power of two.
pub(super) fn pow2_shift(scale: [i64; 3]) -> Option<[u32; 3]> {
    scale
        .iter()
        .all(|s| *s > 0 && (*s as u64).is_power_of_two())
        .then(|| scale.map(|s| s.trailing_zeros()))
}
