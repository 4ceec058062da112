//! The text attributes an EXR frame carries: the camera, the isosurfaces, the method, the
//! timings and the origin of its `P` channels, so that a frame says how it was made.

use crate::camera::Projection;
use crate::render::Rendered;
use crate::scene::Scene;
use crate::shade::IsoSpec;
use crate::stats::ms;

/// The header attributes of `rendered`, a frame of `scene`, followed by `extra`.
pub fn frame_header(
    scene: &Scene,
    rendered: &Rendered,
    extra: &[(&str, String)],
) -> Vec<(String, String)> {
    let c = &rendered.camera;
    // `V:#rrggbb[:OPACITY]` as `--iso` reads it, with the colour the surface was drawn in.
    let isos: Vec<String> = scene
        .isosurfaces()
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let drawn = IsoSpec {
                color: Some(s.color_or_palette(i)),
                ..*s
            };
            drawn.to_string()
        })
        .collect();
    let stats = scene.stats();
    let mut m: Vec<(String, String)> = vec![
        (
            "camera".into(),
            match c.projection {
                Projection::Perspective => format!(
                    "pos={:?} look_at={:?} up={:?} fov_deg={}",
                    c.pos, c.look_at, c.up, c.fov_deg
                ),
                Projection::Orthographic { height } => format!(
                    "pos={:?} look_at={:?} up={:?} orthographic view_height={height}",
                    c.pos, c.look_at, c.up
                ),
            },
        ),
        ("field".into(), scene.field_name().to_string()),
        ("isovalues".into(), isos.join(" ")),
        ("method".into(), scene.method().name().into()),
        (
            "timings_ms".into(),
            format!(
                "extract={:.3} bvh={:.3} render={:.3}",
                ms(stats.extract),
                ms(stats.bvh),
                ms(rendered.stats.render)
            ),
        ),
        (
            "P_relative_to".into(),
            "P_origin_x/y/z (world position of the domain's lower corner)".into(),
        ),
        ("file".into(), scene.path().display().to_string()),
    ];
    if !scene.one_field() {
        // Each isovalue's field, in order ("; " apart: names may hold spaces), when some are
        // not `field`'s.
        let fields: Vec<&str> = scene
            .isosurfaces()
            .iter()
            .map(|s| scene.surface_field_name(s))
            .collect();
        m.push(("iso_fields".into(), fields.join("; ")));
    }
    if scene.color_by().iter().any(Option::is_some) {
        let by: Vec<String> = (0..scene.isosurfaces().len())
            .map(|i| match scene.color_by().get(i).cloned().flatten() {
                Some(by) => by.to_string(),
                None => "-".into(),
            })
            .collect();
        m.push(("color_by".into(), by.join(" ")));
    }
    match rendered.color_ranges.as_slice() {
        [] => {}
        [one] => {
            let (lo, hi) = one.range;
            m.push(("color_range".into(), format!("{lo} {hi}")));
        }
        several => {
            // Each painting field's range and colormap, `; ` apart (names may hold spaces).
            let ranges: Vec<String> = several
                .iter()
                .map(|r| {
                    let log = if r.scale.log { " log" } else { "" };
                    let (lo, hi) = r.range;
                    format!("{} {lo} {hi} {}{log}", r.field, r.scale.colormap)
                })
                .collect();
            m.push(("color_ranges".into(), ranges.join("; ")));
        }
    }
    if !scene.slices().is_empty() {
        let slices: Vec<String> = scene
            .slices()
            .iter()
            .map(|(s, by)| {
                format!(
                    "point={:?} normal={:?} opacity={} color_by={by}",
                    s.point, s.normal, s.opacity
                )
            })
            .collect();
        m.push(("slices".into(), slices.join("; ")));
    }
    m.extend(extra.iter().map(|(k, v)| ((*k).to_string(), v.clone())));
    m
}
