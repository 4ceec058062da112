//! Context lines: the domain's bounding box and the AMR boxes of each level, drawn into a frame as
//! thin lines that surfaces in front of them hide (tested against the frame's depth).

use std::str::FromStr;

use amr_format::AmrkFile;

use crate::camera::{dot, sub, Camera, Projection};
use crate::coloring::ColorBy;
use crate::colormap::{level_palette, oklab_distance, srgb8_to_linear};
use crate::output::background::Background;
use crate::output::frame::FrameBuffer;
use crate::output::png_preview::display_srgb8;
use crate::scene::Scene;

/// Which boxes a frame outlines.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Outline {
    /// None.
    #[default]
    None,
    /// The domain's bounding box.
    Domain,
    /// The domain and the boxes (bricks) of every level, coloured by level.
    Boxes,
}

impl FromStr for Outline {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "none" => Ok(Outline::None),
            "domain" => Ok(Outline::Domain),
            "boxes" => Ok(Outline::Boxes),
            _ => Err(format!("unknown outline '{s}' (none, domain, boxes)")),
        }
    }
}

/// Level colours closer than this (OKLab distance) to a surface's colour or the background are
/// not used for boxes: a reader would take the lines for the surface, or not see them.
const CONFUSABLE: f32 = 0.13;

/// The colour of each level's boxes in one frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LevelColors {
    /// 8-bit sRGB colours, level `l` taking entry `l % len`.
    palette: Vec<[u8; 3]>,
}

impl LevelColors {
    /// The categorical palette of levels, as surfaces painted by level use it.
    pub fn categorical() -> LevelColors {
        LevelColors {
            palette: level_palette().collect(),
        }
    }

    /// Colours for `levels` levels from the categorical palette without the colours a reader
    /// could confuse with one of `avoid` (8-bit sRGB). Telling levels apart comes first: the
    /// most confusable colours are left out only while at least `levels` colours remain (the
    /// whole palette when it has fewer).
    pub fn avoiding(avoid: &[[u8; 3]], levels: usize) -> LevelColors {
        let all: Vec<[u8; 3]> = level_palette().collect();
        let nearest = |c: [u8; 3]| {
            avoid
                .iter()
                .map(|&a| oklab_distance(c, a))
                .fold(f32::INFINITY, f32::min)
        };
        let mut confusable: Vec<(f32, usize)> = (0..all.len())
            .map(|i| (nearest(all[i]), i))
            .filter(|&(d, _)| d < CONFUSABLE)
            .collect();
        confusable.sort_by(|a, b| a.0.total_cmp(&b.0));
        let removable = all.len().saturating_sub(levels.max(1));
        let dropped: Vec<usize> = confusable.iter().take(removable).map(|&(_, i)| i).collect();
        let palette = (0..all.len())
            .filter(|i| !dropped.contains(i))
            .map(|i| all[i])
            .collect();
        LevelColors { palette }
    }

    /// The colours of a frame of `scene` over `background`: the categorical palette when
    /// something is painted by level (lines and surfaces then agree), else the palette clear of
    /// the background and of every unpainted surface's colour. A painting colormap is not
    /// avoided: it spans so many hues that too few colours would be left to tell the levels
    /// apart, and a thin line is not taken for a painted surface.
    pub fn of_scene(scene: &Scene, background: &Background) -> LevelColors {
        if scene.painters().any(|b| *b == ColorBy::Level) {
            return LevelColors::categorical();
        }
        let mut avoid = vec![background.srgb8()];
        for (i, s) in scene.isosurfaces().iter().enumerate() {
            if scene.color_by().get(i).is_none_or(Option::is_none) {
                avoid.push(s.color_or_palette(i).map(display_srgb8));
            }
        }
        LevelColors::avoiding(&avoid, scene.file().levels().len())
    }

    /// The 8-bit sRGB colour of `level`'s boxes.
    pub fn srgb8(&self, level: u32) -> [u8; 3] {
        self.palette[level as usize % self.palette.len()]
    }

    /// The linear RGB colour of `level`'s boxes.
    pub fn linear(&self, level: u32) -> [f32; 3] {
        srgb8_to_linear(self.srgb8(level))
    }
}

/// A world-space segment and its linear colour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// One end.
    pub a: [f64; 3],
    /// The other end.
    pub b: [f64; 3],
    /// Linear RGB.
    pub color: [f32; 3],
}

/// The 12 edges of the box `[lo, hi]`.
pub fn box_edges(lo: [f64; 3], hi: [f64; 3], color: [f32; 3]) -> impl Iterator<Item = Segment> {
    let corner = move |i: usize| [0, 1, 2].map(|a| if i >> a & 1 == 1 { hi[a] } else { lo[a] });
    (0..8usize).flat_map(move |i| {
        (0..3)
            .filter(move |a| i >> a & 1 == 0)
            .map(move |a| Segment {
                a: corner(i),
                b: corner(i | 1 << a),
                color,
            })
    })
}

/// The segments `outline` asks for in `file` whose domain is `[lo, hi]` (world): brick edges in
/// `colors`, finest level last, so that they draw over the coarser ones they share, and the
/// domain's edges in `domain` (linear).
pub fn segments<D: AsRef<[u8]>>(
    outline: Outline,
    file: &AmrkFile<D>,
    (lo, hi): ([f64; 3], [f64; 3]),
    (colors, domain): (&LevelColors, [f32; 3]),
) -> Vec<Segment> {
    let mut out = Vec::new();
    if outline == Outline::None {
        return out;
    }
    if outline == Outline::Boxes {
        let mut bricks: Vec<usize> = (0..file.num_bricks()).collect();
        bricks.sort_by_key(|&b| file.brick(b).level);
        for b in bricks {
            let info = file.brick(b);
            let Some(level) = file.levels().get(info.level as usize) else {
                continue;
            };
            let at =
                |i: [i64; 3]| [0, 1, 2].map(|a| level.origin[a] + i[a] as f64 * level.cell_size[a]);
            out.extend(box_edges(
                at(info.cells.lo),
                at(info.cells.hi),
                colors.linear(info.level),
            ));
        }
    }
    out.extend(box_edges(lo, hi, domain));
    out
}

/// Draws `segments` into `frame` seen by `camera`, `width` pixels wide: where nothing in the
/// frame is nearer the line's colour replaces the pixel's; behind the first surface it is blended
/// in by the light the surfaces let through (`1 - alpha`), so that lines show through transparent
/// surfaces and not through opaque ones.
pub fn draw(frame: &mut FrameBuffer, camera: &Camera, segments: &[Segment], width: u32) {
    let (w, h) = (frame.width, frame.height);
    let f = camera.forward();
    let (right, up) = camera.basis();
    // Half the picture's height at a unit's distance (perspective) or in world units.
    let (tan, parallel) = match camera.projection {
        Projection::Perspective => ((0.5 * camera.fov_deg).to_radians().tan(), false),
        Projection::Orthographic { height } => (0.5 * height, true),
    };
    let aspect = f64::from(w) / f64::from(h);
    // Where a point falls on the picture, and its distance along the ray that meets it there.
    let project = |p: [f64; 3]| -> Option<(f64, f64, f64)> {
        let v = sub(p, camera.pos);
        let depth = dot(v, f);
        if depth <= 1e-12 {
            return None;
        }
        let (scale, dist) = match parallel {
            true => (1.0, depth),
            false => (depth, dot(v, v).sqrt()),
        };
        let sx = dot(v, right) / scale / (tan * aspect);
        let sy = dot(v, up) / scale / tan;
        Some((
            (sx + 1.0) * 0.5 * f64::from(w),
            (1.0 - sy) * 0.5 * f64::from(h),
            dist,
        ))
    };
    let width = i64::from(width.max(1));
    let (lo, hi) = (-(width - 1) / 2, width / 2);
    for s in segments {
        let (Some(pa), Some(pb)) = (project(s.a), project(s.b)) else {
            continue;
        };
        let pixels = (pb.0 - pa.0).abs().max((pb.1 - pa.1).abs());
        let steps = (2.0 * pixels).ceil().clamp(1.0, 1e5) as usize;
        for k in 0..=steps {
            let u = k as f64 / steps as f64;
            let p = [0, 1, 2].map(|a| s.a[a] + u * (s.b[a] - s.a[a]));
            let Some((x, y, dist)) = project(p) else {
                continue;
            };
            for dy in lo..=hi {
                for dx in lo..=hi {
                    let (px, py) = (x.floor() as i64 + dx, y.floor() as i64 + dy);
                    if px < 0 || py < 0 || px >= i64::from(w) || py >= i64::from(h) {
                        continue;
                    }
                    let i = py as usize * w as usize + px as usize;
                    // Behind the first hit, a line shows through what the surfaces let through.
                    let seen = match f64::from(frame.z[i]) * (1.0 + 1e-5) < dist {
                        true => 1.0 - frame.alpha[i],
                        false => 1.0,
                    };
                    if seen <= 0.0 {
                        continue;
                    }
                    for c in 0..3 {
                        let v = &mut frame.rgb[c][i];
                        *v += (s.color[c] - *v) * seen;
                    }
                    frame.alpha[i] += (1.0 - frame.alpha[i]) * seen;
                }
            }
        }
    }
}

/// The line width for a `w x h` frame: one pixel up to 1000 pixels, wider above.
pub fn line_width(w: u32, h: u32) -> u32 {
    (w.max(h) / 1000).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::colormap::level_srgb8;

    #[test]
    fn level_colors_stay_clear_of_what_they_avoid() {
        let avoid = [level_srgb8(0), level_srgb8(1), [118, 118, 118]];
        let colors = LevelColors::avoiding(&avoid, 3);
        for l in 0..30 {
            for a in avoid {
                assert!(
                    oklab_distance(colors.srgb8(l), a) >= CONFUSABLE,
                    "level {l}"
                );
            }
        }
        assert_ne!(colors.srgb8(0), colors.srgb8(1));
    }

    #[test]
    fn levels_keep_distinct_colours_before_avoiding_any() {
        let all: Vec<[u8; 3]> = level_palette().collect();
        for levels in 1..=all.len() + 2 {
            let colors = LevelColors::avoiding(&all, levels);
            let distinct = levels.min(all.len());
            let used: std::collections::BTreeSet<[u8; 3]> =
                (0..distinct as u32).map(|l| colors.srgb8(l)).collect();
            assert_eq!(used.len(), distinct, "{levels} levels");
        }
        // The nearest colours go first: with room for nine, only the avoided grey goes.
        let grey = all[9];
        let colors = LevelColors::avoiding(&[grey, [0, 0, 255]], 9);
        assert!((0..9).all(|l| colors.srgb8(l) != grey));
        assert_eq!(LevelColors::avoiding(&[], 3), LevelColors::categorical());
    }

    #[test]
    fn a_box_has_twelve_edges_of_its_sides() {
        let e: Vec<Segment> = box_edges([0.0; 3], [1.0, 2.0, 3.0], [1.0; 3]).collect();
        assert_eq!(e.len(), 12);
        let total: f64 = e
            .iter()
            .map(|s| (0..3).map(|a| (s.b[a] - s.a[a]).abs()).sum::<f64>())
            .sum();
        assert_eq!(total, 4.0 * (1.0 + 2.0 + 3.0));
    }
}
