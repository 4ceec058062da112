//! The colour a picture shows where no surface is: what a PNG picture is composited over, and
//! what the lines and labels drawn on it must stand out from.

use crate::colormap::srgb8_to_linear;
use crate::output::png_preview::display_srgb8;
use crate::shade::material::parse_css_srgb8;

/// A picture's background, kept as the linear radiance composited behind the frame before its
/// tone mapping, so that a surface's translucent edge blends into it as into the surfaces
/// behind it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Background {
    radiance: [f32; 3],
}

impl Default for Background {
    /// The neutral grey of every picture before backgrounds could be chosen (linear 0.18).
    fn default() -> Background {
        Background {
            radiance: [0.18; 3],
        }
    }
}

impl Background {
    /// The background a picture shows as the 8-bit sRGB colour `srgb8`: the tone mapping
    /// inverted, so that white shows as white.
    pub fn from_srgb8(srgb8: [u8; 3]) -> Background {
        let shown = srgb8_to_linear(srgb8);
        // The tone mapping shows radiance `v` as `v / (1 + v / 4)`: its inverse.
        Background {
            radiance: shown.map(|u| u / (1.0 - 0.25 * u)),
        }
    }

    /// The radiance composited behind the frame.
    pub fn radiance(&self) -> [f32; 3] {
        self.radiance
    }

    /// The 8-bit sRGB colour the picture shows.
    pub fn srgb8(&self) -> [u8; 3] {
        self.radiance.map(display_srgb8)
    }

    /// True for a light background (white, a pale colour), on which dark lines and text read.
    pub fn is_light(&self) -> bool {
        let [r, g, b] = srgb8_to_linear(self.srgb8());
        0.2126 * r + 0.7152 * g + 0.0722 * b > 0.3
    }

    /// The colour of the legend's text, tick marks and labels, of the edge under them that keeps
    /// them readable over a surface, and of the legend's panels: light text on dark panels over
    /// a dark background, dark text on light panels over a light one.
    pub fn ink(&self) -> Ink {
        match self.is_light() {
            true => Ink {
                fill: [25, 25, 25],
                edge: [255, 255, 255],
                panel: [250, 250, 250],
            },
            false => Ink {
                fill: [240, 240, 240],
                edge: [0, 0, 0],
                panel: [24, 24, 24],
            },
        }
    }

    /// The linear colour of the domain's outline: light grey on dark, dark grey on light.
    pub fn outline(&self) -> [f32; 3] {
        match self.is_light() {
            true => [0.03; 3],
            false => [0.75; 3],
        }
    }
}

impl std::str::FromStr for Background {
    type Err = String;

    /// A CSS colour (a name, `#rrggbb`, `rgb(r,g,b)`), which the picture then shows exactly:
    /// `white` is white and `black` black (not the muted shades `--iso` gives those names).
    fn from_str(s: &str) -> Result<Background, String> {
        Ok(Background::from_srgb8(parse_css_srgb8(s)?))
    }
}

/// Text or lines drawn on a picture: the colour, the one-pixel edge drawn under them, and the
/// panel behind the legend's parts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ink {
    /// The text's or line's colour, 8-bit sRGB.
    pub fill: [u8; 3],
    /// The edge under it, 8-bit sRGB.
    pub edge: [u8; 3],
    /// The panel under the legend's parts, 8-bit sRGB, blended in.
    pub panel: [u8; 3],
}

impl Default for Ink {
    /// The ink of the default background.
    fn default() -> Ink {
        Background::default().ink()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_background_shows_the_colour_asked_for() {
        for (name, want) in [
            ("white", [255, 255, 255]),
            ("black", [0, 0, 0]),
            ("#336699", [0x33, 0x66, 0x99]),
            ("rgb(250,240,230)", [250, 240, 230]),
        ] {
            let b: Background = name.parse().unwrap();
            assert_eq!(b.srgb8(), want, "{name}");
        }
        assert!("nocolour".parse::<Background>().is_err());
    }

    #[test]
    fn lines_and_text_stand_out_from_the_background() {
        let white: Background = "white".parse().unwrap();
        let grey = Background::default();
        assert!(white.is_light() && !grey.is_light());
        assert!(!"black".parse::<Background>().unwrap().is_light());
        assert!(white.ink().fill[0] < 64 && grey.ink().fill[0] > 192);
        assert!(white.outline()[0] < 0.1 && grey.outline()[0] > 0.5);
        // The default is the grey every picture had before: linear 0.18.
        assert_eq!(grey.radiance(), [0.18; 3]);
    }
}
