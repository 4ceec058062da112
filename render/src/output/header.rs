//! The text attributes an EXR frame carries: the camera, the isosurfaces, the method, the
//! timings and the origin of its `P` channels, so that a frame says how it was made.

use crate::render::Rendered;
use crate::scene::Scene;
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
        .map(|s| format!("{}:{:?}:{}", s.value, s.color, s.opacity))
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
    m.extend(extra.iter().map(|(k, v)| ((*k).to_string(), v.clone())));
    m
}
