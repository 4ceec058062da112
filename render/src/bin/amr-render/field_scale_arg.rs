//! `--color-scale FIELD=[COLORMAP][:log|:linear][:LO:HI]`: a field painted with a colour scale
//! of its own, each part it leaves out taken from the frame's (`--colormap`, `--color-log`,
//! `--color-range`, else the range of the field's values in view).

use std::str::FromStr;

use amr_render::colormap::Colormap;
use amr_render::{ColorBy, ColorScale};

use crate::render_args::parse_range;
use crate::surface_arg::split_field;

/// A field's own colour scale, as typed.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldScaleArg {
    /// The field's name.
    pub field: String,
    /// Its colormap.
    pub colormap: Option<Colormap>,
    /// Logarithmic (`log`) or not (`linear`).
    pub log: Option<bool>,
    /// The values at the colormap's ends.
    pub range: Option<(f64, f64)>,
}

impl FieldScaleArg {
    /// The scale: what was typed, the rest from `frame`.
    pub fn scale(&self, frame: &ColorScale) -> ColorScale {
        ColorScale {
            colormap: self.colormap.unwrap_or(frame.colormap),
            range: self.range.or(frame.range),
            log: self.log.unwrap_or(frame.log),
        }
    }
}

impl FromStr for FieldScaleArg {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let (Some(field), rest) = split_field(s)? else {
            return Err(format!("'{s}' is not FIELD=[COLORMAP][:log][:LO:HI]"));
        };
        let mut parts: Vec<&str> = rest.split(':').map(str::trim).collect();
        // A range is the last two parts when both are numbers.
        let number = |p: &str| p.parse::<f64>().is_ok();
        let range = match parts.as_slice() {
            [.., a, b] if number(a) && number(b) => {
                let range = parse_range(&format!("{a}:{b}"))?;
                parts.truncate(parts.len() - 2);
                Some(range)
            }
            _ => None,
        };
        let (mut colormap, mut log) = (None, None);
        for p in parts.into_iter().filter(|p| !p.is_empty()) {
            match p {
                "log" => log = Some(true),
                "linear" => log = Some(false),
                name if colormap.is_none() => colormap = Some(name.parse::<Colormap>()?),
                other => return Err(format!("'{other}' in '{s}': a second colormap")),
            }
        }
        let scale = ColorScale {
            colormap: colormap.unwrap_or_default(),
            range,
            log: log.unwrap_or(false),
        };
        scale.validate().map_err(|e| format!("'{s}': {e}"))?;
        // A magnitude as its painter names it, however it is spaced: `| vx, vy |` is `|vx,vy|`.
        let field = match field.parse::<ColorBy>() {
            Ok(m @ ColorBy::Magnitude { .. }) => m.to_string(),
            _ => field,
        };
        Ok(FieldScaleArg {
            field,
            colormap,
            log,
            range,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_part_is_optional_and_read_in_any_order() {
        let a: FieldScaleArg = "Y(OH)=magma:log:1e-8:1e-3".parse().unwrap();
        assert_eq!(a.field, "Y(OH)");
        let m: FieldScaleArg = "| vx, vy |=magma".parse().unwrap();
        assert_eq!(m.field, "|vx,vy|");
        assert_eq!(a.colormap, Some(Colormap::Magma));
        assert_eq!((a.log, a.range), (Some(true), Some((1e-8, 1e-3))));
        let b: FieldScaleArg = "temp=:300:1600".parse().unwrap();
        assert_eq!(
            (b.colormap, b.log, b.range),
            (None, None, Some((300.0, 1600.0)))
        );
        let c: FieldScaleArg = "temp=linear:inferno".parse().unwrap();
        assert_eq!((c.colormap, c.log), (Some(Colormap::Inferno), Some(false)));
        let frame = ColorScale {
            colormap: Colormap::Cividis,
            range: Some((0.0, 1.0)),
            log: true,
        };
        let scale = b.scale(&frame);
        assert_eq!(scale.colormap, Colormap::Cividis);
        assert!(scale.log);
        assert_eq!(scale.range, Some((300.0, 1600.0)));
        assert_eq!(c.scale(&frame).range, Some((0.0, 1.0)), "the frame's range");
        for bad in [
            "temp",
            "=magma",
            "temp=nope",
            "temp=magma:viridis",
            "t=log:-1:1",
            "t=:2:1",
        ] {
            assert!(bad.parse::<FieldScaleArg>().is_err(), "{bad}");
        }
    }
}
