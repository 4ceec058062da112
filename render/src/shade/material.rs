//! Isosurface specifications from the command line: `V[:COLOR[:OPACITY]]`.

use std::str::FromStr;

/// One isosurface to render: isovalue, colour, opacity, and the field it is of.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IsoSpec {
    /// The isovalue.
    pub value: f32,
    /// Linear RGB colour, or `None` for the palette's colour at the surface's position.
    pub color: Option<[f32; 3]>,
    /// Opacity in `[0, 1]`; 1 is opaque.
    pub opacity: f32,
    /// The index of the field (in the file) the surface is of; `None`: the scene's field. The
    /// text form does not hold it: the command line reads a field's name before `=`.
    pub field: Option<usize>,
}

/// Colours given to isosurfaces without one, in order.
pub const PALETTE: [[f32; 3]; 6] = [
    [0.85, 0.62, 0.35],
    [0.35, 0.55, 0.85],
    [0.45, 0.75, 0.40],
    [0.80, 0.35, 0.40],
    [0.65, 0.50, 0.80],
    [0.80, 0.80, 0.80],
];

const NAMED: [(&str, [f32; 3]); 12] = [
    ("white", [1.0, 1.0, 1.0]),
    ("grey", [0.5, 0.5, 0.5]),
    ("gray", [0.5, 0.5, 0.5]),
    ("black", [0.02, 0.02, 0.02]),
    ("red", [0.85, 0.15, 0.12]),
    ("green", [0.2, 0.7, 0.25]),
    ("blue", [0.15, 0.3, 0.85]),
    ("yellow", [0.9, 0.8, 0.2]),
    ("orange", [0.95, 0.5, 0.1]),
    ("cyan", [0.2, 0.75, 0.8]),
    ("magenta", [0.8, 0.2, 0.7]),
    ("gold", [0.85, 0.65, 0.25]),
];

impl IsoSpec {
    /// An opaque isosurface at `value` with the palette's colour.
    pub fn new(value: f32) -> IsoSpec {
        IsoSpec {
            value,
            color: None,
            opacity: 1.0,
            field: None,
        }
    }

    /// The colour to shade with: the given one, or the palette's `index`-th.
    pub fn color_or_palette(&self, index: usize) -> [f32; 3] {
        self.color.unwrap_or(PALETTE[index % PALETTE.len()])
    }
}

impl std::fmt::Display for IsoSpec {
    /// The form `FromStr` reads back: `V`, `V:#rrggbb` or `V:#rrggbb:OPACITY` (sRGB hex of the
    /// linear colour, so a named colour reads back within 1/255).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.value)?;
        if let Some(c) = self.color {
            let hex = c.map(|v| (linear_to_srgb(v) * 255.0).round().clamp(0.0, 255.0) as u8);
            write!(f, ":#{:02x}{:02x}{:02x}", hex[0], hex[1], hex[2])?;
        }
        if self.opacity != 1.0 {
            if self.color.is_none() {
                f.write_str(":")?;
            }
            write!(f, ":{}", self.opacity)?;
        }
        Ok(())
    }
}

/// Parses a colour (returned linear): one of the muted shading colours above by name (`red`,
/// `gold`, ...), else any CSS colour (`steelblue`, `#4080ff`, `#48f`, `rgb(64,128,255)`,
/// `hsl(...)`) or bare hex `rrggbb`.
pub fn parse_color(s: &str) -> Result<[f32; 3], String> {
    let lower = s.trim().to_ascii_lowercase();
    if let Some((_, c)) = NAMED.iter().find(|(n, _)| *n == lower) {
        return Ok(*c);
    }
    let [r, g, b, _] = parse_css(s)?.to_linear_rgba();
    Ok([r, g, b])
}

/// Parses a CSS colour exactly as CSS defines it (`black` is black, not the muted shading
/// colour [`parse_color`] gives), `#rrggbb`, `rgb(...)`, or bare hex `rrggbb`: 8-bit sRGB.
pub fn parse_css_srgb8(s: &str) -> Result<[u8; 3], String> {
    let [r, g, b, _] = parse_css(s)?.to_rgba8();
    Ok([r, g, b])
}

fn parse_css(s: &str) -> Result<csscolorparser::Color, String> {
    let lower = s.trim().to_ascii_lowercase();
    let bare_hex = lower.len() == 6 && lower.chars().all(|c| c.is_ascii_hexdigit());
    let css = if bare_hex { format!("#{lower}") } else { lower };
    csscolorparser::parse(&css).map_err(|e| {
        format!("unknown colour '{s}' ({e}): use a CSS colour name, #rrggbb or rgb(r,g,b)")
    })
}

/// The 8-bit sRGB of linear RGB `c`.
pub fn srgb8(c: [f32; 3]) -> [u8; 3] {
    let [r, g, b, _] = csscolorparser::Color::from_linear_rgba(c[0], c[1], c[2], 1.0).to_rgba8();
    [r, g, b]
}

fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

impl FromStr for IsoSpec {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let mut parts = s.splitn(3, ':');
        let v = parts.next().unwrap_or("");
        let value: f32 = v
            .trim()
            .parse()
            .map_err(|_| format!("isovalue '{v}' in '{s}' is not a number"))?;
        if !value.is_finite() {
            return Err(format!("isovalue '{v}' is not finite"));
        }
        let color = match parts.next() {
            Some(c) if !c.is_empty() => Some(parse_color(c)?),
            _ => None,
        };
        let opacity = match parts.next() {
            Some(o) => o
                .trim()
                .parse::<f32>()
                .map_err(|_| format!("opacity '{o}' in '{s}' is not a number"))?,
            None => 1.0,
        };
        if !(0.0..=1.0).contains(&opacity) {
            return Err(format!("opacity {opacity} in '{s}' is outside [0, 1]"));
        }
        Ok(IsoSpec {
            value,
            color,
            opacity,
            field: None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_text_form_reads_back() {
        for text in ["-60", "0.5:#3070ff", "10:#d99e59:0.3", "2::0.5"] {
            let spec: IsoSpec = text.parse().unwrap();
            let again: IsoSpec = spec.to_string().parse().unwrap();
            assert_eq!(again.value, spec.value, "{text}");
            assert_eq!(again.opacity, spec.opacity, "{text}");
            for (a, b) in again
                .color
                .unwrap_or_default()
                .iter()
                .zip(spec.color.unwrap_or_default())
            {
                assert!((a - b).abs() < 1e-3, "{text}: {again:?} {spec:?}");
            }
        }
    }

    #[test]
    fn parses_iso_specs() {
        assert_eq!("0.5".parse::<IsoSpec>().unwrap(), IsoSpec::new(0.5));
        let s: IsoSpec = "-2:red:0.3".parse().unwrap();
        assert_eq!((s.value, s.opacity), (-2.0, 0.3));
        assert_eq!(s.color, Some([0.85, 0.15, 0.12]));
        let s: IsoSpec = "1e3:#ffffff".parse().unwrap();
        assert!((s.color.unwrap()[0] - 1.0).abs() < 1e-6);
        assert!("x".parse::<IsoSpec>().is_err());
        assert!("1:nocolour".parse::<IsoSpec>().is_err());
        let s: IsoSpec = "-60:steelblue".parse().unwrap();
        assert_eq!(s.to_string(), "-60:#4682b4");
        assert_eq!(parse_color("rgb(255, 0, 0)").unwrap(), [1.0, 0.0, 0.0]);
        assert!("1:red:2".parse::<IsoSpec>().is_err());
        assert!("nan".parse::<IsoSpec>().is_err());
    }
}
