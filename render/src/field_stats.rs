//! The distribution of a field's cell values (percentiles over every cell of every level, from an
//! even subsample when the file is large), and numbers formatted for people.

use amr_format::compress::Encoding;
use amr_format::AmrkFile;

use crate::error::{RenderError, Result};
use crate::mapping::MappedFile;

/// Most cell values a distribution is computed from.
pub const MAX_SAMPLES: usize = 1 << 20;

/// The quantiles `amr-render info` lists for each field.
pub const TABLE: [f64; 7] = [0.0, 0.01, 0.25, 0.5, 0.75, 0.99, 1.0];

/// Cells read together at each place a large field is sampled: a run of consecutive values,
/// so that a subsample reads a few pages in a few hundred places, not every page of the file.
pub const SAMPLE_RUN: u64 = 512;

/// The value at percentile `percent` (0 to 100) of field `field`'s cell values over every cell
/// of every level of `file`: [`percentile_values`] of one percentile.
pub fn percentile_value(file: &MappedFile, field: usize, percent: f64) -> Result<f32> {
    Ok(percentile_values(file, field, &[percent])?[0])
}

/// The values at `percents` (each 0 to 100) of field `field`'s cell values over every cell of
/// every level of `file` (nearest rank; from an even subsample of [`MAX_SAMPLES`] cells in
/// larger files, read ahead, once for them all), each rounded to the five significant digits
/// [`format_value`] prints, so that the isovalue shown can be typed again; unrounded where
/// rounding would leave the field's range.
pub fn percentile_values(file: &MappedFile, field: usize, percents: &[f64]) -> Result<Vec<f32>> {
    if let Some(bad) = percents.iter().find(|q| !(0.0..=100.0).contains(*q)) {
        return Err(RenderError::Invalid(format!(
            "percentile {bad} is outside 0 to 100"
        )));
    }
    let read_ahead = |r: &[(u64, u64)]| crate::mapping::read_ahead(file, r.iter().copied());
    let p = FieldPercentiles::of_reading_ahead(file, field, read_ahead)?;
    let f = &file.fields()[field];
    percents
        .iter()
        .map(|&q| {
            p.value_shown(q, (f.min, f.max)).ok_or_else(|| {
                RenderError::Invalid(format!(
                    "field '{}' has no finite value to take a percentile of",
                    f.name
                ))
            })
        })
        .collect()
}

/// The sorted finite cell values of a field: every cell, or evenly spaced runs of cells.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldPercentiles {
    sorted: Vec<f32>,
    /// Cells counted in the file.
    pub cells: u64,
    /// True when the values are runs of cells, not every cell ([`Self::of`]).
    pub subsampled: bool,
}

impl FieldPercentiles {
    /// The distribution of field `field` of `file`: every cell when the file has at most
    /// [`MAX_SAMPLES`], else `MAX_SAMPLES / SAMPLE_RUN` runs of [`SAMPLE_RUN`] consecutive cells
    /// evenly spaced along all the bricks' cells in brick order (each cell as likely to be taken
    /// as any other; a run may go on into the next brick). Only the bricks a run meets are read.
    pub fn of<D: AsRef<[u8]>>(file: &AmrkFile<D>, field: usize) -> Result<Self> {
        Self::of_reading_ahead(file, field, |_| {})
    }

    /// [`Self::of`], first handing `read_ahead` the byte ranges of the file it is about to read
    /// (offset, length): the runs of raw bricks, compressed bricks whole. A mapped file asks the
    /// kernel for them all at once, so that a cold disk reads them with a deep queue rather
    /// than one page fault at a time.
    pub fn of_reading_ahead<D: AsRef<[u8]>>(
        file: &AmrkFile<D>,
        field: usize,
        read_ahead: impl FnOnce(&[(u64, u64)]),
    ) -> Result<Self> {
        if field >= file.fields().len() {
            return Err(RenderError::Invalid(format!("no field {field}")));
        }
        let sizes: Vec<u64> = (0..file.num_bricks())
            .map(|b| file.brick(b).cells.num_cells().unwrap_or(0))
            .collect();
        let cells: u64 = sizes.iter().sum();
        let takes = brick_takes(&sizes, &sample_runs(cells));
        let ranges: Vec<(u64, u64)> = takes
            .iter()
            .map(|&(b, lo, hi)| {
                let at = file.brick_data(field, b);
                match at.encoding {
                    Encoding::Raw => (at.offset + 4 * lo, 4 * (hi - lo)),
                    _ => (at.offset, at.len),
                }
            })
            .collect();
        read_ahead(&ranges);
        let mut sorted = Vec::with_capacity(cells.min(MAX_SAMPLES as u64) as usize + 1);
        let mut last: Option<(usize, std::borrow::Cow<'_, [f32]>)> = None;
        for &(b, lo, hi) in &takes {
            if last.as_ref().is_none_or(|(l, _)| *l != b) {
                last = Some((b, file.brick_values(field, b)?));
            }
            let Some((_, values)) = &last else {
                unreachable!("set above");
            };
            // `open` checks that a brick holds its cells' values; kept from panicking all the same.
            let Some(taken) = values.get(lo as usize..hi as usize) else {
                return Err(RenderError::Invalid(format!(
                    "brick {b} of field {field} holds {} values, fewer than its cells",
                    values.len()
                )));
            };
            sorted.extend(taken.iter().copied().filter(|v| v.is_finite()));
        }
        sorted.sort_unstable_by(f32::total_cmp);
        Ok(FieldPercentiles {
            sorted,
            cells,
            subsampled: cells > MAX_SAMPLES as u64,
        })
    }

    /// The value at quantile `q` in `[0, 1]` (nearest rank; NaN without values).
    pub fn at(&self, q: f64) -> f64 {
        if self.sorted.is_empty() {
            return f64::NAN;
        }
        let i = ((self.sorted.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
        f64::from(self.sorted[i])
    }

    /// The value at percentile `percent` (0 to 100), rounded to the five significant digits
    /// [`format_value`] prints, unrounded where rounding would leave `range` (the field's
    /// smallest and largest values); `None` without values.
    pub fn value_shown(&self, percent: f64, range: (f32, f32)) -> Option<f32> {
        let exact = self.at(percent / 100.0);
        if exact.is_nan() {
            return None;
        }
        let rounded = round_to_shown(exact);
        Some(match (range.0..=range.1).contains(&rounded) {
            true => rounded,
            false => exact as f32,
        })
    }

    /// The median of the values off the plateaus at the ends of the range: the values within
    /// round-off (a millionth of their magnitude) of the smallest or the largest are left out, as
    /// a floor or a ceiling many cells sit on. `None` when nothing is left.
    pub fn median_off_plateaus(&self) -> Option<f64> {
        let (floor, ceiling) = self.plateau_edges()?;
        let first = self.sorted.partition_point(|&v| f64::from(v) <= floor);
        let end = self.sorted.partition_point(|&v| f64::from(v) < ceiling);
        (first < end).then(|| f64::from(self.sorted[first + (end - 1 - first) / 2]))
    }

    /// True when `v` lies off the plateaus at the ends of the range (see
    /// [`FieldPercentiles::median_off_plateaus`]).
    pub fn off_plateaus(&self, v: f64) -> bool {
        self.plateau_edges()
            .is_some_and(|(floor, ceiling)| v > floor && v < ceiling)
    }

    /// The top of the floor plateau and the bottom of the ceiling plateau; `None` without values.
    fn plateau_edges(&self) -> Option<(f64, f64)> {
        let (lo, hi) = (
            f64::from(*self.sorted.first()?),
            f64::from(*self.sorted.last()?),
        );
        Some((lo + 1e-6 * lo.abs(), hi - 1e-6 * hi.abs()))
    }

    /// Values the distribution was computed from.
    pub fn samples(&self) -> usize {
        self.sorted.len()
    }
}

/// The cells a distribution is computed from, as ranges of the bricks' cells in brick order:
/// all of them up to [`MAX_SAMPLES`], else runs of [`SAMPLE_RUN`] centred on evenly spaced
/// places (apart by more than a run, so they never overlap).
fn sample_runs(cells: u64) -> Vec<(u64, u64)> {
    let max = MAX_SAMPLES as u64;
    if cells <= max {
        return vec![(0, cells)];
    }
    let runs = max / SAMPLE_RUN;
    (0..runs)
        .map(|k| {
            let centre = ((2 * k + 1) as u128 * u128::from(cells) / (2 * runs) as u128) as u64;
            let lo = centre
                .saturating_sub(SAMPLE_RUN / 2)
                .min(cells - SAMPLE_RUN);
            (lo, lo + SAMPLE_RUN)
        })
        .collect()
}

/// The cells of each brick that `runs` (ranges of all the bricks' cells in brick order, sorted
/// and apart) take: `(brick, first, end)` with cell indices within the brick, in brick order.
fn brick_takes(sizes: &[u64], runs: &[(u64, u64)]) -> Vec<(usize, u64, u64)> {
    let mut takes = Vec::new();
    let mut next = 0;
    let mut first = 0u64;
    for (b, &n) in sizes.iter().enumerate() {
        let end = first + n;
        while next < runs.len() && runs[next].1 <= first {
            next += 1;
        }
        for &(lo, hi) in runs[next..].iter().take_while(|r| r.0 < end) {
            let (lo, hi) = (lo.max(first), hi.min(end));
            if lo < hi {
                takes.push((b, lo - first, hi - first));
            }
        }
        first = end;
    }
    takes
}

/// `v` with about 5 significant digits: plain between 1e-3 and 1e6, scientific otherwise
/// (`-6.6796e-33`, not 40 digits of zeros).
pub fn format_value(v: f64) -> String {
    format_significant(v, 5)
}

/// The `f32` nearest to `v` as [`format_value`] writes it (five significant digits).
pub fn round_to_shown(v: f64) -> f32 {
    format_value(v).parse().unwrap_or(v as f32)
}

/// An isovalue as [`format_value`] writes it, with more significant digits (up to the 9 that
/// tell any two `f32` apart) where five would read as another isovalue: `1.000005` is not `1`.
pub fn format_isovalue(v: f32) -> String {
    let mut s = format_value(f64::from(v));
    for digits in 6..=9 {
        if s.parse::<f32>().is_ok_and(|read| read == v) {
            break;
        }
        s = format_significant(f64::from(v), digits);
    }
    s
}

/// `(x, y, z)` with each value as [`format_value`] writes it.
pub fn format_vector(v: [f64; 3]) -> String {
    format!(
        "({}, {}, {})",
        format_value(v[0]),
        format_value(v[1]),
        format_value(v[2])
    )
}

/// The labels of `values` (tick marks, ascending) by [`format_value`], with more significant
/// digits where fewer would print two of them alike or put a label on the wrong tick: ticks
/// `5e-6` apart from 1.000005 are `1.000005, 1.00001`, not `1, 1.00001`.
pub fn distinct_labels(values: &[f64]) -> Vec<String> {
    let spacing = values
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(f64::INFINITY, f64::min);
    let reads_as_its_tick = |label: &str, v: f64| {
        !spacing.is_finite()
            || label
                .parse::<f64>()
                .is_ok_and(|read| (read - v).abs() <= 0.01 * spacing)
    };
    let mut labels = Vec::new();
    for digits in 5..=17 {
        labels = values
            .iter()
            .map(|&v| format_significant(v, digits))
            .collect();
        if labels.windows(2).all(|w| w[0] != w[1])
            && labels
                .iter()
                .zip(values)
                .all(|(l, &v)| reads_as_its_tick(l, v))
        {
            break;
        }
    }
    labels
}

/// `v` with about `digits` significant digits, as [`format_value`] prints it.
fn format_significant(v: f64, digits: usize) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if (1e-3..1e6).contains(&a) {
        let decimals = (digits as i32 - 1 - a.log10().floor() as i32).max(0) as usize;
        let s = format!("{v:.decimals$}");
        match s.contains('.') {
            true => s.trim_end_matches('0').trim_end_matches('.').to_string(),
            false => s,
        }
    } else {
        let mantissa = digits.saturating_sub(1);
        let s = format!("{v:.mantissa$e}");
        let (m, e) = s.split_once('e').unwrap_or((&s, "0"));
        let m = match m.contains('.') {
            true => m.trim_end_matches('0').trim_end_matches('.'),
            false => m,
        };
        format!("{m}e{e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn isovalues_print_with_the_digits_that_tell_them_apart() {
        assert_eq!(format_isovalue(10.0), "10");
        assert_eq!(format_isovalue(0.27), "0.27");
        assert_eq!(format_isovalue(1.000005), "1.000005");
        assert_eq!(format_isovalue(-2.5e-7), "-2.5e-7");
        assert_eq!(format_isovalue(4.476523), "4.476523");
        assert_eq!(round_to_shown(4.476523), 4.4765);
        assert_eq!(format_isovalue(round_to_shown(0.232615713)), "0.23262");
        for v in [
            1.000_000_1f32,
            123_456.79,
            3.333_333_3e-12,
            f32::MAX,
            f32::MIN_POSITIVE,
        ] {
            assert_eq!(format_isovalue(v).parse::<f32>(), Ok(v), "{v}");
        }
    }

    #[test]
    fn sample_runs_are_every_cell_or_even_runs_inside_the_cells() {
        assert_eq!(sample_runs(1000), vec![(0, 1000)]);
        assert_eq!(
            sample_runs(MAX_SAMPLES as u64),
            vec![(0, MAX_SAMPLES as u64)]
        );
        for cells in [MAX_SAMPLES as u64 + 1, 3_000_000, 2_035_056_640] {
            let runs = sample_runs(cells);
            assert_eq!(runs.len() as u64, MAX_SAMPLES as u64 / SAMPLE_RUN);
            assert!(runs
                .iter()
                .all(|&(lo, hi)| hi - lo == SAMPLE_RUN && hi <= cells));
            assert!(
                runs.windows(2).all(|w| w[0].1 <= w[1].0),
                "{cells}: runs overlap"
            );
            // Evenly spread: the gaps between runs differ by at most one cell.
            let gaps: Vec<u64> = runs.windows(2).map(|w| w[1].0 - w[0].0).collect();
            let (lo, hi) = (gaps.iter().min().unwrap(), gaps.iter().max().unwrap());
            assert!(hi - lo <= 1, "{cells}: gaps {lo}..{hi}");
        }
    }

    /// On a file of more cells than are sampled, the runs give the quartiles and the 1st and
    /// 99th percentiles of every cell to within 1.5 % of the field's spread there.
    #[test]
    fn sampled_percentiles_agree_with_every_cell() {
        use amr_format::progress::NoProgress;
        use amr_synth::{write_synth, Case, SynthParams};
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.amrk");
        let params = SynthParams {
            base: 96,
            brick: 16,
            ..SynthParams::default()
        };
        write_synth(&path, Case::Blobs, &params, Default::default(), &NoProgress).unwrap();
        let file = AmrkFile::open(std::fs::read(&path).unwrap()).unwrap();
        let sampled = FieldPercentiles::of(&file, 0).unwrap();
        assert!(sampled.subsampled && sampled.cells > 2 * MAX_SAMPLES as u64);
        let mut every: Vec<f32> = Vec::new();
        for b in 0..file.num_bricks() {
            every.extend(file.brick_values(0, b).unwrap().iter().copied());
        }
        every.sort_unstable_by(f32::total_cmp);
        let exact = |q: f64| f64::from(every[((every.len() - 1) as f64 * q).round() as usize]);
        let spread = exact(0.99) - exact(0.01);
        for q in [0.01, 0.25, 0.5, 0.75, 0.99] {
            let off = (sampled.at(q) - exact(q)).abs();
            assert!(
                off < 0.015 * spread,
                "p{}: {} against {}",
                q * 100.0,
                sampled.at(q),
                exact(q)
            );
        }
    }

    #[test]
    fn numbers_read_as_people_write_them() {
        assert_eq!(format_value(-6.679641e-33), "-6.6796e-33");
        assert_eq!(format_value(298.0), "298");
        assert_eq!(format_value(1579.8536), "1579.9");
        assert_eq!(format_value(0.016), "0.016");
        assert_eq!(format_value(-126103.875), "-126104");
        assert_eq!(format_value(101325.0), "101325");
        assert_eq!(format_value(1.5e-13), "1.5e-13");
        assert_eq!(format_value(855399.2), "855399");
        assert_eq!(format_value(2.5e7), "2.5e7");
        assert_eq!(format_value(0.0), "0");
    }

    #[test]
    fn tick_labels_are_told_apart() {
        assert_eq!(distinct_labels(&[0.0, 2.5, 5.0]), ["0", "2.5", "5"]);
        assert_eq!(
            distinct_labels(&[1.0, 1.00002, 1.00004]),
            ["1", "1.00002", "1.00004"]
        );
        assert_eq!(distinct_labels(&[2e7, 2.00001e7]), ["2e7", "2.00001e7"]);
        assert_eq!(
            distinct_labels(&[1.000005, 1.00001]),
            ["1.000005", "1.00001"]
        );
        assert_eq!(
            distinct_labels(&[-0.25, 0.0, 0.25, 0.5]),
            ["-0.25", "0", "0.25", "0.5"]
        );
        assert_eq!(
            distinct_labels(&[10.0, 100.0, 1000.0]),
            ["10", "100", "1000"]
        );
    }
}
