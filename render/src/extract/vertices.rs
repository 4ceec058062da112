//! Vertex values of one leaf's boundary octants, in a dense grid over the leaf's level-`L`
//! half-cell lattice: octants sharing a vertex compute it once, with array lookups in cell
//! order instead of hashing. Generation stamps make starting a new leaf free.
//!
//! Vertices on a leaf's faces are also vertices of the leaves beside it, which are mostly
//! extracted soon after (leaves go in kd-tree order). The values the sampler computes (the
//! costly ones, next to other levels) are also kept across leaves, in a small direct-mapped
//! table keyed by position and level: a vertex value is a function of those two alone.

use amr_format::IBox;

/// Flag of a slot stamp whose value is `None`.
const NONE: u32 = 1 << 31;

/// Per-thread scratch: remembered vertex values of the leaf being processed.
#[derive(Default)]
pub struct LeafVertices {
    base: [i64; 3],
    scale: [i64; 3],
    dims: [usize; 3],
    /// Per slot: the generation that wrote it (with [`NONE`] set when the value is `None`) and
    /// the value's bits, side by side so one lookup touches one cache line.
    slots: Vec<(u32, f32)>,
    generation: u32,
    /// Values computed by the sampler for any leaf, direct-mapped (allocated on first use).
    shared: Vec<Shared>,
}

/// A slot of [`LeafVertices`]' table of values kept across leaves.
#[derive(Clone, Copy)]
struct Shared {
    /// The vertex (doubled coordinates).
    v: [i64; 3],
    /// The asking level; `u32::MAX` for an empty slot.
    level: u32,
    /// The value, `None` where a cell touching the vertex is not covered.
    value: Option<f32>,
}

/// log2 of the slots of the table of values kept across leaves (40 bytes each).
const SHARED_BITS: u32 = 12;

impl LeafVertices {
    /// Starts a leaf whose cells (of level scale `scale`) are `cells`, with lowest doubled
    /// corner `lo`.
    pub fn start(&mut self, cells: &IBox, lo: [i64; 3], scale: [i64; 3]) {
        let e = cells.extent();
        self.base = lo;
        self.scale = scale;
        self.dims = [0, 1, 2].map(|a| 2 * e[a] as usize + 1);
        let n = self.dims.iter().product();
        self.generation += 1;
        if self.generation >= NONE || self.slots.len() < n {
            self.slots.clear();
            self.slots.resize(n, (0, 0.0));
            self.generation = 1;
        }
    }

    fn slot(&self, v: [i64; 3]) -> Option<usize> {
        let mut i = 0usize;
        for a in (0..3).rev() {
            let d = v[a] - self.base[a];
            if d < 0 || d % self.scale[a] != 0 {
                return None;
            }
            let k = (d / self.scale[a]) as usize;
            if k >= self.dims[a] {
                return None;
            }
            i = i * self.dims[a] + k;
        }
        Some(i)
    }

    /// The slot of the vertex at half-cell lattice position `k` (`0..=2 * extent` per axis,
    /// counted from the lowest cell's lower face).
    #[inline]
    pub fn slot_at(&self, k: [usize; 3]) -> usize {
        debug_assert!((0..3).all(|a| k[a] < self.dims[a]));
        k[0] + self.dims[0] * (k[1] + self.dims[1] * k[2])
    }

    /// The remembered value in slot `i`, if any.
    #[inline]
    pub fn get_slot(&self, i: usize) -> Option<Option<f32>> {
        let (stamp, value) = self.slots[i];
        if stamp == self.generation {
            Some(Some(value))
        } else if stamp == self.generation | NONE {
            Some(None)
        } else {
            None
        }
    }

    /// Remembers the value in slot `i`.
    #[inline]
    pub fn put_slot(&mut self, i: usize, value: Option<f32>) {
        self.slots[i] = match value {
            Some(x) => (self.generation, x),
            None => (self.generation | NONE, 0.0),
        };
    }

    /// The slot of vertex `v` asked by level `level` in the table kept across leaves.
    #[inline]
    fn shared_slot(v: [i64; 3], level: u32) -> usize {
        let h = (v[0] as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (v[1] as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
            ^ (v[2] as u64).wrapping_mul(0x1656_67B1_9E37_79F9)
            ^ u64::from(level).wrapping_mul(0x27D4_EB2F_1656_67C5);
        (h >> (64 - SHARED_BITS)) as usize
    }

    /// The value at doubled vertex `v` as seen by level `level`, kept from any leaf
    /// ([`Self::keep`]), if any.
    #[inline]
    pub fn kept(&self, v: [i64; 3], level: u32) -> Option<Option<f32>> {
        let e = self.shared.get(Self::shared_slot(v, level))?;
        (e.level == level && e.v == v).then_some(e.value)
    }

    /// Keeps the value at doubled vertex `v` as seen by level `level` for any later leaf.
    #[inline]
    pub fn keep(&mut self, v: [i64; 3], level: u32, value: Option<f32>) {
        if self.shared.is_empty() {
            let empty = Shared {
                v: [0; 3],
                level: u32::MAX,
                value: None,
            };
            self.shared.resize(1 << SHARED_BITS, empty);
        }
        self.shared[Self::shared_slot(v, level)] = Shared { v, level, value };
    }

    /// The remembered value at doubled vertex `v`, if any.
    #[inline]
    pub fn get(&self, v: [i64; 3]) -> Option<Option<f32>> {
        self.get_slot(self.slot(v)?)
    }

    /// Remembers the value at doubled vertex `v` (ignored outside the leaf's lattice).
    #[inline]
    pub fn put(&mut self, v: [i64; 3], value: Option<f32>) {
        if let Some(i) = self.slot(v) {
            self.put_slot(i, value);
        }
    }
}
