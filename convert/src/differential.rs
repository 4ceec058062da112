//! Derived fields from the differences between a cell and its neighbours: a gradient's length,
//! a vorticity's length, a divergence and the Q-criterion, from the gradients of stored fields
//! at every cell.
//!
//! A cell's gradient is the least-squares fit of a linear function through its value and the
//! values of the leaf cells (the finest cells the file holds) at the centres of its six face
//! neighbours, each at the leaf cell's own centre. Where the neighbours are the cell's own
//! level's, it is the central difference; across a level boundary, where a neighbour is a finer
//! or a coarser cell, and at the domain's faces, where a neighbour is missing, it is still exact
//! for a linear field: no crack or step is made at a level boundary by the differencing itself.

use std::fmt;

use amr_render::mapping::{MappedFile, WatchedMap};
use amr_render::reconstruct::sampler::Sampler;
use amr_render::RenderError;

/// Decoded bricks of compressed files each differential field keeps, in bytes.
const CACHE_BYTES: usize = 16 << 20;

/// What is computed from the fields' gradients.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Operator {
    /// `grad(f)`: the length of the gradient of one field.
    Gradient,
    /// `curl(u,v,w)`: the length of the curl (the vorticity's magnitude) of a vector field.
    Curl,
    /// `div(u,v,w)`: the divergence of a vector field (a flow's dilatation).
    Divergence,
    /// `qcriterion(u,v,w)`: `(|Ω|² - |S|²) / 2` of the velocity gradient's antisymmetric (`Ω`)
    /// and symmetric (`S`) parts: positive where rotation dominates strain (vortex cores).
    QCriterion,
}

impl Operator {
    /// The operator written `name`, if any.
    pub fn named(name: &str) -> Option<Operator> {
        match name {
            "grad" => Some(Operator::Gradient),
            "curl" => Some(Operator::Curl),
            "div" => Some(Operator::Divergence),
            "qcriterion" => Some(Operator::QCriterion),
            _ => None,
        }
    }

    /// How many fields it takes.
    pub fn arity(self) -> usize {
        match self {
            Operator::Gradient => 1,
            Operator::Curl | Operator::Divergence | Operator::QCriterion => 3,
        }
    }

    /// Its value from the gradients `g[k]` of its fields.
    #[inline]
    pub fn apply(self, g: &[[f64; 3]]) -> f64 {
        match self {
            Operator::Gradient => length(g[0]),
            Operator::Curl => length([g[2][1] - g[1][2], g[0][2] - g[2][0], g[1][0] - g[0][1]]),
            Operator::Divergence => g[0][0] + g[1][1] + g[2][2],
            Operator::QCriterion => {
                let (mut rotation, mut strain) = (0.0, 0.0);
                for i in 0..3 {
                    for j in 0..3 {
                        let (s, o) = (0.5 * (g[i][j] + g[j][i]), 0.5 * (g[i][j] - g[j][i]));
                        strain += s * s;
                        rotation += o * o;
                    }
                }
                0.5 * (rotation - strain)
            }
        }
    }
}

impl fmt::Display for Operator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Operator::Gradient => "grad",
            Operator::Curl => "curl",
            Operator::Divergence => "div",
            Operator::QCriterion => "qcriterion",
        })
    }
}

fn length(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// The gradients of some fields of a file at every cell of a brick.
pub struct Gradients<'f> {
    file: &'f MappedFile,
    /// One sampler per field: the first locates leaf cells, each reads its field's values.
    samplers: Vec<Sampler<'f, WatchedMap>>,
    /// The finest domain's lower corner, in finest cells.
    finest_lo: [i64; 3],
}

impl<'f> Gradients<'f> {
    /// Ready to differentiate the fields `fields` (one or more) of `file`.
    pub fn new(file: &'f MappedFile, fields: &[usize]) -> Result<Self, RenderError> {
        let samplers = fields
            .iter()
            .map(|&f| Sampler::new(file, f, CACHE_BYTES))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Gradients {
            file,
            samplers,
            finest_lo: file.finest_domain().lo,
        })
    }

    /// `op` of the fields at every cell of brick `brick` (x fastest), whose own values of the
    /// fields are `own[k]`.
    pub fn brick(
        &self,
        brick: usize,
        op: Operator,
        own: &[&[f32]],
    ) -> Result<Vec<f64>, RenderError> {
        let info = self.file.brick(brick);
        let cells = info.cells;
        let level = &self.file.levels()[info.level as usize];
        let [nx, ny, nz] = cells.extent();
        let mut out = Vec::with_capacity(own.first().map_or(0, |v| v.len()));
        // At most three fields (an operator's arity).
        let fields = own.len().min(3);
        let mut gradients = [[0.0f64; 3]; 3];
        let gradients = &mut gradients[..fields];
        let mut neighbour_values = [0.0f64; 3];
        let neighbour_values = &mut neighbour_values[..fields];
        let mut rhs = [[0.0f64; 3]; 3];
        let rhs = &mut rhs[..fields];
        // A cell of the brick that no finer brick covers is a leaf cell: where a cell's
        // neighbours inside the brick are such cells, they are read from the brick, and where
        // all six are, the least-squares fit is the central difference.
        let covered = self.covered(brick, info.level);
        let leaf = |j: usize| covered.as_ref().is_none_or(|c| !c[j]);
        let h = level.cell_size;
        let stride = [1, nx as usize, (nx * ny) as usize];
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let i = (x + nx * (y + ny * z)) as usize;
                    let inside = x > 0 && y > 0 && z > 0 && x + 1 < nx && y + 1 < ny && z + 1 < nz;
                    if inside && (0..3).all(|a| leaf(i + stride[a]) && leaf(i - stride[a])) {
                        for (g, values) in gradients.iter_mut().zip(own) {
                            *g = [0, 1, 2].map(|a| {
                                let (up, down) = (values[i + stride[a]], values[i - stride[a]]);
                                (f64::from(up) - f64::from(down)) / (2.0 * h[a])
                            });
                        }
                        out.push(op.apply(gradients));
                        continue;
                    }
                    let cell = [cells.lo[0] + x, cells.lo[1] + y, cells.lo[2] + z];
                    let centre = self.centre(info.level, cell);
                    let mut normal = [[0.0f64; 3]; 3];
                    rhs.fill([0.0; 3]);
                    for axis in 0..3 {
                        for side in [-1, 1] {
                            let mut at = cell;
                            at[axis] += side;
                            let j = (i as i64 + side * stride[axis] as i64) as usize;
                            let position = if cells.contains_cell(at) && leaf(j) {
                                for (v, values) in neighbour_values.iter_mut().zip(own) {
                                    *v = f64::from(values[j]);
                                }
                                self.centre(info.level, at)
                            } else {
                                match self.neighbour(level.finest_scale, at, neighbour_values)? {
                                    Some(position) => position,
                                    None => continue,
                                }
                            };
                            let d = [0, 1, 2].map(|a| position[a] - centre[a]);
                            for r in 0..3 {
                                for c in 0..3 {
                                    normal[r][c] += d[r] * d[c];
                                }
                            }
                            for (k, v) in neighbour_values.iter().enumerate() {
                                let dv = v - f64::from(own[k][i]);
                                for r in 0..3 {
                                    rhs[k][r] += d[r] * dv;
                                }
                            }
                        }
                    }
                    for (g, b) in gradients.iter_mut().zip(rhs.iter()) {
                        *g = solve(normal, *b);
                    }
                    out.push(op.apply(gradients));
                }
            }
        }
        Ok(out)
    }

    /// Per cell of brick `brick` (of level `level`), x fastest: whether a finer brick covers
    /// any of it (some kd-tree leaf over it has a finer brick as its finest); `None` when none
    /// does, the common case.
    fn covered(&self, brick: usize, level: u32) -> Option<Vec<bool>> {
        let sampler = &self.samplers[0];
        let cells = self.file.brick(brick).cells;
        let region = sampler.grid().level_finest_box(level, &cells);
        let scale = sampler.grid().scale(level);
        let [nx, ny, nz] = cells.extent();
        let mut covered: Option<Vec<bool>> = None;
        sampler.for_each_leaf_touching(&region, |leaf| {
            if sampler.leaf_top(leaf).is_none_or(|(_, top)| top <= level) {
                return;
            }
            // The leaf's box in the brick's cells (relative), every cell it overlaps.
            let b = sampler.leaf_box(leaf);
            let lo = [0, 1, 2].map(|a| (b.lo[a] - region.lo[a]).div_euclid(scale[a]).max(0));
            let hi = [0, 1, 2].map(|a| {
                let n = [nx, ny, nz][a];
                (b.hi[a] - region.lo[a] + scale[a] - 1)
                    .div_euclid(scale[a])
                    .min(n)
            });
            let mask = covered.get_or_insert_with(|| vec![false; (nx * ny * nz) as usize]);
            for z in lo[2]..hi[2] {
                for y in lo[1]..hi[1] {
                    for x in lo[0]..hi[0] {
                        mask[(x + nx * (y + ny * z)) as usize] = true;
                    }
                }
            }
        });
        covered
    }

    /// The centre of cell `cell` of level `level`, in physical units.
    fn centre(&self, level: u32, cell: [i64; 3]) -> [f64; 3] {
        let l = &self.file.levels()[level as usize];
        [0, 1, 2].map(|a| l.origin[a] + (cell[a] as f64 + 0.5) * l.cell_size[a])
    }

    /// The leaf cell at the centre of cell `at` of a level `scale` finest cells wide: its
    /// values of the fields into `values`, and its centre; `None` outside the domain or where
    /// no brick holds it.
    fn neighbour(
        &self,
        scale: [i64; 3],
        at: [i64; 3],
        values: &mut [f64],
    ) -> Result<Option<[f64; 3]>, RenderError> {
        let finest = [0, 1, 2].map(|a| at[a] * scale[a] + scale[a] / 2 - self.finest_lo[a]);
        let Some(leaf) = self.samplers[0].locate(finest)? else {
            return Ok(None);
        };
        let b = self.samplers[0].brick_cells(leaf.brick);
        let [nx, ny, _] = b.extent();
        let o = [0, 1, 2].map(|a| leaf.cell[a] - b.lo[a]);
        let index = usize::try_from(o[0] + nx * (o[1] + ny * o[2])).ok();
        for (v, sampler) in values.iter_mut().zip(&self.samplers) {
            let slab = sampler.values(leaf.brick)?;
            let value = index.and_then(|i| slab.get(i)).ok_or_else(|| {
                RenderError::Invalid(format!(
                    "cell {:?} of level {} is not in its brick {}",
                    leaf.cell, leaf.level, leaf.brick
                ))
            })?;
            *v = f64::from(*value);
        }
        Ok(Some(self.centre(leaf.level, leaf.cell)))
    }
}

/// The solution `g` of `normal g = rhs`, the normal equations of a least-squares gradient; an
/// axis no neighbour spans (a domain one cell thick) gets no slope.
fn solve(mut normal: [[f64; 3]; 3], rhs: [f64; 3]) -> [f64; 3] {
    let scale = (0..3).map(|a| normal[a][a]).fold(0.0, f64::max);
    for a in 0..3 {
        if normal[a][a] <= scale * 1e-12 {
            normal[a][a] = scale.max(1.0);
        }
    }
    let m = normal;
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(&m);
    if d == 0.0 || !d.is_finite() {
        return [0.0; 3];
    }
    // Cramer's rule: the matrix is 3x3, symmetric and well conditioned (face neighbours).
    [0, 1, 2].map(|c| {
        let mut mc = m;
        for r in 0..3 {
            mc[r][c] = rhs[r];
        }
        det(&mc) / d
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_operators_of_a_linear_velocity() {
        // u = -2y + z, v = 2x, w = 3x - y: rows are the components' gradients.
        let g = [[0.0, -2.0, 1.0], [2.0, 0.0, 0.0], [3.0, -1.0, 0.0]];
        assert_eq!(Operator::Curl.apply(&g), 21f64.sqrt());
        assert_eq!(Operator::QCriterion.apply(&g), 1.0);
        assert_eq!(Operator::Gradient.apply(&g[2..]), 10f64.sqrt());
        assert_eq!(Operator::Divergence.apply(&g), 0.0);
        let expanding = [[1.0, 5.0, 0.0], [0.0, 2.0, -1.0], [0.0, 0.0, 0.5]];
        assert_eq!(Operator::Divergence.apply(&expanding), 3.5);
        // Pure strain has a negative Q, pure rotation a positive one.
        let strain = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 0.0]];
        assert!(Operator::QCriterion.apply(&strain) < 0.0);
    }

    #[test]
    fn the_least_squares_gradient_is_exact_for_a_plane_through_uneven_neighbours() {
        let slope = [0.5, -3.0, 2.0];
        // A cell's neighbours: a finer one offset across, a coarser one farther, one missing.
        let d = [
            [1.0, 0.25, -0.25],
            [-1.5, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.25, -0.75, 0.25],
            [0.0, 0.0, 1.0],
        ];
        let (mut normal, mut rhs) = ([[0.0; 3]; 3], [0.0; 3]);
        for v in d {
            let dv: f64 = (0..3).map(|a| slope[a] * v[a]).sum();
            for r in 0..3 {
                rhs[r] += v[r] * dv;
                for c in 0..3 {
                    normal[r][c] += v[r] * v[c];
                }
            }
        }
        let g = solve(normal, rhs);
        for a in 0..3 {
            assert!((g[a] - slope[a]).abs() < 1e-12, "{g:?}");
        }
        // No neighbour along z: no slope there, the others still found.
        let g = solve(
            [[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 0.0]],
            [1.0, -4.0, 0.0],
        );
        assert_eq!(g, [0.5, -2.0, 0.0]);
    }
}
