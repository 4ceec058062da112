//! Colouring surfaces and slices by data: what paints them ([`ColorBy`]: a field of the file, the
//! length of a vector of fields, or the AMR level) and how values become colours ([`ColorScale`]: a colormap over a range, linear
//! or logarithmic, the range by default robust over the values a frame shows).

use std::fmt;
use std::str::FromStr;

use crate::colormap::Colormap;

/// What paints a surface or a slice.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum ColorBy {
    /// A field of the file, sampled with the scene's reconstruction at each hit.
    Field(String),
    /// The length of the vector whose components are fields of the file, each sampled at each
    /// hit (a velocity's magnitude from its three components): made by [`ColorBy::magnitude`].
    Magnitude {
        /// How it is written and named, `|x-velocity,y-velocity,z-velocity|`.
        name: String,
        /// The components' fields, two or more.
        fields: Vec<String>,
    },
    /// The AMR level of the data at each hit, with a categorical palette.
    Level,
}

impl ColorBy {
    /// The length of the vector of the fields `fields` (two or more, none empty); named
    /// `|a,b,c|`, as the command line writes it.
    pub fn magnitude(fields: &[&str]) -> Result<ColorBy, String> {
        let example = "|x-velocity,y-velocity,z-velocity|";
        if fields.len() < 2 {
            return Err(format!(
                "a magnitude names two or more fields between bars, {example}"
            ));
        }
        if fields.iter().any(|f| f.is_empty()) {
            return Err(format!(
                "an empty field name in a magnitude; write {example}"
            ));
        }
        Ok(ColorBy::Magnitude {
            name: format!("|{}|", fields.join(",")),
            fields: fields.iter().map(|f| f.to_string()).collect(),
        })
    }

    /// The name of what paints, one colour range per name: the field's, or the magnitude's
    /// `|a,b,c|`; `None` for the level.
    pub fn painted_name(&self) -> Option<&str> {
        match self {
            ColorBy::Field(name) | ColorBy::Magnitude { name, .. } => Some(name),
            ColorBy::Level => None,
        }
    }

    /// The fields of the file it reads.
    pub fn fields(&self) -> Vec<&str> {
        match self {
            ColorBy::Field(name) => vec![name],
            ColorBy::Magnitude { fields, .. } => fields.iter().map(String::as_str).collect(),
            ColorBy::Level => Vec::new(),
        }
    }
}

/// The magnitudes the fields `names` hold as x, y and z components: three names alike but for one
/// letter, `x`, `y` and `z` (or `X`, `Y`, `Z`) at the same place (`x-velocity`, `y-velocity`,
/// `z-velocity`; `velx`, `vely`, `velz`), in the order of their x components.
pub fn vector_fields(names: &[&str]) -> Vec<ColorBy> {
    let mut out: Vec<ColorBy> = Vec::new();
    for name in names {
        for (i, c) in name.char_indices() {
            let axes = match c {
                'x' => ['x', 'y', 'z'],
                'X' => ['X', 'Y', 'Z'],
                _ => continue,
            };
            let with = |a: char| format!("{}{a}{}", &name[..i], &name[i + 1..]);
            let [x, y, z] = axes.map(with);
            if names.contains(&y.as_str()) && names.contains(&z.as_str()) {
                let m = ColorBy::magnitude(&[&x, &y, &z]).expect("three names, none empty");
                if !out.contains(&m) {
                    out.push(m);
                }
            }
        }
    }
    out
}

impl fmt::Display for ColorBy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ColorBy::Field(name) | ColorBy::Magnitude { name, .. } => f.write_str(name),
            ColorBy::Level => f.write_str("level"),
        }
    }
}

/// What `painters` paint with besides the level (fields and magnitudes, by
/// [`ColorBy::painted_name`]), each once, in the order they first appear: one colour range each.
pub fn painting_fields<'a>(painters: impl IntoIterator<Item = &'a ColorBy>) -> Vec<&'a str> {
    let mut fields: Vec<&str> = Vec::new();
    for name in painters.into_iter().filter_map(ColorBy::painted_name) {
        if !fields.contains(&name) {
            fields.push(name);
        }
    }
    fields
}

impl FromStr for ColorBy {
    type Err = String;

    /// `level`, a field name, or the magnitude of fields between bars, `|vx,vy,vz|`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "" => Err("an empty field name".into()),
            "level" => Ok(ColorBy::Level),
            bars if bars.len() >= 2 && bars.starts_with('|') && bars.ends_with('|') => {
                let inner = &bars[1..bars.len() - 1];
                ColorBy::magnitude(&inner.split(',').map(str::trim).collect::<Vec<_>>())
            }
            name => Ok(ColorBy::Field(name.to_string())),
        }
    }
}

/// Percentiles of the values a frame shows that bound the default colour range.
pub const ROBUST_PERCENTILES: (f64, f64) = (0.01, 0.99);

/// How values become colours: one scale for every painted surface and slice of a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ColorScale {
    /// The colormap.
    pub colormap: Colormap,
    /// The values at the colormap's ends; `None` takes [`ROBUST_PERCENTILES`] of the values the
    /// frame shows.
    pub range: Option<(f64, f64)>,
    /// Map `log10` of the values (values at or below zero take the low end).
    pub log: bool,
}

impl ColorScale {
    /// Where `value` falls on the colormap for the range `(lo, hi)`: `0` at `lo`, `1` at `hi`.
    pub fn position(&self, value: f64, (lo, hi): (f64, f64)) -> f64 {
        let (v, lo, hi) = match self.log {
            true => (
                log_or_low(value, lo),
                log_or_low(lo, lo),
                log_or_low(hi, lo),
            ),
            false => (value, lo, hi),
        };
        if hi > lo {
            ((v - lo) / (hi - lo)).clamp(0.0, 1.0)
        } else {
            0.5
        }
    }

    /// The linear RGB colour of `value` over `range`.
    pub fn linear(&self, value: f64, range: (f64, f64)) -> [f32; 3] {
        self.colormap.linear(self.position(value, range))
    }

    /// Checks the range and the log scale.
    pub fn validate(&self) -> Result<(), String> {
        if let Some((lo, hi)) = self.range {
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return Err(format!(
                    "colour range {lo}:{hi} must be finite with LO < HI"
                ));
            }
            if self.log && lo <= 0.0 {
                return Err(format!(
                    "a log colour scale needs a positive range, not {lo}:{hi}"
                ));
            }
        }
        Ok(())
    }

    /// The range to paint `values` with: the given one, or the robust range of the finite
    /// values (positive ones for a log scale); `None` when there is none.
    pub fn resolve(&self, values: &mut [f32]) -> Option<(f64, f64)> {
        if let Some(r) = self.range {
            return Some(r);
        }
        robust_range(values, self.log)
    }
}

/// `log10(v)`, or `log10` of the smallest positive value `floor` allows when `v <= 0`.
fn log_or_low(v: f64, floor: f64) -> f64 {
    if v > 0.0 {
        v.log10()
    } else if floor > 0.0 {
        floor.log10()
    } else {
        f64::MIN_POSITIVE.log10()
    }
}

/// The [`ROBUST_PERCENTILES`] of the finite values of `values` (positive ones only when
/// `positive`), widened when they are equal; `None` without such values. Reorders `values`.
pub fn robust_range(values: &mut [f32], positive: bool) -> Option<(f64, f64)> {
    let mut v: Vec<f32> = values
        .iter()
        .copied()
        .filter(|x| x.is_finite() && (!positive || *x > 0.0))
        .collect();
    if v.is_empty() {
        return None;
    }
    v.sort_unstable_by(f32::total_cmp);
    let at = |q: f64| f64::from(v[((v.len() - 1) as f64 * q).round() as usize]);
    let (lo, hi) = (at(ROBUST_PERCENTILES.0), at(ROBUST_PERCENTILES.1));
    if hi > lo {
        return Some((lo, hi));
    }
    let pad = if lo == 0.0 { 1.0 } else { 1e-3 * lo.abs() };
    Some(match positive {
        true => (lo / (1.0 + 1e-3), hi * (1.0 + 1e-3)),
        false => (lo - pad, hi + pad),
    })
}

#[cfg(test)]
mod tests {

    #[test]
    fn a_magnitude_is_written_between_bars() {
        let m: ColorBy = " |x-velocity, y-velocity ,z-velocity| ".parse().unwrap();
        assert_eq!(m.to_string(), "|x-velocity,y-velocity,z-velocity|");
        assert_eq!(m.fields(), ["x-velocity", "y-velocity", "z-velocity"]);
        assert_eq!(m.to_string().parse::<ColorBy>().unwrap(), m);
        for bad in ["|vx|", "||", "|vx,,vy|", "|,vy|"] {
            let e = bad.parse::<ColorBy>().unwrap_err();
            assert!(
                e.contains("|x-velocity,y-velocity,z-velocity|"),
                "{bad}: {e}"
            );
        }
        assert_eq!(
            "Y(H)".parse::<ColorBy>().unwrap(),
            ColorBy::Field("Y(H)".into())
        );
        assert_eq!("|".parse::<ColorBy>().unwrap(), ColorBy::Field("|".into()));
        assert_eq!(painting_fields([&m, &ColorBy::Level, &m]), [m.to_string()]);
    }

    #[test]
    fn vectors_are_found_by_their_components_names() {
        let names = [
            "Density",
            "x-velocity",
            "y-velocity",
            "z-velocity",
            "magx",
            "magy",
            "magZ",
            "velX",
            "velY",
            "velZ",
            "xmom",
            "ymom",
        ];
        let found: Vec<String> = vector_fields(&names)
            .iter()
            .map(|m| m.to_string())
            .collect();
        assert_eq!(
            found,
            ["|x-velocity,y-velocity,z-velocity|", "|velX,velY,velZ|"]
        );
        assert!(vector_fields(&["x", "y"]).is_empty());
        assert_eq!(vector_fields(&["x", "y", "z"])[0].to_string(), "|x,y,z|");
    }

    use super::*;

    #[test]
    fn positions_run_over_the_range() {
        let s = ColorScale::default();
        assert_eq!(s.position(2.0, (2.0, 4.0)), 0.0);
        assert_eq!(s.position(3.0, (2.0, 4.0)), 0.5);
        assert_eq!(s.position(9.0, (2.0, 4.0)), 1.0);
        let log = ColorScale { log: true, ..s };
        assert!((log.position(10.0, (1.0, 100.0)) - 0.5).abs() < 1e-12);
        assert_eq!(log.position(-5.0, (1.0, 100.0)), 0.0);
    }

    #[test]
    fn robust_range_ignores_outliers() {
        let mut v: Vec<f32> = (0..1000).map(|i| i as f32).collect();
        v[0] = -1e30;
        v[999] = f32::NAN;
        let (lo, hi) = robust_range(&mut v, false).unwrap();
        assert!(
            (9.0..=11.0).contains(&lo) && (987.0..=989.0).contains(&hi),
            "{lo} {hi}"
        );
        assert_eq!(robust_range(&mut [f32::NAN], false), None);
        let (lo, hi) = robust_range(&mut [3.0, 3.0], false).unwrap();
        assert!(lo < 3.0 && hi > 3.0);
        assert!(ColorScale {
            range: Some((0.0, 1.0)),
            log: true,
            ..ColorScale::default()
        }
        .validate()
        .is_err());
    }
}
