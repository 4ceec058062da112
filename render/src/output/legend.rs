//! The preview's legend, drawn into its 8-bit sRGB pixels: the colour bar with tick labels and
//! the painting field's name (or the level palette), the isovalues with their colours, an
//! axis triad, and coordinates along the domain's box, laid out to fit the picture (drawn with
//! `canvas`).

use super::axes::{axis_labels, draw_axis_labels, PixelBox};
use super::background::Ink;
use super::canvas::{Canvas, Text};
use crate::camera::Camera;
use crate::coloring::ColorBy;
use crate::colormap::{level_srgb8, Colormap};
use crate::field_stats::{distinct_labels, format_isovalue, format_value, format_vector};
use crate::outline::{LevelColors, Outline};
use crate::reconstruct::Reconstruction;
use crate::render::Rendered;
use crate::scene::{Scene, TraceMethod};
use crate::shade::material::srgb8;
use crate::view::View;

/// A colour bar: the colormap over a range, titled by what it shows.
#[derive(Clone, Debug, PartialEq)]
pub struct ColorBar {
    /// What the colours show (a field's name).
    pub title: String,
    /// The colormap.
    pub colormap: Colormap,
    /// The values at its ends.
    pub range: (f64, f64),
    /// Logarithmic.
    pub log: bool,
    /// Whether the frame holds values below the low end and above the high end, drawn in the
    /// ends' colours: the bar then ends in a pointed cap on that side, as matplotlib's
    /// `extend` draws it, so that a saturated colour is not read as the end's value.
    pub beyond: (bool, bool),
}

/// The mark beside a legend line, in 8-bit sRGB.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Swatch {
    /// A filled square: the colour of a surface.
    Patch([u8; 3]),
    /// A short stroke: the colour of lines drawn in the frame.
    Stroke([u8; 3]),
}

/// Everything a legend shows; absent parts are left out.
#[derive(Clone, Debug, Default)]
pub struct Legend {
    /// Lines at the top left, each with its swatch (`None`: no swatch).
    pub entries: Vec<(String, Option<Swatch>)>,
    /// The colour bars of the fields that paint, top to bottom on the right side.
    pub color_bars: Vec<ColorBar>,
    /// The levels whose palette swatches stand on the right side, ascending.
    pub levels: Vec<u32>,
    /// The camera, for the axis triad.
    pub camera: Option<Camera>,
    /// The world box whose edges carry coordinate labels (the domain, when its outline is
    /// drawn); they go where the other parts leave room.
    pub axes: Option<([f64; 3], [f64; 3])>,
    /// The ink of what is drawn on the picture itself rather than on a panel (coordinate
    /// labels, the triad's names): the background's ([`Background::ink`]).
    pub ink: Ink,
}

/// Lines of text are this many text sizes apart.
const LINE: f32 = 1.3;

/// The smallest text a legend is drawn with, in pixels: DejaVu Sans still reads at 8.
pub const MIN_TEXT_PX: f32 = 8.0;

/// The largest share of a picture a legend's parts may cover.
pub const MAX_COVER: f32 = 1.0 / 3.0;

impl Legend {
    /// The legend of `rendered`, a frame of `scene` seen through `view`.
    pub fn of_frame(scene: &Scene, view: &View, rendered: &Rendered) -> Legend {
        let mut entries = Vec::new();
        if let Some(when) = simulation_stamp(
            scene.file().simulation_time(),
            scene.file().simulation_step(),
        ) {
            entries.push((when, None));
        }
        for (i, s) in scene.isosurfaces().iter().enumerate() {
            let field = scene.surface_field_name(s);
            let painted = scene.color_by().get(i).cloned().flatten();
            let opacity = match s.opacity < 1.0 {
                true => format!(" (opacity {})", s.opacity),
                false => String::new(),
            };
            let (label, swatch) = match painted {
                Some(by) => (
                    format!(
                        "{field} = {}, coloured by {by}{opacity}",
                        format_isovalue(s.value)
                    ),
                    None,
                ),
                None => (
                    format!("{field} = {}{opacity}", format_isovalue(s.value)),
                    Some(Swatch::Patch(srgb8(s.color_or_palette(i)))),
                ),
            };
            entries.push((label, swatch));
        }
        if let Some(how) = how_surfaces_were_made(scene) {
            entries.push((how, None));
        }
        if let (Some(c), false) = (scene.clip(), scene.isosurfaces().is_empty()) {
            entries.push((
                format!(
                    "surfaces cut to {} .. {}",
                    format_vector(c.lo),
                    format_vector(c.hi)
                ),
                None,
            ));
        }
        for (s, by) in scene.slices() {
            let p = s.point.map(format_value);
            entries.push((
                format!(
                    "slice through ({}, {}, {}) coloured by {by}",
                    p[0], p[1], p[2]
                ),
                None,
            ));
        }
        if view.outline == Outline::Boxes {
            let colors = LevelColors::of_scene(scene, &view.background);
            for l in 0..scene.file().levels().len() as u32 {
                let swatch = Swatch::Stroke(colors.srgb8(l));
                entries.push((format!("level {l} boxes"), Some(swatch)));
            }
        }
        let by_level = scene.painters().any(|b| *b == ColorBy::Level);
        // With levels painted too, a pixel whose value is its level was painted by level.
        let level_channel = by_level.then_some(rendered.frame.level.as_slice());
        let one_field = rendered.color_ranges.len() == 1;
        let color_bars: Vec<ColorBar> = rendered
            .color_ranges
            .iter()
            .map(|r| ColorBar {
                title: r.field.clone(),
                colormap: r.scale.colormap,
                range: r.range,
                log: r.scale.log,
                // One field: every painted pixel of the frame is its. Several share the
                // `color_value` channel, so each bar tells what its field's pre-pass saw.
                beyond: match one_field {
                    true => values_beyond(&rendered.frame.color_value, level_channel, r.range),
                    false => r.beyond,
                },
            })
            .collect();
        // The levels painted into the frame; every level of the file when that was not recorded.
        let mut levels = match (by_level, &rendered.painted_levels) {
            (false, _) => Vec::new(),
            (true, Some(painted)) => painted.clone(),
            (true, None) => (0..scene.file().levels().len() as u32).collect(),
        };
        if !color_bars.is_empty() {
            // The colour bar takes the right side: the level palette joins the list.
            let palette = levels
                .drain(..)
                .map(|l| (format!("level {l}"), Some(Swatch::Patch(level_srgb8(l)))));
            entries.extend(palette);
        }
        Legend {
            entries,
            color_bars,
            levels,
            camera: Some(rendered.camera),
            axes: (view.outline != Outline::None).then(|| scene.grid_frame().world_bounds()),
            ink: view.background.ink(),
        }
    }

    /// Draws the legend into `rgb` (`w x h` RGB8, row-major) at the largest text size from
    /// `h / 40` down to [`MIN_TEXT_PX`] at which its parts fit (see [`Legend::fits`]), the axis
    /// triad left out before the text shrinks; draws nothing and returns false when none does.
    pub fn draw(&self, rgb: &mut [u8], w: u32, h: u32) -> bool {
        let Some((text, triad)) = self.layout(w, h) else {
            return false;
        };
        let px = text.px;
        let mut canvas = Canvas { rgb, w, h };
        let m = px;
        let line = px * 1.3;
        let swatch_w = px * 1.2;
        if !self.entries.is_empty() {
            let (x0, y0, x1, y1) = self.entries_box(&text);
            canvas.panel((x0, y0), (x1, y1), px * 0.4, self.ink);
        }
        for (k, (s, swatch)) in self.entries.iter().enumerate() {
            let y = m + k as f32 * line;
            let mut x = m;
            let side = (0.8 * px) as i64;
            match swatch {
                Some(Swatch::Patch(c)) => {
                    canvas.rect(
                        x as i64 - 1,
                        y as i64 + 1,
                        side + 2,
                        side + 2,
                        [0, 0, 0],
                        1.0,
                    );
                    canvas.rect(x as i64, y as i64 + 2, side, side, *c, 1.0);
                }
                Some(Swatch::Stroke(c)) => {
                    let thick = (side / 5).max(2);
                    let y0 = y as i64 + 2 + (side - thick) / 2;
                    canvas.rect(x as i64 - 1, y0 - 1, side + 2, thick + 2, [0, 0, 0], 1.0);
                    canvas.rect(x as i64, y0, side, thick, *c, 1.0);
                }
                None => {}
            }
            if swatch.is_some() {
                x += swatch_w;
            }
            text.draw(&mut canvas, s, x, y, self.ink);
        }
        if !self.color_bars.is_empty() {
            let left = self.bars_left(&text, w as f32);
            for (k, bar) in self.color_bars.iter().enumerate() {
                let span = self.bar_span(&text, (w as f32, h as f32), k);
                self.draw_bar(&mut canvas, &text, bar, left, span);
            }
        } else if !self.levels.is_empty() {
            let (x, y0, x1, y1) = self.levels_box(&text, w as f32);
            canvas.panel((x, y0), (x1, y1), px * 0.4, self.ink);
            for (k, &l) in self.levels.iter().enumerate() {
                let y = m + k as f32 * line;
                let side = (0.8 * px) as i64;
                canvas.rect(x as i64, y as i64 + 2, side, side, level_srgb8(l), 1.0);
                text.draw(
                    &mut canvas,
                    &format!("level {l}"),
                    x + swatch_w,
                    y,
                    self.ink,
                );
            }
        }
        if let (Some(camera), true) = (&self.camera, triad) {
            draw_triad(&mut canvas, &text, camera, m, self.ink);
        }
        if let (Some(camera), Some(bounds)) = (&self.camera, self.axes) {
            let taken = self.parts(&text, w as f32, h as f32, triad);
            let labels = axis_labels(camera, bounds, (w, h), &text, &taken);
            draw_axis_labels(&mut canvas, &text, &labels, self.ink);
        }
        true
    }

    /// Whether the legend has room in a `w x h` picture at some text size of at least
    /// [`MIN_TEXT_PX`]: every part inside the frame, no two overlapping, a colour bar's tick labels
    /// apart, and all of them together covering at most [`MAX_COVER`] of the picture.
    pub fn fits(&self, w: u32, h: u32) -> bool {
        self.layout(w, h).is_some()
    }

    /// The smallest picture of `w x h`'s shape, enlarged by steps of a quarter up to 16 times,
    /// in which the legend fits; `None` when none of those does.
    pub fn smallest_fitting_size(&self, (w, h): (u32, u32)) -> Option<(u32, u32)> {
        (0..=60)
            .map(|k| 1.0 + 0.25 * f64::from(k))
            .map(|s| {
                let scale = |n: u32| (f64::from(n) * s).round() as u32;
                (scale(w), scale(h))
            })
            .find(|&(w, h)| self.fits(w, h))
    }

    /// The text and whether the triad is drawn: the largest size from the nominal `h / 40`
    /// (10 to 28 px) down to [`MIN_TEXT_PX`] at which the legend fits, with its triad if it
    /// fits so, else without.
    fn layout(&self, w: u32, h: u32) -> Option<(Text, bool)> {
        let nominal = (h as f32 / 40.0).clamp(10.0, 28.0);
        let sizes = (0..).map(|k| nominal - k as f32);
        for px in sizes.take_while(|px| *px >= MIN_TEXT_PX) {
            let text = Text::new(px)?;
            for triad in [true, false] {
                if self.has_room(&text, w as f32, h as f32, triad) {
                    return Some((text, triad));
                }
            }
        }
        None
    }

    /// The boxes the parts take in a `w x h` picture when drawn with `text`, panels' margins
    /// included (the triad's when `triad`).
    fn parts(&self, text: &Text, w: f32, h: f32, triad: bool) -> Vec<PixelBox> {
        let px = text.px;
        let mut parts: Vec<PixelBox> = Vec::new();
        if !self.entries.is_empty() {
            parts.push(self.entries_box(text));
        }
        if !self.color_bars.is_empty() {
            let left = self.bars_left(text, w);
            for k in 0..self.color_bars.len() {
                let (top, bottom) = self.bar_span(text, (w, h), k);
                let title = title_height(text, &self.color_bars[k], w);
                parts.push((left, top - title, w - px, bottom + px * 0.6));
            }
        } else if !self.levels.is_empty() {
            parts.push(self.levels_box(text, w));
        }
        let pad = px * 0.4;
        let mut parts: Vec<_> = parts
            .into_iter()
            .map(|(x0, y0, x1, y1)| (x0 - pad, y0 - pad, x1 + pad, y1 + pad))
            .collect();
        if let (Some(_), true) = (&self.camera, triad) {
            parts.push(triad_box(w, h, px));
        }
        parts
    }

    /// Whether the parts, drawn with `text`, fit a `w x h` picture (see [`Legend::fits`]).
    fn has_room(&self, text: &Text, w: f32, h: f32, triad: bool) -> bool {
        for k in 0..self.color_bars.len() {
            let (top, bottom) = self.bar_span(text, (w, h), k);
            let bar = &self.color_bars[k];
            if bottom <= top || bar_ticks(bar, text, (top, bottom), w).is_none() {
                return false;
            }
        }
        let parts = self.parts(text, w, h, triad);
        let inside = |b: &(f32, f32, f32, f32)| b.0 >= 0.0 && b.1 >= 0.0 && b.2 <= w && b.3 <= h;
        let apart = |a: &(f32, f32, f32, f32), b: &(f32, f32, f32, f32)| {
            a.2 <= b.0 || b.2 <= a.0 || a.3 <= b.1 || b.3 <= a.1
        };
        let covered: f32 = parts.iter().map(|b| (b.2 - b.0) * (b.3 - b.1)).sum();
        parts.iter().all(inside)
            && (0..parts.len()).all(|i| (i + 1..parts.len()).all(|j| apart(&parts[i], &parts[j])))
            && covered <= MAX_COVER * w * h
    }

    /// The box of the lines at the top left, without the panel's margin.
    fn entries_box(&self, text: &Text) -> (f32, f32, f32, f32) {
        let px = text.px;
        let swatch_w = px * 1.2;
        let width = self
            .entries
            .iter()
            .map(|(s, sw)| text.width(s) + if sw.is_some() { swatch_w } else { 0.0 })
            .fold(0.0, f32::max);
        (px, px, px + width, list_bottom(px, self.entries.len()))
    }

    /// The box of the level palette on the right side (drawn when no colour bar takes it),
    /// without the panel's margin; its left edge is where the swatches start.
    fn levels_box(&self, text: &Text, w: f32) -> (f32, f32, f32, f32) {
        let px = text.px;
        let tw = self
            .levels
            .iter()
            .map(|l| text.width(&format!("level {l}")))
            .fold(0.0, f32::max);
        let x = w - px - tw - px * 1.2;
        (x, px, w - px, list_bottom(px, self.levels.len()))
    }

    /// One left edge for every colour bar, so that their panels line up.
    fn bars_left(&self, text: &Text, w: f32) -> f32 {
        self.color_bars
            .iter()
            .map(|b| bar_left(text, b, w))
            .fold(f32::INFINITY, f32::min)
    }

    /// The heights between which colour bar `k` is drawn in a `w x h` picture: the bars share
    /// the right side's span from a fifth of the height to four fifths, each below its title
    /// (one line or more).
    fn bar_span(&self, text: &Text, (w, h): (f32, f32), k: usize) -> (f32, f32) {
        let n = self.color_bars.len() as f32;
        let (top, bottom) = (h * 0.2, h * 0.8);
        let line = text.px * LINE;
        // Above each bar after the first: the bar's title and the space the first one has.
        let gap = |j: usize| {
            let lines = title_lines(text, &self.color_bars[j], w).len() as f32;
            text.px * 4.0 + (lines - 1.0) * line
        };
        let gaps: f32 = (1..self.color_bars.len()).map(gap).sum();
        let each = (bottom - top - gaps) / n;
        let y0 = top + k as f32 * each + (1..=k).map(gap).sum::<f32>();
        (y0, y0 + each)
    }

    /// Draws `bar` on the right side from `x0` (its [`bar_left`], or further left) between
    /// heights `top` and `bottom`, its title above.
    fn draw_bar(
        &self,
        canvas: &mut Canvas<'_>,
        text: &Text,
        bar: &ColorBar,
        x0: f32,
        (top, bottom): (f32, f32),
    ) {
        let w = canvas.w as f32;
        let px = text.px;
        let Some(BarTicks { y0, y1, labels }) = bar_ticks(bar, text, (top, bottom), w) else {
            return;
        };
        let bar_w = bar_width(w);
        let right = w - px;
        let title_top = top - title_height(text, bar, w);
        canvas.panel(
            (x0, title_top),
            (right, bottom + px * 0.6),
            px * 0.4,
            self.ink,
        );
        for (k, line) in title_lines(text, bar, w).iter().enumerate() {
            text.draw(canvas, line, x0, title_top + k as f32 * px * LINE, self.ink);
        }
        let cap = bar_w.round() as i64;
        canvas.rect(
            x0 as i64 - 1,
            y0 as i64 - 1,
            bar_w as i64 + 2,
            (y1 - y0) as i64 + 2,
            [0, 0, 0],
            1.0,
        );
        for y in y0 as i64..y1 as i64 {
            let t = f64::from((y1 - y as f32) / (y1 - y0));
            canvas.rect(x0 as i64, y, bar_w as i64, 1, bar.colormap.srgb8(t), 1.0);
        }
        for (beyond, base, step, t) in [
            (bar.beyond.1, y0 as i64 - 1, -1, 1.0),
            (bar.beyond.0, y1 as i64 + 1, 1, 0.0),
        ] {
            if beyond {
                canvas.cap((x0 as i64 - 1, base), cap + 2, step, bar.colormap.srgb8(t));
            }
        }
        for (y, s) in labels {
            canvas.rect(
                (x0 + bar_w) as i64,
                y as i64,
                (px * 0.3) as i64,
                1,
                self.ink.fill,
                1.0,
            );
            text.draw(canvas, &s, x0 + bar_w + px * 0.5, y - px * 0.6, self.ink);
        }
    }
}

/// The bottom of a list of `n` lines in text of `px` pixels drawn from the top margin: the last
/// line's top plus its height.
fn list_bottom(px: f32, n: usize) -> f32 {
    px + (n as f32 - 1.0) * px * 1.3 + px * 1.2
}

/// The width of a colour bar's colours in a frame `w` wide.
fn bar_width(w: f32) -> f32 {
    (w / 60.0).max(10.0)
}

/// Where a colour bar's colours run and which of its tick labels are drawn where.
struct BarTicks {
    /// The colours' top, short of a cap drawn above.
    y0: f32,
    /// The colours' bottom, short of a cap drawn below.
    y1: f32,
    /// The labels drawn, each with the height of its tick.
    labels: Vec<(f32, String)>,
}

/// `bar` drawn between heights `top` and `bottom` in a frame `w` wide: its colours' span, and
/// every k-th of its tick labels for the least k that sets them at least a line of `text`
/// apart; `None` when no two labels are (or the span is empty).
fn bar_ticks(bar: &ColorBar, text: &Text, (top, bottom): (f32, f32), w: f32) -> Option<BarTicks> {
    let cap = bar_width(w).round() as i64;
    let cap_room = |drawn: bool| if drawn { (cap / 2 + 3) as f32 } else { 0.0 };
    let (y0, y1) = (
        top + cap_room(bar.beyond.1),
        bottom - cap_room(bar.beyond.0),
    );
    if y1 <= y0 {
        return None;
    }
    let scale = crate::coloring::ColorScale {
        colormap: bar.colormap,
        range: None,
        log: bar.log,
    };
    let placed: Vec<(f32, String)> = bar_labels(bar)
        .into_iter()
        .map(|(v, s)| (y1 - scale.position(v, bar.range) as f32 * (y1 - y0), s))
        .collect();
    let apart = |picked: &[&(f32, String)]| {
        picked
            .windows(2)
            .all(|p| (p[0].0 - p[1].0).abs() >= text.px * 1.1)
    };
    let steps = 1..placed.len().max(2);
    let labels = steps
        .map(|k| placed.iter().step_by(k).collect::<Vec<_>>())
        .find(|picked| apart(picked))?;
    let labels = labels.into_iter().cloned().collect();
    Some(BarTicks { y0, y1, labels })
}

/// The tick values of `bar` and their labels.
fn bar_labels(bar: &ColorBar) -> Vec<(f64, String)> {
    let ticks = ticks(bar.range, bar.log);
    ticks.iter().copied().zip(distinct_labels(&ticks)).collect()
}

/// The title drawn above `bar`.
fn bar_title(bar: &ColorBar) -> String {
    match bar.log {
        true => format!("{} (log)", bar.title),
        false => bar.title.clone(),
    }
}

/// The width of `bar`'s colours and tick labels in a frame `w` wide.
fn bar_block_width(text: &Text, bar: &ColorBar, w: f32) -> f32 {
    let label_w = bar_labels(bar)
        .iter()
        .map(|l| text.width(&l.1))
        .fold(0.0, f32::max);
    label_w + text.px * 0.5 + bar_width(w)
}

/// The left edge of `bar`'s colours and title in a frame `w` wide: room on their right for the
/// widest label, and for the widest line of the title.
fn bar_left(text: &Text, bar: &ColorBar, w: f32) -> f32 {
    let right = w - text.px;
    let title_w = title_lines(text, bar, w)
        .iter()
        .map(|l| text.width(l))
        .fold(0.0, f32::max);
    (right - bar_block_width(text, bar, w)).min(right - title_w)
}

/// `bar`'s title in lines no wider than its colours and labels where it can be broken (after a
/// comma or a space): a magnitude's `|x-velocity,y-velocity,z-velocity|` would otherwise widen
/// the bar's panel across the picture.
fn title_lines(text: &Text, bar: &ColorBar, w: f32) -> Vec<String> {
    let title = bar_title(bar);
    let room = bar_block_width(text, bar, w);
    let mut lines: Vec<String> = Vec::new();
    let mut line = String::new();
    for piece in title.split_inclusive([',', ' ']) {
        let longer = format!("{line}{piece}");
        if !line.is_empty() && text.width(longer.trim_end()) > room {
            lines.push(line.trim_end().to_string());
            line = piece.to_string();
        } else {
            line = longer;
        }
    }
    lines.push(line.trim_end().to_string());
    lines
}

/// The height `bar`'s title takes above its colours' span.
fn title_height(text: &Text, bar: &ColorBar, w: f32) -> f32 {
    let lines = title_lines(text, bar, w).len() as f32;
    text.px * (1.6 + (lines - 1.0) * LINE)
}

/// A line for surfaces made otherwise than by default (the octant reconstruction, traced
/// exactly), whose look differs: blocky `nearest` cells, `current`'s cracks at level
/// boundaries, sampled surfaces; `None` for the default or a frame without surfaces.
fn how_surfaces_were_made(scene: &Scene) -> Option<String> {
    if scene.isosurfaces().is_empty() {
        return None;
    }
    let reconstruction = scene.reconstruction();
    let sampled = scene.method() == TraceMethod::Sample;
    let mut parts = Vec::new();
    if reconstruction != Reconstruction::Octant {
        parts.push(format!("{} reconstruction", reconstruction.name()));
    }
    if sampled {
        parts.push("sampled along rays".to_string());
    }
    (!parts.is_empty()).then(|| format!("surfaces: {}", parts.join(", ")))
}

/// When in the simulation the data was written, as the file records it: `t = 0.81751, step 10`
/// (either part alone when only one is recorded; `None` when neither is).
fn simulation_stamp(time: Option<f64>, step: Option<i64>) -> Option<String> {
    match (time, step) {
        (Some(t), Some(s)) => Some(format!("t = {}, step {s}", format_value(t))),
        (Some(t), None) => Some(format!("t = {}", format_value(t))),
        (None, Some(s)) => Some(format!("step {s}")),
        (None, None) => None,
    }
}

/// Whether any of the painted values (NaN: not painted) lies below `lo` and above `hi`, by more
/// than the `f32` rounding of the range's ends. With `levels` (the frame's level channel, when
/// some surfaces are painted by level), a value equal to its pixel's level is taken for a level
/// and left out.
fn values_beyond(values: &[f32], levels: Option<&[f32]>, (lo, hi): (f64, f64)) -> (bool, bool) {
    let slack = 1e-6 * lo.abs().max(hi.abs());
    let painted_by_level = |i: usize| levels.is_some_and(|l| l.get(i) == Some(&values[i]));
    (0..values.len())
        .filter(|&i| values[i].is_finite() && !painted_by_level(i))
        .fold((false, false), |(below, above), i| {
            let v = f64::from(values[i]);
            (below || v < lo - slack, above || v > hi + slack)
        })
}

/// About five round tick values in `range`: powers of ten for a log scale spanning three
/// decades or more, 1-2-5 steps within each decade for one spanning one to three (where the
/// powers of ten alone would label the bar at one or two places).
pub fn ticks((lo, hi): (f64, f64), log: bool) -> Vec<f64> {
    if !(hi > lo) || !lo.is_finite() || !hi.is_finite() {
        return vec![lo];
    }
    if log && lo > 0.0 && hi / lo >= 10.0 {
        let (a, b) = (lo.log10().ceil() as i32, hi.log10().floor() as i32);
        if b - a >= 2 {
            let step = ((b - a) / 6 + 1).max(1);
            return (a..=b)
                .step_by(step as usize)
                .map(|e| 10f64.powi(e))
                .collect();
        }
        let slack = 1e-9;
        return (a - 1..=b)
            .flat_map(|e| [1.0, 2.0, 5.0].map(|m| m * 10f64.powi(e)))
            .filter(|v| *v >= lo * (1.0 - slack) && *v <= hi * (1.0 + slack))
            .collect();
    }
    let raw = (hi - lo) / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let steps = [0.5, 1.0, 2.0, 2.5, 5.0, 10.0].map(|m| m * mag);
    let at = steps[1..]
        .iter()
        .position(|s| *s >= raw)
        .map_or(5, |k| k + 1);
    let in_steps = |step: f64| -> Vec<f64> {
        let first = (lo / step - 1e-9).ceil() as i64;
        (first..)
            .map(|k| k as f64 * step)
            .take_while(|v| *v <= hi + 1e-9 * step)
            .take(12)
            .collect()
    };
    // The first round step at least a fifth of the range can leave two ticks (20 to 560 in
    // steps of 200): then the next smaller one.
    let ticks = in_steps(steps[at]);
    match ticks.len() < 3 {
        true => in_steps(steps[at - 1]),
        false => ticks,
    }
}

/// The box the axis triad and its letters may take at the bottom left of a `w x h` frame,
/// whatever the camera's turn, cut to the frame.
fn triad_box(w: f32, h: f32, px: f32) -> (f32, f32, f32, f32) {
    let len = h.min(w) / 14.0;
    let o = (px + len + 4.0, h - px - len - 4.0);
    let reach = 1.25 * len;
    (
        (o.0 - reach - px * 0.3).max(0.0),
        (o.1 - reach - px * 0.6).max(0.0),
        (o.0 + reach + px * 0.7).min(w),
        (o.1 + reach + px * 0.6).min(h),
    )
}

/// The world axes as the camera sees them, at the bottom left: x red, y green, z blue, their
/// names in `ink`.
fn draw_triad(canvas: &mut Canvas<'_>, text: &Text, camera: &Camera, m: f32, ink: Ink) {
    let (right, up) = camera.basis();
    let len = f64::from(canvas.h).min(f64::from(canvas.w)) / 14.0;
    let o = (
        f64::from(m) + len + 4.0,
        f64::from(canvas.h) - f64::from(m) - len - 4.0,
    );
    let colors = [[230, 80, 70], [90, 200, 90], [90, 140, 240]];
    let width = ((len / 25.0) as i64).max(2);
    for (a, name) in ["x", "y", "z"].iter().enumerate() {
        let tip = (o.0 + len * right[a], o.1 - len * up[a]);
        canvas.line(o, tip, colors[a], width);
        let lx = o.0 + 1.25 * len * right[a] - f64::from(text.px) * 0.3;
        let ly = o.1 - 1.25 * len * up[a] - f64::from(text.px) * 0.6;
        text.draw(canvas, name, lx as f32, ly as f32, ink);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_inside() {
        let t = ticks((0.0, 1.0), false);
        assert_eq!(t.len(), 6);
        assert!(t
            .iter()
            .zip([0.0, 0.2, 0.4, 0.6, 0.8, 1.0])
            .all(|(a, b)| (a - b).abs() < 1e-12));
        let t = ticks((-0.35, 0.8), false);
        assert_eq!(t, vec![-0.25, 0.0, 0.25, 0.5, 0.75]);
        let t = ticks((298.0, 1580.0), false);
        assert!(
            t.iter().all(|v| (298.0..=1580.0).contains(v)) && t.len() >= 3,
            "{t:?}"
        );
        assert_eq!(ticks((1.0, 1000.0), true), vec![1.0, 10.0, 100.0, 1000.0]);
        assert_eq!(
            ticks((0.09, 8.3), true),
            vec![0.1, 0.2, 0.5, 1.0, 2.0, 5.0],
            "a log bar over two decades is labelled at more than its powers of ten"
        );
        assert_eq!(ticks((1.5, 16.0), true), vec![2.0, 5.0, 10.0]);
        assert_eq!(
            ticks((20.0, 560.0), false),
            vec![100.0, 200.0, 300.0, 400.0, 500.0],
            "a range the first round step would label twice takes the next smaller"
        );
        let t = ticks((1.0, 1.0000141), false);
        assert_eq!(t.len(), 3, "the tick at the range's low end is kept: {t:?}");
        assert!((t[0] - 1.0).abs() < 1e-12, "{t:?}");
    }

    #[test]
    fn values_past_the_range_are_told_on_their_side() {
        let nan = f32::NAN;
        assert_eq!(
            values_beyond(&[nan, 1.0, 5.0], None, (0.0, 4.0)),
            (false, true)
        );
        assert_eq!(values_beyond(&[-1.0, 2.0], None, (0.0, 4.0)), (true, false));
        assert_eq!(
            values_beyond(&[nan, 0.0, 4.0], None, (0.0, 4.0)),
            (false, false)
        );
        let levels = [5.0, 1.0, 2.0];
        assert_eq!(
            values_beyond(&[5.0, 1.0, 2.0], Some(&levels), (0.0, 4.0)),
            (false, false),
            "level 5 painted by level"
        );
        assert_eq!(
            values_beyond(&[5.0, 6.0, 2.0], Some(&levels), (0.0, 4.0)),
            (false, true)
        );
        let hi = 1.000_014_066_696_167;
        assert_eq!(values_beyond(&[hi as f32], None, (1.0, hi)), (false, false));
    }

    #[test]
    fn a_long_colour_bar_title_breaks_after_its_commas() {
        let text = Text::new(12.0).unwrap();
        let bar = |title: &str| ColorBar {
            title: title.into(),
            colormap: Colormap::default(),
            range: (0.9, 1.1),
            log: false,
            beyond: (false, false),
        };
        let long = bar("|x-velocity,y-velocity,z-velocity|");
        let lines = title_lines(&text, &long, 640.0);
        assert_eq!(lines.len(), 3, "{lines:?}");
        assert_eq!(lines.concat(), long.title);
        let room = bar_block_width(&text, &long, 640.0);
        // A line wider than the bar's colours and labels cannot be broken.
        let unbreakable = |l: &str| !l[..l.len() - 1].contains([',', ' ']);
        assert!(
            lines
                .iter()
                .all(|l| text.width(l) <= room || unbreakable(l)),
            "{lines:?}"
        );
        assert_eq!(title_lines(&text, &bar("T"), 640.0), ["T"]);
        // Two bars under wrapped titles still fit, their parts apart.
        let legend = Legend {
            color_bars: vec![long.clone(), bar("Dark_Matter_Density, in code units")],
            ..Legend::default()
        };
        assert!(legend.fits(640, 480));
        let spans: Vec<(f32, f32)> = (0..2)
            .map(|k| legend.bar_span(&text, (640.0, 480.0), k))
            .collect();
        let second_title = title_height(&text, &legend.color_bars[1], 640.0);
        assert!(
            spans[0].1 + text.px * 0.6 < spans[1].0 - second_title,
            "{spans:?}"
        );
    }

    #[test]
    fn a_bar_with_values_past_its_ends_is_capped_on_those_sides() {
        let (w, h) = (400u32, 300u32);
        let draw = |beyond| {
            let mut rgb = vec![128u8; (3 * w * h) as usize];
            let legend = Legend {
                color_bars: vec![ColorBar {
                    title: "T".into(),
                    colormap: Colormap::default(),
                    range: (0.0, 1.0),
                    log: false,
                    beyond,
                }],
                ..Legend::default()
            };
            legend.draw(&mut rgb, w, h);
            rgb
        };
        let (plain, top, both) = (
            draw((false, false)),
            draw((false, true)),
            draw((true, true)),
        );
        let count = |rgb: &[u8], t: f64| {
            let c = Colormap::default().srgb8(t);
            rgb.chunks(3).filter(|p| *p == c).count()
        };
        let bar_w = (w as f32 / 60.0).max(10.0) as usize;
        assert!(
            count(&top, 1.0) > count(&plain, 1.0) + bar_w,
            "no cap on top"
        );
        assert_eq!(count(&top, 0.0), count(&plain, 0.0));
        assert!(
            count(&both, 0.0) > count(&top, 0.0) + bar_w,
            "no cap at the bottom"
        );
    }

    /// The legend of a frame with two surfaces painted by level, as the demo's.
    fn two_surfaces_by_level() -> Legend {
        Legend {
            entries: vec![
                ("blobs = 10, coloured by level".into(), None),
                ("blobs = 6, coloured by level (opacity 0.3)".into(), None),
            ],
            levels: vec![1, 2],
            camera: Some(Camera::new([3.0, 2.0, 1.5], [0.5; 3], [0.0, 0.0, 1.0], 40.0).unwrap()),
            ..Legend::default()
        }
    }

    #[test]
    fn a_picture_too_small_for_its_legend_is_left_as_rendered() {
        let legend = two_surfaces_by_level();
        let (w, h) = (128u32, 96u32);
        let mut rgb = vec![128u8; (3 * w * h) as usize];
        assert!(!legend.fits(w, h));
        assert!(!legend.draw(&mut rgb, w, h), "drawn where it does not fit");
        assert!(rgb.iter().all(|&c| c == 128), "pixels changed");
        // The smallest size of its shape that holds it is one, and the step below is not.
        let (fw, fh) = legend.smallest_fitting_size((w, h)).unwrap();
        assert!(legend.fits(fw, fh) && fw > w && fh > h, "{fw}x{fh}");
        let below = |n: u32| (f64::from(n) * (f64::from(fw) / f64::from(w) - 0.25)).round() as u32;
        assert!(
            !legend.fits(below(w), below(h)),
            "{fw}x{fh} is not the smallest"
        );
        let mut rgb = vec![128u8; (3 * fw * fh) as usize];
        assert!(legend.draw(&mut rgb, fw, fh));
        assert!(rgb.iter().any(|&c| c != 128));
    }

    #[test]
    fn a_crowded_legend_shrinks_its_text_before_it_is_left_out() {
        let legend = two_surfaces_by_level();
        let (w, h) = (200u32, 150u32);
        let text = |px| Text::new(px).unwrap();
        let nominal = (h as f32 / 40.0).clamp(10.0, 28.0);
        assert!(
            !legend.has_room(&text(nominal), w as f32, h as f32, false),
            "the case needs no shrinking"
        );
        let (drawn, triad) = legend.layout(w, h).expect("no room at any size");
        assert!(drawn.px < nominal && drawn.px >= MIN_TEXT_PX);
        assert!(triad, "the triad left out where smaller text holds it");
        // At 1024x768 nothing shrinks.
        assert_eq!(legend.layout(1024, 768).unwrap().0.px, 768.0 / 40.0);
    }

    #[test]
    fn a_short_colour_bar_labels_every_other_tick_a_line_apart() {
        let bar = ColorBar {
            title: "T".into(),
            colormap: Colormap::default(),
            range: (0.0, 1.0),
            log: false,
            beyond: (false, false),
        };
        let text = Text::new(10.0).unwrap();
        let all = bar_ticks(&bar, &text, (0.0, 200.0), 400.0).unwrap().labels;
        assert_eq!(all.len(), 6, "{all:?}");
        let short = bar_ticks(&bar, &text, (0.0, 40.0), 400.0).unwrap().labels;
        let names: Vec<&str> = short.iter().map(|l| l.1.as_str()).collect();
        assert_eq!(names, ["0", "0.4", "0.8"]);
        assert!(short.windows(2).all(|p| (p[0].0 - p[1].0).abs() >= 11.0));
        assert!(bar_ticks(&bar, &text, (0.0, 8.0), 400.0).is_none());
    }

    #[test]
    fn the_simulation_stamp_shows_what_the_file_records() {
        assert_eq!(
            simulation_stamp(Some(0.81751317119117), Some(10)).as_deref(),
            Some("t = 0.81751, step 10")
        );
        assert_eq!(
            simulation_stamp(Some(1.3924182125972017e-8), None).as_deref(),
            Some("t = 1.3924e-8")
        );
        assert_eq!(simulation_stamp(None, Some(20)).as_deref(), Some("step 20"));
        assert_eq!(simulation_stamp(None, None), None);
    }
}
