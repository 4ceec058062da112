//! The filter's window test eight neighbours at a time in AVX2 lanes: each lane computes the
//! `f32` operations of [`HitColumns::add_run`] in their order, and the kept neighbours'
//! occlusions are added one after the other in the run's order, so the sum is the scalar one
//! bit for bit. Most neighbours fail a test (another surface, a crease, another layer): the
//! lanes test all of them at once instead of branching on each.

use std::arch::x86_64::*;
use std::ops::Range;

use super::{Centre, HitColumns, Mean, MIN_NORMAL_COSINE};

/// Lanes per group.
const LANES: usize = 8;

/// [`HitColumns::add_run`], eight hits at a time.
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn add_run(cols: &HitColumns, run: Range<usize>, centre: &Centre, mean: &mut Mean) {
    // Every group read starts at a hit and stays inside the padding after the last one.
    assert!(run.end <= cols.hits() && HitColumns::PAD >= LANES);
    let surface = _mm256_set1_epi32(centre.surface as i32);
    let cn = centre.n.map(|v| _mm256_set1_ps(v));
    let cp = centre.p.map(|v| _mm256_set1_ps(v));
    let min_cosine = _mm256_set1_ps(MIN_NORMAL_COSINE);
    let footprint = _mm256_set1_ps(centre.footprint);
    let x = _mm256_set1_epi32(centre.x as i32);
    let least_steps = _mm256_set1_epi32(centre.least_steps as i32);
    let lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let sign = _mm256_set1_ps(-0.0);
    let mut i = run.start;
    while i < run.end {
        // SAFETY: `i < run.end <= hits()`, and every column holds `PAD >= LANES` entries
        // after its hits: the eight entries from `i` are inside each.
        let (s, n, p, column) = unsafe {
            let f = |v: &Vec<f32>| _mm256_loadu_ps(v.as_ptr().add(i));
            let u = |v: &Vec<u32>| _mm256_loadu_si256(v.as_ptr().add(i).cast());
            (
                u(&cols.surface),
                [f(&cols.n[0]), f(&cols.n[1]), f(&cols.n[2])],
                [f(&cols.p[0]), f(&cols.p[1]), f(&cols.p[2])],
                u(&cols.column),
            )
        };
        let in_run = _mm256_cmpgt_epi32(_mm256_set1_epi32((run.end - i) as i32), lane);
        let same = _mm256_and_si256(_mm256_cmpeq_epi32(s, surface), in_run);
        let cosine = _mm256_add_ps(
            _mm256_add_ps(_mm256_mul_ps(n[0], cn[0]), _mm256_mul_ps(n[1], cn[1])),
            _mm256_mul_ps(n[2], cn[2]),
        );
        let faces = _mm256_cmp_ps::<_CMP_GE_OQ>(cosine, min_cosine);
        let off = _mm256_add_ps(
            _mm256_add_ps(
                _mm256_mul_ps(cn[0], _mm256_sub_ps(p[0], cp[0])),
                _mm256_mul_ps(cn[1], _mm256_sub_ps(p[1], cp[1])),
            ),
            _mm256_mul_ps(cn[2], _mm256_sub_ps(p[2], cp[2])),
        );
        let steps = _mm256_max_epi32(_mm256_abs_epi32(_mm256_sub_epi32(column, x)), least_steps);
        let tolerance = _mm256_mul_ps(footprint, _mm256_cvtepi32_ps(steps));
        let near = _mm256_cmp_ps::<_CMP_LE_OQ>(_mm256_andnot_ps(sign, off), tolerance);
        let kept = _mm256_and_ps(_mm256_and_ps(faces, near), _mm256_castsi256_ps(same));
        let mut bits = _mm256_movemask_ps(kept) as u32;
        mean.count += bits.count_ones();
        while bits != 0 {
            mean.sum += cols.ao[i + bits.trailing_zeros() as usize];
            bits &= bits - 1;
        }
        i += LANES;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shade::ao_filter::{AoLayer, AoRow};

    /// A splitmix-like generator, for reproducible neighbours.
    fn next(state: &mut u64) -> f32 {
        *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = *state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }

    #[test]
    fn the_lanes_keep_the_neighbours_and_sum_of_the_scalar_test() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut state = 7u64;
        let mut row = AoRow::new();
        // Nearly facing normals and points near a plane, so that every test both passes and
        // fails; a few NaN positions too.
        for x in 0..40 {
            for _ in 0..(x % 3) {
                let mut r = || next(&mut state);
                let n = [0.1 * r(), 0.1 * r(), -1.0];
                let len = (n[0] * n[0] + n[1] * n[1] + 1.0).sqrt();
                let z = if x == 17 { f32::NAN } else { 1.0 + 0.02 * r() };
                row.layers_mut().push(AoLayer {
                    surface: (r() * 1.5) as u32,
                    p: [0.01 * x as f32, 0.0, z],
                    n: n.map(|v| v / len),
                    ao: r(),
                    weight: [1.0; 3],
                });
            }
            row.end_pixel();
        }
        let cols = HitColumns::of(&row);
        let hits = cols.hits();
        for (c, layer) in row.layers.iter().enumerate() {
            for least_steps in [1, 2] {
                for footprint in [0.0, 1e-3, 0.01, f32::INFINITY] {
                    let centre = Centre {
                        surface: layer.surface,
                        p: layer.p,
                        n: layer.n,
                        footprint,
                        x: row.column[c],
                        least_steps,
                    };
                    for start in [0, c.saturating_sub(3), c] {
                        for end in [start, (start + 5).min(hits), (start + 13).min(hits), hits] {
                            let (mut a, mut b) = (Mean::default(), Mean::default());
                            cols.add_run(start..end, &centre, &mut a);
                            // SAFETY: the CPU has AVX2, checked above.
                            unsafe { add_run(&cols, start..end, &centre, &mut b) };
                            assert_eq!(a.count, b.count, "{c} {start}..{end}");
                            assert_eq!(a.sum.to_bits(), b.sum.to_bits(), "{c} {start}..{end}");
                        }
                    }
                }
            }
        }
    }
}
