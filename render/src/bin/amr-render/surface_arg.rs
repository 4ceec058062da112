//! `--iso [FIELD=]V[:COLOR[:OPACITY]]`: an isosurface as typed, its field named and its value
//! a number or a percentile (not yet resolved: each file of a time series resolves the name to
//! its own field index, and a percentile to its own value).

use std::fmt;
use std::str::FromStr;

use amr_render::scene::field_named;
use amr_render::shade::IsoSpec;
use amr_render::Scene;

use crate::iso_value::IsoValue;

/// An isosurface of the command line: the field it is of (`None`: the scene's field), its
/// value, colour and opacity.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceArg {
    /// The field's name, as typed before `=`.
    pub field: Option<String>,
    /// The value as typed.
    pub value: IsoValue,
    /// Colour and opacity (its `value` that of a number typed, its `field` unset).
    pub spec: IsoSpec,
}

impl SurfaceArg {
    /// An isosurface of the scene's field.
    pub fn of_scene_field(spec: IsoSpec) -> Self {
        SurfaceArg {
            field: None,
            value: IsoValue::Number(spec.value),
            spec,
        }
    }

    /// The isosurface for `scene`: its field's name resolved in the scene's file, a percentile
    /// to that field's value there.
    pub fn resolve(&self, scene: &Scene) -> anyhow::Result<IsoSpec> {
        let field = match &self.field {
            None => None,
            Some(name) => {
                Some(field_named(scene.file(), name).map_err(|e| e.in_file(scene.path()))?)
            }
        };
        let field_index = field.unwrap_or(scene.field());
        let value = self
            .value
            .resolve(scene.file(), scene.path(), field_index)?;
        Ok(IsoSpec {
            field,
            value,
            ..self.spec
        })
    }
}

/// The field an argument names before `=` (`None` without one) and the rest: the form of
/// `--iso`, `--iso-sweep` and `--color-scale`, none of whose other parts holds an `=`.
pub fn split_field(s: &str) -> Result<(Option<String>, &str), String> {
    match s.split_once('=') {
        None => Ok((None, s)),
        Some((name, _)) if name.trim().is_empty() => {
            Err(format!("'{s}': no field name before '='"))
        }
        Some((name, rest)) => Ok((Some(name.trim().to_string()), rest)),
    }
}

impl FromStr for SurfaceArg {
    type Err = String;

    /// `V[:COLOR[:OPACITY]]`, or `FIELD=V[:COLOR[:OPACITY]]` for a surface of another field
    /// than `--field`; `V` a number or a percentile (`p99`).
    fn from_str(s: &str) -> Result<Self, String> {
        let (field, rest) = split_field(s)?;
        let (typed, style) = match rest.split_once(':') {
            Some((v, style)) => (v, format!(":{style}")),
            None => (rest, String::new()),
        };
        let value: IsoValue = typed.parse()?;
        Ok(SurfaceArg {
            field,
            value,
            spec: format!("{}{style}", value.typed_number()).parse()?,
        })
    }
}

impl fmt::Display for SurfaceArg {
    /// The form `FromStr` reads back.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(name) = &self.field {
            write!(f, "{name}=")?;
        }
        // The spec's colour and opacity after its value.
        let spec = self.spec.to_string();
        let style = spec.find(':').map_or("", |i| &spec[i..]);
        write!(f, "{}{style}", self.value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_field_before_the_value_is_read_and_written_back() {
        let a: SurfaceArg = "Y(OH)=1e-3:red:0.5".parse().unwrap();
        assert_eq!(a.field.as_deref(), Some("Y(OH)"));
        assert_eq!((a.spec.value, a.spec.opacity), (1e-3, 0.5));
        let again: SurfaceArg = a.to_string().parse().unwrap();
        assert_eq!(again.field, a.field);
        assert_eq!(again.spec.value, a.spec.value);
        let plain: SurfaceArg = "-60:red".parse().unwrap();
        assert_eq!((plain.field, plain.spec.value), (None, -60.0));
        assert!("=5".parse::<SurfaceArg>().is_err());
        assert!("temp=hot".parse::<SurfaceArg>().is_err());
        let p: SurfaceArg = "Y(OH)=p99.5:#3070ff:0.5".parse().unwrap();
        assert_eq!(p.value, IsoValue::Percentile(99.5));
        assert_eq!(p.spec.opacity, 0.5);
        assert_eq!(p.to_string(), "Y(OH)=p99.5:#3070ff:0.5");
        assert_eq!("p90".parse::<SurfaceArg>().unwrap().to_string(), "p90");
    }
}
