//! Boxes of a run of refs naming cells of one lattice, written four at a time (AVX2).
//!
//! A leaf's merged dual cells lie on a lattice: the cell of local index `i` (x fastest) sits at
//! `lowest + step * d`, `d` the index's three coordinates, and is `size` wide. The build's
//! [`BoxRun::push_ints`] decodes such boxes one ref at a time (two integer divisions, six
//! conversions, a Morton code); here four refs share each instruction: the coordinates by
//! exact `f64` divisions, the corners, the union, the padded `f32` boxes and the grid steps of the
//! centres in vector lanes, and the Morton codes by bit deposit. The boxes, codes and union are
//! those [`BoxRun::push_ints`] gives for the same corners.

use super::BoxRun;

/// Cells of a lattice named by the low 32 bits of refs: ref `r` names the cell of local index
/// `(r as u32).wrapping_sub(first_id)` when that is below `cells`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CellLattice {
    /// The id of the cell of local index 0.
    pub first_id: u32,
    /// Cells along x and along y.
    pub extent: [u32; 2],
    /// Cells in the lattice (any index below it names a cell).
    pub cells: u32,
    /// The lower corner of the cell of index 0.
    pub lowest: [i64; 3],
    /// From one cell's lower corner to the next cell's, per axis.
    pub step: [i64; 3],
    /// A cell's width per axis.
    pub size: [i64; 3],
}

/// Coordinates at or past this are not taken four at a time (their `f64` arithmetic stays far
/// from rounding).
const EXACT: i64 = 1 << 50;

impl CellLattice {
    /// The boxes' corners of the cell of local index `i` (for tests and the scalar reference).
    #[cfg(test)]
    fn corners(&self, i: u32) -> ([i64; 3], [i64; 3]) {
        let (e0, e1) = (self.extent[0], self.extent[1]);
        let d = [i % e0, i / e0 % e1, i / e0 / e1].map(i64::from);
        let lo = [0, 1, 2].map(|a| self.lowest[a] + d[a] * self.step[a]);
        (lo, [0, 1, 2].map(|a| lo[a] + self.size[a]))
    }

    /// True when every cell's corners and centre sum lie where the four-lane path computes
    /// exactly what [`BoxRun::push_ints_coded`] computes on `grid`'s shifts `up` and `down`.
    fn lanes_exact(&self, up: u32, down: u32) -> bool {
        if self.cells == 0 || self.cells > 1 << 31 || self.extent.contains(&0) {
            return false;
        }
        let last = [
            i64::from(self.extent[0] - 1),
            i64::from(self.extent[1] - 1),
            i64::from((self.cells - 1) / self.extent[0] / self.extent[1]),
        ];
        (0..3).all(|a| {
            let (lo, step, size) = (self.lowest[a], self.step[a], self.size[a]);
            let in_range = (0..EXACT).contains(&lo)
                && (0..EXACT).contains(&step)
                && (0..EXACT).contains(&size);
            // The greatest upper corner and centre sum (all terms are non-negative).
            let hi = in_range
                .then(|| {
                    last[a]
                        .checked_mul(step)?
                        .checked_add(lo)?
                        .checked_add(size)
                })
                .flatten();
            hi.is_some_and(|hi| {
                let sum = 2 * hi;
                // `sum << up` stays below 2^62 and the step below 2^31: the shifts of
                // `i64`s equal a scaling by `2^(up - down)` rounded down.
                hi < EXACT && up < 62 && (sum >> (62 - up)) == 0 && (sum << up >> down) < 1 << 31
            })
        })
    }
}

impl BoxRun<'_> {
    /// Pushes the boxes of the leading refs of `refs` that name cells of `lattice`, four at a
    /// time where the CPU has AVX2 and BMI2 and the lattice's coordinates allow
    /// ([`CellLattice::lanes_exact`]); returns how many it pushed (a multiple of four: it stops
    /// before the first four holding a ref that names no cell, and before the last refs
    /// short of four, which the caller pushes one at a time). The boxes, codes and union are
    /// [`BoxRun::push_ints`]'s of the cells' corners.
    #[inline]
    pub fn push_lattice(&mut self, lattice: &CellLattice, refs: &[u64]) -> usize {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("bmi2")
            && lattice.lanes_exact(self.grid.up, self.grid.down)
        {
            // SAFETY: the CPU has AVX2 and BMI2, checked just above.
            return unsafe { self.push_lattice_avx2(lattice, refs) };
        }
        let _ = (lattice, refs);
        0
    }

    /// [`BoxRun::push_lattice`] for a CPU with AVX2 and BMI2, on a lattice whose coordinates
    /// [`CellLattice::lanes_exact`] accepts.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,bmi2")]
    fn push_lattice_avx2(&mut self, lattice: &CellLattice, refs: &[u64]) -> usize {
        use std::arch::x86_64::*;

        use glam::Vec3A;
        use obvhs::aabb::Aabb;

        use super::wide::morton_bmi2;

        let start = self.next;
        let out = self.boxes.get_mut(start..).unwrap_or_default();
        let codes = self.codes.get_mut(start..).unwrap_or_default();
        let groups = refs.len().min(out.len()).min(codes.len()) / 4;
        let splat = |x: i64| _mm256_set1_pd(x as f64);
        let first = _mm_set1_epi32(lattice.first_id as i32);
        let last_index = _mm_set1_epi32((lattice.cells - 1) as i32);
        let (e0, e1) = (
            _mm256_set1_pd(f64::from(lattice.extent[0])),
            _mm256_set1_pd(f64::from(lattice.extent[1])),
        );
        let lowest = lattice.lowest.map(splat);
        let step = lattice.step.map(splat);
        let size = lattice.size.map(splat);
        let pad = self.grid.pad;
        let (minus_pad, plus_pad) = (_mm256_set1_pd(-pad), _mm256_set1_pd(pad));
        // `2^up / 2^down`: the products below are exact, then rounded down.
        let scale = _mm256_set1_pd(self.grid.scale);
        let steps_mask = _mm_set1_epi32(super::STEPS as i32);
        // The low 32 bits of four refs, in order.
        let low_halves = _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6);
        let mut union_lo = [_mm256_set1_pd(f64::INFINITY); 3];
        let mut union_hi = [_mm256_set1_pd(f64::NEG_INFINITY); 3];
        const FLOOR: i32 = _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC;
        let mut g = 0;
        while g < groups {
            let at = 4 * g;
            // SAFETY: `at + 4 <= refs.len()` (`groups` counts whole fours of `refs`).
            let four = unsafe { _mm256_loadu_si256(refs.as_ptr().add(at).cast()) };
            let ids = _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(four, low_halves));
            let index = _mm_sub_epi32(ids, first);
            // Unsigned `index <= cells - 1` in every lane.
            let named = _mm_cmpeq_epi32(_mm_min_epu32(index, last_index), index);
            if _mm_movemask_ps(_mm_castsi128_ps(named)) != 0xf {
                break;
            }
            // Below 2^31: exact as `i32` and as `f64`; the quotients of whole numbers below
            // 2^32, rounded down, are exact.
            let i = _mm256_cvtepi32_pd(index);
            let row = _mm256_round_pd::<FLOOR>(_mm256_div_pd(i, e0));
            let layer = _mm256_round_pd::<FLOOR>(_mm256_div_pd(row, e1));
            let d = [
                _mm256_sub_pd(i, _mm256_mul_pd(row, e0)),
                _mm256_sub_pd(row, _mm256_mul_pd(layer, e1)),
                layer,
            ];
            let mut q = [_mm_setzero_si128(); 3];
            let mut lo32 = [_mm_setzero_ps(); 3];
            let mut hi32 = [_mm_setzero_ps(); 3];
            for a in 0..3 {
                let lo = _mm256_add_pd(lowest[a], _mm256_mul_pd(d[a], step[a]));
                let hi = _mm256_add_pd(lo, size[a]);
                union_lo[a] = _mm256_min_pd(union_lo[a], lo);
                union_hi[a] = _mm256_max_pd(union_hi[a], hi);
                let s = _mm256_round_pd::<FLOOR>(_mm256_mul_pd(_mm256_add_pd(lo, hi), scale));
                q[a] = _mm_and_si128(_mm256_cvttpd_epi32(s), steps_mask);
                lo32[a] = _mm256_cvtpd_ps(_mm256_add_pd(lo, minus_pad));
                hi32[a] = _mm256_cvtpd_ps(_mm256_add_pd(hi, plus_pad));
            }
            // Four `(x, y, z, z)` vectors (glam's `Vec3A` layout) from the three axes' lanes.
            let transpose = |v: [__m128; 3]| {
                let (xy01, xy23) = (_mm_unpacklo_ps(v[0], v[1]), _mm_unpackhi_ps(v[0], v[1]));
                let (zz01, zz23) = (_mm_unpacklo_ps(v[2], v[2]), _mm_unpackhi_ps(v[2], v[2]));
                [
                    _mm_movelh_ps(xy01, zz01),
                    _mm_movehl_ps(zz01, xy01),
                    _mm_movelh_ps(xy23, zz23),
                    _mm_movehl_ps(zz23, xy23),
                ]
            };
            let (mins, maxs) = (transpose(lo32), transpose(hi32));
            let lane = |v: __m128i| -> [u32; 4] {
                let mut l = [0u32; 4];
                // SAFETY: `l` has room for the 16 bytes stored.
                unsafe { _mm_storeu_si128(l.as_mut_ptr().cast(), v) };
                l
            };
            let (qx, qy, qz) = (lane(q[0]), lane(q[1]), lane(q[2]));
            for k in 0..4 {
                out[at + k] = Aabb {
                    min: Vec3A::from(mins[k]),
                    max: Vec3A::from(maxs[k]),
                };
                // SAFETY: the CPU has BMI2 (this function's target features).
                codes[at + k] = unsafe { morton_bmi2([qx[k], qy[k], qz[k]]) };
            }
            g += 1;
        }
        let n = 4 * g;
        if n > 0 {
            let fold = |v: __m256d, f: fn(f64, f64) -> f64| {
                let mut l = [0f64; 4];
                // SAFETY: `l` has room for the 32 bytes stored.
                unsafe { _mm256_storeu_pd(l.as_mut_ptr(), v) };
                f(f(l[0], l[1]), f(l[2], l[3]))
            };
            for a in 0..3 {
                // Whole numbers below 2^50: exact as `i64`.
                self.int_lo[a] = self.int_lo[a].min(fold(union_lo[a], f64::min) as i64);
                self.int_hi[a] = self.int_hi[a].max(fold(union_hi[a], f64::max) as i64);
            }
            self.next = start + n;
        }
        n
    }
}

#[cfg(test)]
mod tests {
    use obvhs::aabb::Aabb;

    use super::*;
    use crate::bvh::BoxGrid;

    /// The boxes, codes and union of `refs` pushed four at a time where they can be, the rest
    /// one at a time, against all one at a time.
    /// Returns how many were pushed four at a time.
    fn both(lattice: &CellLattice, refs: &[u64], grid: BoxGrid) -> usize {
        let corners = |r: u64| {
            let i = (r as u32).wrapping_sub(lattice.first_id);
            if i < lattice.cells {
                lattice.corners(i)
            } else {
                ([0; 3], [0; 3])
            }
        };
        let n = refs.len();
        let (mut b1, mut c1) = (vec![Aabb::empty(); n], vec![0u64; n]);
        let (mut b2, mut c2) = (vec![Aabb::empty(); n], vec![0u64; n]);
        let mut one = BoxRun::new(&mut b1, &mut c1, grid);
        one.push_ints(refs.iter().map(|&r| corners(r)));
        let u1 = one.union().get();
        let mut four = BoxRun::new(&mut b2, &mut c2, grid);
        let mut rest = refs;
        let mut lanes = 0;
        while !rest.is_empty() {
            let done = four.push_lattice(lattice, rest);
            lanes += done;
            let k = (done + 4).min(rest.len());
            four.push_ints(rest[done..k].iter().map(|&r| corners(r)));
            rest = &rest[k..];
        }
        let u2 = four.union().get();
        assert_eq!(u1, u2);
        assert_eq!(c1, c2);
        for (k, (a, b)) in b1.iter().zip(&b2).enumerate() {
            let bits = |b: &Aabb| [b.min.to_array(), b.max.to_array()].map(|v| v.map(f32::to_bits));
            assert_eq!(bits(a), bits(b), "box {k}");
        }
        lanes
    }

    #[test]
    fn four_at_a_time_equals_one_at_a_time() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move |m: u64| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed % m
        };
        for t in 0..200 {
            let extent = [1 + next(40) as u32, 1 + next(40) as u32];
            let layers = 1 + next(40) as u32;
            let scale = [1, 2, 4, 8].map(|_| 1i64 << next(4));
            let lattice = CellLattice {
                first_id: 1 << 31,
                extent,
                cells: extent[0] * extent[1] * layers,
                lowest: [0, 1, 2].map(|a| scale[a] * (1 + 2 * next(500) as i64)),
                step: [0, 1, 2].map(|a| 2 * scale[a]),
                size: [0, 1, 2].map(|a| 2 * scale[a]),
            };
            let extent_grid = [0, 1, 2]
                .map(|a| lattice.lowest[a] + 2 * lattice.step[a] * 40)
                .into_iter()
                .fold(0, i64::max) as f64;
            // Grids coarser and finer than the coordinates (shifts down and up).
            let grid = BoxGrid::new(1e-5 * extent_grid, extent_grid * [1.0, 1e-3, 7e4][t % 3]);
            let n = next(300) as usize;
            let mut refs: Vec<u64> = (0..n)
                .map(|_| {
                    let id = match next(40) {
                        // An octant, a cell past the lattice, a ref of no cell.
                        0 => next(1000) as u32,
                        1 => lattice.first_id + lattice.cells + next(5) as u32,
                        2 => u32::MAX,
                        _ => lattice.first_id + next(u64::from(lattice.cells)) as u32,
                    };
                    7u64 << 32 | u64::from(id)
                })
                .collect();
            if t % 2 == 0 {
                refs.sort_unstable();
            }
            both(&lattice, &refs, grid);
            // Refs of cells only: all but the last few four at a time.
            let cells: Vec<u64> = (0..n)
                .map(|_| u64::from(lattice.first_id) + next(u64::from(lattice.cells)))
                .collect();
            let lanes = both(&lattice, &cells, grid);
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("bmi2")
                && lattice.lanes_exact(grid.up, grid.down)
            {
                assert_eq!(lanes, n / 4 * 4, "test {t}");
            }
        }
    }

    #[test]
    fn coordinates_past_the_exact_range_go_one_at_a_time() {
        let lattice = CellLattice {
            first_id: 0,
            extent: [4, 4],
            cells: 64,
            lowest: [EXACT, 0, 0],
            step: [2; 3],
            size: [2; 3],
        };
        assert!(!lattice.lanes_exact(0, 0));
        let grid = BoxGrid::new(1e-4, 1e3);
        let refs: Vec<u64> = (0..64).collect();
        let (mut b, mut c) = (vec![Aabb::empty(); 64], vec![0; 64]);
        assert_eq!(
            BoxRun::new(&mut b, &mut c, grid).push_lattice(&lattice, &refs),
            0
        );
    }
}
