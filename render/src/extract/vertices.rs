//! Vertex values of one leaf's boundary octants, in a dense grid over the leaf's level-`L`
//! half-cell lattice: octants sharing a vertex compute it once, with array lookups in cell
//! order instead of hashing. Generation stamps make starting a new leaf free.

use amr_format::IBox;

/// Per-thread scratch: remembered vertex values of the leaf being processed.
#[derive(Default)]
pub struct LeafVertices {
    base: [i64; 3],
    scale: [i64; 3],
    dims: [usize; 3],
    stamp: Vec<u32>,
    value: Vec<Option<f32>>,
    generation: u32,
}

impl LeafVertices {
    /// Starts a leaf whose cells (of level scale `scale`) are `cells`, with lowest doubled
    /// corner `lo`.
    pub fn start(&mut self, cells: &IBox, lo: [i64; 3], scale: [i64; 3]) {
        let e = cells.extent();
        self.base = lo;
        self.scale = scale;
        self.dims = [0, 1, 2].map(|a| 2 * e[a] as usize + 1);
        let n = self.dims.iter().product();
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 || self.stamp.len() < n {
            self.stamp.clear();
            self.stamp.resize(n, 0);
            self.value.resize(n, None);
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

    /// The remembered value at doubled vertex `v`, if any.
    #[inline]
    pub fn get(&self, v: [i64; 3]) -> Option<Option<f32>> {
        let i = self.slot(v)?;
        (self.stamp[i] == self.generation).then(|| self.value[i])
    }

    /// Remembers the value at doubled vertex `v` (ignored outside the leaf's lattice).
    #[inline]
    pub fn put(&mut self, v: [i64; 3], value: Option<f32>) {
        if let Some(i) = self.slot(v) {
            self.stamp[i] = self.generation;
            self.value[i] = value;
        }
    }
}
