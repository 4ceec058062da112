//! The range of many `f32` values, accumulated over independent lanes so that it vectorizes.
//!
//! A single running `min`/`max` is one long dependency chain and does not vectorize; range scans
//! of brick data (the writer, `verify`, the renderer's tight ranges) are bandwidth-bound only when
//! the lanes are independent.

const LANES: usize = 16;

/// True for a range a tight leaf range table may hold: no NaN, and `lo <= hi` or the empty
/// range `(+inf, -inf)` of a leaf without data.
pub fn valid_tight_range(lo: f32, hi: f32) -> bool {
    lo <= hi || (lo == f32::INFINITY && hi == f32::NEG_INFINITY)
}
const EXPONENT: u32 = 0x7f80_0000;

/// A running range of `f32` values fed a slice at a time; NaNs are ignored.
#[derive(Clone, Debug)]
pub struct RangeAccumulator {
    lo: [f32; LANES],
    hi: [f32; LANES],
}

impl Default for RangeAccumulator {
    fn default() -> Self {
        Self::new()
    }
}

impl RangeAccumulator {
    /// The empty range.
    pub fn new() -> Self {
        Self {
            lo: [f32::INFINITY; LANES],
            hi: [f32::NEG_INFINITY; LANES],
        }
    }

    /// Adds `values`.
    #[inline]
    pub fn add(&mut self, values: &[f32]) {
        let (mut lo, mut hi) = (self.lo, self.hi);
        let (chunks, tail) = values.as_chunks::<LANES>();
        for chunk in chunks {
            for k in 0..LANES {
                // A select rather than `f32::min`: one instruction per lane, and a NaN
                // compares false so it is ignored all the same.
                lo[k] = if chunk[k] < lo[k] { chunk[k] } else { lo[k] };
                hi[k] = if chunk[k] > hi[k] { chunk[k] } else { hi[k] };
            }
        }
        for &v in tail {
            lo[0] = if v < lo[0] { v } else { lo[0] };
            hi[0] = if v > hi[0] { v } else { hi[0] };
        }
        (self.lo, self.hi) = (lo, hi);
    }

    /// The range so far: `(+inf, -inf)` when empty.
    pub fn range(&self) -> (f32, f32) {
        (
            self.lo.iter().copied().fold(f32::INFINITY, f32::min),
            self.hi.iter().copied().fold(f32::NEG_INFINITY, f32::max),
        )
    }
}

/// The range of `values`: `(+inf, -inf)` when empty; NaNs are ignored.
pub fn value_range(values: &[f32]) -> (f32, f32) {
    let mut acc = RangeAccumulator::new();
    acc.add(values);
    acc.range()
}

/// The range of `values`, or `None` if one is NaN or infinite.
pub fn finite_range(values: &[f32]) -> Option<(f32, f32)> {
    let mut not_finite = [0u32; LANES];
    let chunks = values.chunks_exact(LANES);
    let tail = chunks.remainder();
    for chunk in chunks {
        for (bad, &v) in not_finite.iter_mut().zip(chunk) {
            *bad |= u32::from(v.to_bits() & EXPONENT == EXPONENT);
        }
    }
    let tail_bad = tail.iter().any(|v| !v.is_finite());
    if tail_bad || not_finite.iter().any(|&b| b != 0) {
        return None;
    }
    Some(value_range(values))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_a_running_min_and_max_for_every_length_and_offset() {
        let values: Vec<f32> = (0..200)
            .map(|i| ((i * 37 % 101) as f32 - 50.0) * 0.25)
            .collect();
        for start in 0..20 {
            for end in start..values.len() {
                let part = &values[start..end];
                let expected = part
                    .iter()
                    .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
                        (a.min(v), b.max(v))
                    });
                assert_eq!(value_range(part), expected, "{start}..{end}");
                assert_eq!(finite_range(part), Some(expected));
            }
        }
    }

    #[test]
    fn nan_is_ignored_by_value_range() {
        let mut values = vec![2.0f32; 40];
        values[17] = f32::NAN;
        assert_eq!(value_range(&values), (2.0, 2.0));
    }

    #[test]
    fn finite_range_finds_extremes_and_non_finite_values_anywhere() {
        for n in [1usize, 15, 16, 17, 100] {
            let v: Vec<f32> = (0..n).map(|i| i as f32 - 3.0).collect();
            assert_eq!(finite_range(&v), Some((-3.0, n as f32 - 4.0)));
            for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
                for at in [0, n / 2, n - 1] {
                    let mut w = v.clone();
                    w[at] = bad;
                    assert_eq!(finite_range(&w), None, "n {n}, {bad} at {at}");
                }
            }
        }
    }
}
