//! An isovalue as typed: a number, or `pQ`, the Q-th percentile (0 to 100) of its field's values
//! over every cell, found in each file the surface is drawn from
//! ([`amr_render::field_stats::percentile_value`]).

use std::fmt;
use std::str::FromStr;

use std::path::Path;

use amr_render::field_stats::percentile_value;
use amr_render::mapping::MappedFile;

/// An isovalue of the command line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum IsoValue {
    /// The value itself.
    Number(f32),
    /// A percentile of the field's cell values, 0 to 100.
    Percentile(f64),
}

impl IsoValue {
    /// The number typed, or 0 for a percentile: what an [`amr_render::shade::IsoSpec`] parsed
    /// beside it holds until the percentile is resolved.
    pub fn typed_number(&self) -> f32 {
        match *self {
            IsoValue::Number(v) => v,
            IsoValue::Percentile(_) => 0.0,
        }
    }

    /// The isovalue of field `field` of `file` (opened from `path`).
    pub fn resolve(&self, file: &MappedFile, path: &Path, field: usize) -> anyhow::Result<f32> {
        match *self {
            IsoValue::Number(v) => Ok(v),
            IsoValue::Percentile(q) => {
                percentile_value(file, field, q).map_err(|e| e.in_file(path).into())
            }
        }
    }
}

impl FromStr for IsoValue {
    type Err = String;

    /// `V` (a finite number) or `pQ` (`p99`, `p99.9`, `P50`).
    fn from_str(s: &str) -> Result<Self, String> {
        let t = s.trim();
        if let Some(q) = t.strip_prefix(['p', 'P']) {
            let q: f64 = q
                .parse()
                .map_err(|_| format!("'{t}' is not a percentile: p and a number, as p99"))?;
            if !(0.0..=100.0).contains(&q) {
                return Err(format!("percentile '{t}' is outside p0 to p100"));
            }
            return Ok(IsoValue::Percentile(q));
        }
        let v: f32 = t
            .parse()
            .map_err(|_| format!("isovalue '{t}' is not a number (or a percentile, as p99)"))?;
        if !v.is_finite() {
            return Err(format!("isovalue '{t}' is not finite"));
        }
        Ok(IsoValue::Number(v))
    }
}

impl fmt::Display for IsoValue {
    /// The form `FromStr` reads back.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            IsoValue::Number(v) => write!(f, "{v}"),
            IsoValue::Percentile(q) => write!(f, "p{q}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_and_percentiles_are_read_and_written_back() {
        assert_eq!("-60".parse(), Ok(IsoValue::Number(-60.0)));
        assert_eq!("p99.5".parse(), Ok(IsoValue::Percentile(99.5)));
        assert_eq!("P0".parse(), Ok(IsoValue::Percentile(0.0)));
        for bad in ["p101", "p-1", "pq", "p", "nan", "inf", "hot"] {
            assert!(bad.parse::<IsoValue>().is_err(), "{bad}");
        }
        for v in [IsoValue::Number(1e-3), IsoValue::Percentile(90.0)] {
            assert_eq!(v.to_string().parse(), Ok(v));
        }
    }
}
