//! The text attributes an EXR frame carries: the camera, the isosurfaces, the method, the
//! timings and the origin of its `P` channels, so that a frame says how it was made.

use crate::render::Rendered;
use crate::scene::Scene;
use crate::shade::material::css_hex;
use crate::stats::ms;

/// The header attributes of `rendered`, a frame of `scene`, followed by `extra`.
pub fn frame_header(
    scene: &Scene,
    rendered: &Rendered,
    extra: &[(&str, String)],
) -> Vec<(String, String)> {
    let c = &rendered.camera;
    let isos: Vec<String> = scene
        .isosurfaces()
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let paint = match scene.color_by().get(i).cloned().flatten() {
                Some(by) => format!(" color_by={by}"),
                None => String::new(),
            };
            format!(
                "{} color={} opacity={}{paint}",
                s.value,
                css_hex(s.color_or_palette(i)),
                s.opacity
            )
        })
        .collect();
    let stats = scene.stats();
    let mut m: Vec<(String, String)> = vec![
        (
            "camera".into(),
            format!(
                "pos={:?} look_at={:?} up={:?} fov_deg={}",
                c.pos, c.look_at, c.up, c.fov_deg
            ),
        ),
        ("field".into(), scene.field_name().to_string()),
        ("isovalues".into(), isos.join("; ")),
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
    if let Some((lo, hi)) = rendered.color_range {
        m.push(("color_range".into(), format!("{lo} {hi}")));
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
