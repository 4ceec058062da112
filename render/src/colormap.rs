//! Named colormaps for values (viridis, magma, ..., coolwarm, grey) and the categorical palette of
//! AMR levels, taken from the `colorous` crate (the d3-scale-chromatic tables): no hand-typed
//! tables here.

use std::fmt;
use std::str::FromStr;
use std::sync::LazyLock;

/// A colormap from values in `[0, 1]` to colours.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Colormap {
    /// Perceptually uniform, blue to yellow (matplotlib's default).
    #[default]
    Viridis,
    /// Perceptually uniform, black to light yellow through magenta.
    Magma,
    /// Perceptually uniform, black to yellow through red.
    Inferno,
    /// Perceptually uniform, blue to yellow through magenta.
    Plasma,
    /// Viridis made readable with colour-vision deficiencies.
    Cividis,
    /// Google's improved rainbow.
    Turbo,
    /// Diverging blue to red through white (ColorBrewer's RdBu, reversed): for signed fields.
    Coolwarm,
    /// Black to white.
    Grey,
}

impl Colormap {
    /// Every colormap, in the order the command line lists them.
    pub const ALL: [Colormap; 8] = [
        Colormap::Viridis,
        Colormap::Magma,
        Colormap::Inferno,
        Colormap::Plasma,
        Colormap::Cividis,
        Colormap::Turbo,
        Colormap::Coolwarm,
        Colormap::Grey,
    ];

    /// The name used on command lines and in file headers.
    pub fn name(self) -> &'static str {
        match self {
            Colormap::Viridis => "viridis",
            Colormap::Magma => "magma",
            Colormap::Inferno => "inferno",
            Colormap::Plasma => "plasma",
            Colormap::Cividis => "cividis",
            Colormap::Turbo => "turbo",
            Colormap::Coolwarm => "coolwarm",
            Colormap::Grey => "grey",
        }
    }

    /// The 8-bit sRGB colour at `t` (clamped to `[0, 1]`; NaN maps to 0).
    pub fn srgb8(self, t: f64) -> [u8; 3] {
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        let c = match self {
            Colormap::Viridis => colorous::VIRIDIS.eval_continuous(t),
            Colormap::Magma => colorous::MAGMA.eval_continuous(t),
            Colormap::Inferno => colorous::INFERNO.eval_continuous(t),
            Colormap::Plasma => colorous::PLASMA.eval_continuous(t),
            Colormap::Cividis => colorous::CIVIDIS.eval_continuous(t),
            Colormap::Turbo => colorous::TURBO.eval_continuous(t),
            Colormap::Coolwarm => colorous::RED_BLUE.eval_continuous(1.0 - t),
            Colormap::Grey => colorous::GREYS.eval_continuous(1.0 - t),
        };
        [c.r, c.g, c.b]
    }

    /// The linear RGB colour at `t`, for shading.
    pub fn linear(self, t: f64) -> [f32; 3] {
        srgb8_to_linear(self.srgb8(t))
    }
}

/// The categorical palette of AMR levels (Tableau 10), as 8-bit sRGB.
pub fn level_palette() -> impl Iterator<Item = [u8; 3]> {
    colorous::TABLEAU10.iter().map(|c| [c.r, c.g, c.b])
}

/// The 8-bit sRGB colour of AMR level `level` (Tableau 10, repeating after ten levels).
pub fn level_srgb8(level: u32) -> [u8; 3] {
    let c = colorous::TABLEAU10[level as usize % colorous::TABLEAU10.len()];
    [c.r, c.g, c.b]
}

/// The linear RGB colour of AMR level `level`.
pub fn level_linear(level: u32) -> [f32; 3] {
    srgb8_to_linear(level_srgb8(level))
}

/// The distance of two 8-bit sRGB colours in OKLab, a perceptually uniform space: about 0.02 is
/// barely visible, 0.1 a plain difference of hue or lightness.
pub fn oklab_distance(a: [u8; 3], b: [u8; 3]) -> f32 {
    let lab = |c: [u8; 3]| csscolorparser::Color::from_rgba8(c[0], c[1], c[2], 255).to_oklaba();
    let (a, b) = (lab(a), lab(b));
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f32>().sqrt()
}

/// Linear RGB of an 8-bit sRGB colour.
pub fn srgb8_to_linear(c: [u8; 3]) -> [f32; 3] {
    // Every hit painted by data converts its colour: a table, not three `powf`s.
    static LINEAR: LazyLock<[f32; 256]> = LazyLock::new(|| {
        std::array::from_fn(|v| {
            let s = v as f32 / 255.0;
            if s <= 0.04045 {
                s / 12.92
            } else {
                ((s + 0.055) / 1.055).powf(2.4)
            }
        })
    });
    c.map(|v| LINEAR[usize::from(v)])
}

impl fmt::Display for Colormap {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Colormap {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let lower = s.trim().to_ascii_lowercase();
        let lower = if lower == "gray" {
            "grey".to_string()
        } else {
            lower
        };
        Colormap::ALL
            .into_iter()
            .find(|c| c.name() == lower)
            .ok_or_else(|| {
                let names: Vec<&str> = Colormap::ALL.iter().map(|c| c.name()).collect();
                format!("unknown colormap '{s}' ({})", names.join(", "))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maps_run_from_their_documented_ends() {
        assert_eq!(Colormap::Grey.srgb8(0.0), [0, 0, 0]);
        assert_eq!(Colormap::Grey.srgb8(1.0), [255, 255, 255]);
        let lo = Colormap::Coolwarm.srgb8(0.0);
        let hi = Colormap::Coolwarm.srgb8(1.0);
        assert!(
            lo[2] > lo[0] && hi[0] > hi[2],
            "coolwarm is blue to red: {lo:?} {hi:?}"
        );
        assert_eq!(Colormap::Viridis.srgb8(-1.0), Colormap::Viridis.srgb8(0.0));
        for c in Colormap::ALL {
            assert_eq!(c.name().parse::<Colormap>(), Ok(c));
        }
        assert!("jet".parse::<Colormap>().is_err());
        assert_ne!(level_srgb8(0), level_srgb8(1));
    }
}
