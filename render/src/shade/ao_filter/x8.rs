//! The filter eight pixels at a time in AVX2 lanes: hit `h` of each of eight neighbouring
//! pixels is a lane, and the window's neighbours, taken in the order of
//! [`AoRows::filtered`] (row after row, pixel after pixel, hit after hit), are each one column
//! entry at a fixed offset from the lane's ([`super::Slots`]). Every lane computes the `f32`
//! operations of [`AoRows::filtered`] in their order; a neighbour a lane does not keep adds
//! `+0.0` to its sum, which leaves a sum of non-negative occlusions bit for bit as it was.

use std::arch::x86_64::*;

use super::{
    window_columns, AoRows, PixelSpan, AFTER, BEFORE, GROUP, MIN_FACING, MIN_NORMAL_COSINE,
    PLANE_TOLERANCE,
};

/// Writes to `out` the filtered occlusion of hit `h` of each of the [`GROUP`] pixels from
/// `x0` of row `y` (anything for a pixel without one).
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn filter_group(
    rows: &AoRows,
    y: u32,
    x0: usize,
    h: usize,
    span: PixelSpan,
    out: &mut [f32; GROUP],
) {
    // Every row's columns hold `BEFORE + width + AFTER + GROUP` entries ([`Slots::empty`]): from
    // `x0 + BEFORE + dx` with `-BEFORE <= dx <= AFTER`, `GROUP` entries are inside.
    assert!(x0 < rows.width as usize);
    let at = x0 + BEFORE as usize;
    let c = rows.slots_of(y)[h];
    // SAFETY: `at` and the offsets below stay inside every row's columns (above).
    let load = |v: &Vec<f32>, i: usize| unsafe { _mm256_loadu_ps(v.as_ptr().add(i)) };
    let load_u32 = |v: &Vec<u32>, i: usize| unsafe { _mm256_loadu_si256(v.as_ptr().add(i).cast()) };
    let surface = load_u32(&c.surface, at);
    let cp = [0, 1, 2].map(|a| load(&c.p[a], at));
    let cn = [0, 1, 2].map(|a| load(&c.n[a], at));
    let sign = _mm256_set1_ps(-0.0);
    // The scalar filter's footprint, lane by lane.
    let footprint = match span {
        PixelSpan::Angle(angle) => {
            let distance = _mm256_sqrt_ps(dot(cp, cp));
            let facing = _mm256_max_ps(
                _mm256_div_ps(_mm256_andnot_ps(sign, dot(cn, cp)), distance),
                _mm256_set1_ps(MIN_FACING),
            );
            _mm256_div_ps(
                _mm256_mul_ps(
                    _mm256_mul_ps(_mm256_set1_ps(PLANE_TOLERANCE), distance),
                    _mm256_set1_ps(angle),
                ),
                _mm256_mul_ps(facing, facing),
            )
        }
        PixelSpan::Parallel { size, forward } => {
            let f = forward.map(|v| _mm256_set1_ps(v));
            let facing = _mm256_max_ps(
                _mm256_andnot_ps(sign, dot(cn, f)),
                _mm256_set1_ps(MIN_FACING),
            );
            _mm256_div_ps(
                _mm256_set1_ps(PLANE_TOLERANCE * size),
                _mm256_mul_ps(facing, facing),
            )
        }
    };
    let min_cosine = _mm256_set1_ps(MIN_NORMAL_COSINE);
    let (mut sum, mut count) = (_mm256_setzero_ps(), _mm256_setzero_si256());
    let last_row = rows.rows.len() as u32 - 1;
    for qy in y.saturating_sub(BEFORE)..=(y + AFTER).min(last_row) {
        let dy = qy.abs_diff(y);
        let row = rows.slots_of(qy);
        for (dx, steps) in window_columns(dy) {
            let tolerance = _mm256_mul_ps(footprint, _mm256_set1_ps(steps));
            let i = at.wrapping_add_signed(dx);
            for q in row {
                let same =
                    _mm256_castsi256_ps(_mm256_cmpeq_epi32(load_u32(&q.surface, i), surface));
                let n = [0, 1, 2].map(|a| load(&q.n[a], i));
                let faces = _mm256_cmp_ps::<_CMP_GE_OQ>(dot(n, cn), min_cosine);
                let d = [0, 1, 2].map(|a| _mm256_sub_ps(load(&q.p[a], i), cp[a]));
                let off = _mm256_andnot_ps(sign, dot(cn, d));
                let near = _mm256_cmp_ps::<_CMP_LE_OQ>(off, tolerance);
                let kept = _mm256_and_ps(_mm256_and_ps(faces, near), same);
                sum = _mm256_add_ps(sum, _mm256_and_ps(kept, load(&q.ao, i)));
                count = _mm256_sub_epi32(count, _mm256_castps_si256(kept));
            }
        }
    }
    let mean = _mm256_div_ps(sum, _mm256_cvtepi32_ps(count));
    let some = _mm256_castsi256_ps(_mm256_cmpgt_epi32(count, _mm256_setzero_si256()));
    let filtered = _mm256_blendv_ps(load(&c.ao, at), mean, some);
    // SAFETY: `out` holds eight `f32`.
    unsafe { _mm256_storeu_ps(out.as_mut_ptr(), filtered) };
}

/// `a . b` lane by lane, as [`super::dot`]: `(a0 b0 + a1 b1) + a2 b2`.
#[target_feature(enable = "avx2")]
#[inline]
fn dot(a: [__m256; 3], b: [__m256; 3]) -> __m256 {
    _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(a[0], b[0]), _mm256_mul_ps(a[1], b[1])),
        _mm256_mul_ps(a[2], b[2]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shade::ao_filter::{AoLayer, AoRow, FILTERED_HITS};

    /// A splitmix-like generator, for reproducible hits.
    fn next(state: &mut u64) -> f32 {
        *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = *state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }

    #[test]
    fn the_lanes_filter_each_hit_as_the_scalar_filter_does() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let (width, height) = (21u32, 7u32);
        let mut state = 7u64;
        // Nearly facing normals, points near a plane, two surfaces: every test both keeps and
        // rejects neighbours; one hit at the camera (distance zero).
        let rows: Vec<AoRow> = (0..height)
            .map(|y| {
                let mut row = AoRow::new();
                for x in 0..width {
                    for _ in 0..((x + y) % 3).min(FILTERED_HITS as u32) {
                        let mut r = || next(&mut state);
                        let n = [0.2 * r() - 0.1, 0.2 * r() - 0.1, -1.0];
                        let len = (n[0] * n[0] + n[1] * n[1] + 1.0).sqrt();
                        let z = if (x, y) == (5, 3) {
                            0.0
                        } else {
                            1.0 + 0.02 * r()
                        };
                        row.layers_mut().push(AoLayer {
                            surface: (r() * 1.5) as u32,
                            p: [0.01 * x as f32, 0.01 * y as f32, z],
                            n: n.map(|v| v / len),
                            ao: r(),
                            weight: [1.0; 3],
                        });
                    }
                    row.end_pixel();
                }
                row
            })
            .collect();
        let filter = AoRows::new(width, &rows);
        let parallel = PixelSpan::Parallel {
            size: 0.0002,
            forward: [0.1, -0.1, 0.99],
        };
        for span in [PixelSpan::Angle(0.01), parallel] {
            let (mut kept, mut hits) = (0, 0);
            for y in 0..height {
                for x0 in (0..width as usize).step_by(GROUP) {
                    for h in 0..FILTERED_HITS {
                        let mut out = [0.0; GROUP];
                        // SAFETY: the CPU has AVX2, checked above.
                        unsafe { filter_group(&filter, y, x0, h, span, &mut out) };
                        for (x, &lane) in (x0..(x0 + GROUP).min(width as usize)).zip(&out) {
                            let Some(layer) = rows[y as usize].pixel(x as u32).get(h) else {
                                continue;
                            };
                            let scalar = filter.filtered(layer, x as u32, y, span);
                            assert_eq!(lane.to_bits(), scalar.to_bits(), "{span:?} {x} {y} {h}");
                            hits += 1;
                            kept += usize::from(scalar != layer.ao);
                        }
                    }
                }
            }
            assert!(kept > 0 && kept < hits, "{span:?}: {kept} of {hits}");
        }
    }
}
