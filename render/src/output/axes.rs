//! Coordinate labels along the domain's box: on one edge per axis, on the box's outline as the
//! camera sees it, tick marks with their world coordinates and the axis' name, so that a picture
//! tells where and how large what it shows is (VisIt's bounding-box axes; ParaView's cube axes).

use super::background::Ink;
use super::canvas::{Canvas, Text};
use super::legend::ticks;
use crate::camera::{box_corners, Camera};
use crate::field_stats::distinct_labels;

/// A rectangle of the picture, `(x0, y0, x1, y1)` in pixels.
pub(crate) type PixelBox = (f32, f32, f32, f32);

/// One labelled tick on the picture.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Tick {
    /// The point on the edge.
    pub at: (f64, f64),
    /// The tick mark's outer end.
    pub end: (f64, f64),
    /// The coordinate written.
    pub label: String,
    /// Where the label is written.
    pub label_box: PixelBox,
}

/// The labels of one axis laid out on the picture.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct AxisLabels {
    /// The axis, 0 to 2 for x to z.
    pub axis: usize,
    /// Its ticks, in ascending order.
    pub ticks: Vec<Tick>,
    /// The axis' name (`x`, `y`, `z`) and its box, when it has room.
    pub name: Option<(String, PixelBox)>,
}

/// The fewest labels an axis is drawn with: one label tells a position, two tell a scale.
const MIN_LABELS: usize = 2;

/// An edge of the box parallel to an axis, as the picture shows it.
struct Edge {
    /// The world points at its two ends (the axis' low end first).
    ends: [[f64; 3]; 2],
    /// Where they fall on the picture.
    at: [(f64, f64); 2],
    /// The unit direction on the picture pointing away from the box, across the edge.
    outward: (f64, f64),
}

/// The labels of the box `[lo, hi]` seen by `camera` in a `w x h` picture drawn with `text`:
/// per axis, on the edge of the box's outline that lies lowest (an edge that runs across the
/// picture) or leftmost (one that runs up it), every k-th round coordinate for the least k that
/// keeps the labels apart; labels that would leave the picture or cover a box of `taken` (the
/// legend's parts, then the labels already placed) are left out, and an axis with fewer than
/// two labels left is not labelled. Nothing when the camera is inside the box or a corner of
/// it is behind the camera.
pub(crate) fn axis_labels(
    camera: &Camera,
    (lo, hi): ([f64; 3], [f64; 3]),
    (w, h): (u32, u32),
    text: &Text,
    taken: &[PixelBox],
) -> Vec<AxisLabels> {
    let inside = (0..3).all(|a| lo[a] <= camera.pos[a] && camera.pos[a] <= hi[a]);
    let corners: Option<Vec<(f64, f64)>> = box_corners(lo, hi)
        .into_iter()
        .map(|p| camera.image_point(p, w, h).map(|[x, y]| (x, y)))
        .collect();
    let Some(corners) = corners.filter(|_| !inside && (0..3).all(|a| lo[a] < hi[a])) else {
        return Vec::new();
    };
    // The middle of the box's outline on the picture, which edges point away from.
    let n = corners.len() as f64;
    let centre = corners
        .iter()
        .fold((0.0, 0.0), |c, p| (c.0 + p.0 / n, c.1 + p.1 / n));
    let mut taken = taken.to_vec();
    let mut out = Vec::new();
    for axis in 0..3 {
        let Some(edge) = labelled_edge(camera, (lo, hi), (w, h), axis, centre) else {
            continue;
        };
        if let Some(labels) = lay_out(camera, &edge, axis, (w, h), text, &taken) {
            taken.extend(labels.ticks.iter().map(|t| t.label_box));
            taken.extend(labels.name.iter().map(|n| n.1));
            out.push(labels);
        }
    }
    out
}

/// The edge of the box parallel to `axis` that carries its labels: among the edges on the box's
/// outline (one of the two faces that meet there faces the camera, the other away), the lowest
/// on the picture for an edge running across it, the leftmost for one running up it; `None`
/// when every such edge shows as a point (a view along `axis`) or lies partly behind the camera.
fn labelled_edge(
    camera: &Camera,
    (lo, hi): ([f64; 3], [f64; 3]),
    (w, h): (u32, u32),
    axis: usize,
    centre: (f64, f64),
) -> Option<Edge> {
    let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
    let faces_camera = |k: usize, high: bool| camera.sees_face(k, high, (lo, hi));
    let mut best: Option<(f64, Edge)> = None;
    for (high_b, high_c) in [(false, false), (false, true), (true, false), (true, true)] {
        if faces_camera(b, high_b) == faces_camera(c, high_c) {
            continue;
        }
        let end = |v: f64| {
            let mut p = [0.0; 3];
            p[axis] = v;
            p[b] = if high_b { hi[b] } else { lo[b] };
            p[c] = if high_c { hi[c] } else { lo[c] };
            p
        };
        let ends = [end(lo[axis]), end(hi[axis])];
        let [Some(p0), Some(p1)] = ends.map(|p| camera.image_point(p, w, h)) else {
            continue;
        };
        let d = (p1[0] - p0[0], p1[1] - p0[1]);
        let len = d.0.hypot(d.1);
        if len < 1.0 {
            continue;
        }
        let mid = (0.5 * (p0[0] + p1[0]), 0.5 * (p0[1] + p1[1]));
        let mut outward = (-d.1 / len, d.0 / len);
        let away = (mid.0 - centre.0) * outward.0 + (mid.1 - centre.1) * outward.1;
        if away.abs() < 1e-9 {
            continue;
        }
        if away < 0.0 {
            outward = (-outward.0, -outward.1);
        }
        let score = match d.0.abs() >= d.1.abs() {
            true => outward.1,
            false => -outward.0,
        };
        let edge = Edge {
            ends,
            at: [(p0[0], p0[1]), (p1[0], p1[1])],
            outward,
        };
        if best.as_ref().is_none_or(|(s, _)| score > *s) {
            best = Some((score, edge));
        }
    }
    best.map(|(_, e)| e)
}

/// The tick marks and labels of `axis` on `edge`, as [`axis_labels`] chooses them; `None` when
/// fewer than [`MIN_LABELS`] have room.
fn lay_out(
    camera: &Camera,
    edge: &Edge,
    axis: usize,
    (w, h): (u32, u32),
    text: &Text,
    taken: &[PixelBox],
) -> Option<AxisLabels> {
    let px = f64::from(text.px);
    let (lo, hi) = (edge.ends[0][axis], edge.ends[1][axis]);
    let values = ticks((lo, hi), false);
    let o = edge.outward;
    let tick_len = 0.5 * px;
    // A label's box, set beyond its tick so that its nearest side is `gap` from the tick's end.
    let label_box = |at: (f64, f64), s: &str, gap: f64| -> PixelBox {
        let (tw, th) = (f64::from(text.width(s)), 1.2 * px);
        let reach = tick_len + gap + 0.5 * (o.0.abs() * tw + o.1.abs() * th);
        let (cx, cy) = (at.0 + o.0 * reach, at.1 + o.1 * reach);
        let half = (0.5 * tw, 0.5 * th);
        (
            (cx - half.0) as f32,
            (cy - half.1) as f32,
            (cx + half.0) as f32,
            (cy + half.1) as f32,
        )
    };
    let placed: Vec<_> = values
        .iter()
        .zip(distinct_labels(&values))
        .filter_map(|(&v, s)| {
            let mut p = edge.ends[0];
            p[axis] = v;
            let [x, y] = camera.image_point(p, w, h)?;
            Some(Tick {
                at: (x, y),
                end: (x + o.0 * tick_len, y + o.1 * tick_len),
                label_box: label_box((x, y), &s, 0.25 * px),
                label: s,
            })
        })
        .collect();
    let gap = 0.3 * text.px;
    let apart = |a: &PixelBox, b: &PixelBox| {
        a.2 + gap <= b.0 || b.2 + gap <= a.0 || a.3 + gap <= b.1 || b.3 + gap <= a.1
    };
    let free = |b: &PixelBox| {
        b.0 >= 0.0
            && b.1 >= 0.0
            && b.2 <= w as f32
            && b.3 <= h as f32
            && taken.iter().all(|t| apart(b, t))
    };
    let spaced = (1..placed.len().max(2))
        .map(|k| placed.iter().step_by(k).collect::<Vec<_>>())
        .find(|picked| {
            picked
                .windows(2)
                .all(|p| apart(&p[0].label_box, &p[1].label_box))
        })?;
    let ticks: Vec<Tick> = spaced
        .into_iter()
        .filter(|t| free(&t.label_box))
        .cloned()
        .collect();
    if ticks.len() < MIN_LABELS {
        return None;
    }
    // The name beyond the labels, at the middle of the edge.
    let name = ["x", "y", "z"][axis].to_string();
    let beyond = ticks
        .iter()
        .map(|t| {
            let b = t.label_box;
            let half = 0.5 * (o.0.abs() * f64::from(b.2 - b.0) + o.1.abs() * f64::from(b.3 - b.1));
            0.25 * px + 2.0 * half
        })
        .fold(0.0, f64::max);
    let mid = (
        0.5 * (edge.at[0].0 + edge.at[1].0),
        0.5 * (edge.at[0].1 + edge.at[1].1),
    );
    let name_box = label_box(mid, &name, beyond + 0.5 * px);
    let name = (free(&name_box) && ticks.iter().all(|t| apart(&name_box, &t.label_box)))
        .then_some((name, name_box));
    Some(AxisLabels { axis, ticks, name })
}

/// Draws `labels`, their tick marks and text in `ink`.
pub(crate) fn draw_axis_labels(
    canvas: &mut Canvas<'_>,
    text: &Text,
    labels: &[AxisLabels],
    ink: Ink,
) {
    let width = ((text.px / 10.0) as i64).max(1);
    // The tick marks a little softer than the text, as they were on the grey background.
    let tick = ink.fill.map(|c| if c > 128 { c - 10 } else { c });
    for axis in labels {
        for t in &axis.ticks {
            canvas.line(t.at, t.end, tick, width);
            text.draw(canvas, &t.label, t.label_box.0, t.label_box.1, ink);
        }
        if let Some((s, b)) = &axis.name {
            text.draw(canvas, s, b.0, b.1, ink);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::ViewFrom;

    const UNIT: ([f64; 3], [f64; 3]) = ([0.0; 3], [1.0; 3]);

    fn apart(a: &PixelBox, b: &PixelBox) -> bool {
        a.2 <= b.0 || b.2 <= a.0 || a.3 <= b.1 || b.3 <= a.1
    }

    /// Every label and name box of `labels`.
    fn boxes(labels: &[AxisLabels]) -> Vec<PixelBox> {
        labels
            .iter()
            .flat_map(|a| {
                a.ticks
                    .iter()
                    .map(|t| t.label_box)
                    .chain(a.name.iter().map(|n| n.1))
            })
            .collect()
    }

    /// The values `axis`' labels read as, checked ascending along the edge.
    fn ascending_values(axis: &AxisLabels) -> Vec<f64> {
        let v: Vec<f64> = axis
            .ticks
            .iter()
            .map(|t| t.label.parse().unwrap())
            .collect();
        assert!(v.windows(2).all(|p| p[0] < p[1]), "{v:?}");
        v
    }

    #[test]
    fn the_default_view_labels_three_edges_outside_the_box_with_labels_apart() {
        let (w, h) = (640, 480);
        let camera = Camera::framing(UNIT.0, UNIT.1, 40.0, 640.0 / 480.0).unwrap();
        let text = Text::new(12.0).unwrap();
        let labels = axis_labels(&camera, UNIT, (w, h), &text, &[]);
        assert_eq!(labels.iter().map(|a| a.axis).collect::<Vec<_>>(), [0, 1, 2]);
        let all = boxes(&labels);
        for (i, a) in all.iter().enumerate() {
            assert!(a.0 >= 0.0 && a.1 >= 0.0 && a.2 <= w as f32 && a.3 <= h as f32);
            assert!(all[i + 1..].iter().all(|b| apart(a, b)), "{a:?} overlaps");
        }
        let centre = camera.image_point([0.5; 3], w, h).unwrap();
        for axis in &labels {
            assert!(
                axis.ticks.len() >= MIN_LABELS && axis.name.is_some(),
                "{axis:?}"
            );
            for Tick {
                at,
                label: s,
                label_box: b,
                ..
            } in &axis.ticks
            {
                // The label reads as a coordinate of the box, and lies beyond its tick.
                let v: f64 = s.parse().unwrap();
                assert!((0.0..=1.0).contains(&v), "{s}");
                let mid = (f64::from(b.0 + b.2) / 2.0, f64::from(b.1 + b.3) / 2.0);
                let from_centre = |p: (f64, f64)| (p.0 - centre[0]).hypot(p.1 - centre[1]);
                assert!(from_centre(mid) > from_centre(*at), "{s} at {at:?}: {b:?}");
            }
            ascending_values(axis);
        }
    }

    #[test]
    fn a_map_view_labels_x_below_and_y_left_of_the_box_and_not_z() {
        let (w, h) = (800, 600);
        let from = ViewFrom {
            dir: [0.0, 0.0, 1.0],
            up: None,
            tight: true,
        };
        let camera = Camera::framing_from(UNIT.0, UNIT.1, &from, 40.0, 800.0 / 600.0).unwrap();
        let text = Text::new(15.0).unwrap();
        let labels = axis_labels(&camera, UNIT, (w, h), &text, &[]);
        assert_eq!(labels.iter().map(|a| a.axis).collect::<Vec<_>>(), [0, 1]);
        let corner = |p| camera.image_point(p, w, h).unwrap();
        let (low_left, top_right) = (corner([0.0, 0.0, 1.0]), corner([1.0, 1.0, 1.0]));
        for t in &labels[0].ticks {
            let b = t.label_box;
            assert!(
                f64::from(b.1) > low_left[1],
                "x label {} {b:?} below",
                t.label
            );
        }
        for t in &labels[1].ticks {
            let b = t.label_box;
            assert!(
                f64::from(b.2) < low_left[0],
                "y label {} {b:?} left",
                t.label
            );
        }
        assert!(top_right[0] > low_left[0] && top_right[1] < low_left[1]);
    }

    #[test]
    fn labels_keep_off_taken_boxes_and_a_camera_inside_the_box_gets_none() {
        let (w, h) = (640, 480);
        let camera = Camera::framing(UNIT.0, UNIT.1, 40.0, 640.0 / 480.0).unwrap();
        let text = Text::new(12.0).unwrap();
        let taken = [(0.0, 240.0, 640.0, 480.0)];
        let labels = axis_labels(&camera, UNIT, (w, h), &text, &taken);
        assert!(
            !labels.is_empty(),
            "the upper half holds the z axis' labels"
        );
        assert!(boxes(&labels).iter().all(|b| apart(b, &taken[0])));
        assert!(labels.iter().all(|a| a.ticks.len() >= MIN_LABELS));
        let inside = Camera::new([0.5, 0.5, 0.9], [0.5, 0.5, 0.0], [0.0, 1.0, 0.0], 60.0).unwrap();
        assert!(axis_labels(&inside, UNIT, (w, h), &text, &[]).is_empty());
        // Extreme boxes: nothing sensible to write, and no hang or panic on the way.
        let far = Camera::new([3e307; 3], [0.0; 3], [0.0, 0.0, 1.0], 40.0).unwrap();
        let boxes_far = [
            ([-1e300; 3], [1e300; 3]),
            ([1e6; 3], [1e6 + 1e-9; 3]),
            ([0.0; 3], [1e-310; 3]),
            ([-f64::MAX; 3], [f64::MAX; 3]),
        ];
        for (lo, hi) in boxes_far {
            let labels = axis_labels(&far, (lo, hi), (w, h), &text, &[]);
            assert!(boxes(&labels)
                .iter()
                .all(|b| b.0.is_finite() && b.3.is_finite()));
        }
        // A box far from the origin reads its own coordinates, each label distinct.
        let (lo, hi) = ([1e6; 3], [1e6 + 0.75; 3]);
        let camera = Camera::framing(lo, hi, 40.0, 640.0 / 480.0).unwrap();
        let labels = axis_labels(&camera, (lo, hi), (w, h), &text, &[]);
        assert_eq!(labels.len(), 3);
        for axis in &labels {
            let v = ascending_values(axis);
            assert!(v.iter().all(|x| (1e6..=1e6 + 0.75).contains(x)), "{v:?}");
        }
        let flat = ([0.0; 3], [1.0, 1.0, 0.0]);
        assert!(axis_labels(&camera, flat, (w, h), &text, &[]).is_empty());
    }
}
