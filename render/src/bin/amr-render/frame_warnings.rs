//! Warnings about what a frame shows: a slice that misses the domain, an isovalue outside its
//! field's range, a camera inside a closed surface, a frame with no surface, with why; and a
//! note on a picture too small for its legend.

use std::path::Path;

use amr_render::camera::{BoxPlacement, Camera, Projection};
use amr_render::field_stats::{format_isovalue, format_value, format_vector};
use amr_render::output::legend::Legend;
use amr_render::shade::IsoSpec;
use amr_render::{enclosing_surface, Scene, View};

use crate::frames::surface_value;

/// Warns about each slice plane that misses the domain: it shows nothing.
pub(crate) fn warn_slices_outside(scene: &Scene) {
    let frame = scene.grid_frame();
    let lo = frame.origin;
    let hi: [f64; 3] = std::array::from_fn(|a| lo[a] + frame.extent[a] * frame.unit[a]);
    for (slice, _) in scene.slices() {
        if !slice.meets_box(lo, hi) {
            eprintln!(
                "warning: {}: the slice through {} with normal {} misses the domain {} .. {}: it shows nothing",
                scene.path().display(),
                format_vector(slice.point),
                format_vector(slice.normal),
                format_vector(lo),
                format_vector(hi)
            );
        }
    }
}

/// Warns when the camera is enclosed by one of the surfaces, so that the frame shows nothing but
/// that surface's inside (a frame every pixel of which shows a surface, as here, may also be a
/// close-up); returns whether it warned.
pub(crate) fn warn_enclosed(scene: &Scene, view: &View, camera: &Camera) -> anyhow::Result<bool> {
    let Some(i) = enclosing_surface(scene, view, camera.pos)? else {
        return Ok(false);
    };
    let s = &scene.isosurfaces()[i];
    eprintln!(
        "warning: {}: the camera at {} is enclosed by the surface {} = {}, which every ray \
         from it meets: the frame shows only its inside; place the camera outside it \
         (--camera-pos) or cut it open (--clip)",
        scene.path().display(),
        format_vector(camera.pos),
        scene.surface_field_name(s),
        format_isovalue(s.value),
    );
    Ok(true)
}

/// Warns about each isovalue outside its field's range: its surface is empty, while the frame
/// shows the others (or slices), so nothing else would say so.
pub(crate) fn warn_isos_outside(scene: &Scene, isos: &[IsoSpec]) {
    for iso in isos {
        let f = &scene.file().fields()[scene.surface_field(iso)];
        if !(iso.value < f.min || iso.value > f.max) {
            continue;
        }
        eprintln!(
            "warning: {}: isovalue {} lies outside {}'s range [{}, {}]: that surface is empty",
            scene.path().display(),
            format_isovalue(iso.value),
            f.name,
            format_value(f64::from(f.min)),
            format_value(f64::from(f.max))
        );
    }
}

/// Warns that a frame shows no surface: with the field's range when there is none to show,
/// else with where the surface lies and why a `size` frame of `camera` misses it (behind the
/// camera, outside the frame, or smaller than a pixel), and what to change.
pub(crate) fn warn_empty(scene: &Scene, camera: &Camera, (w, h): (u32, u32)) {
    let active = scene.stats().active_octants;
    let bounds = match active {
        0 => None,
        _ => scene.surface_bounds().ok().flatten(),
    };
    if let Some((lo, hi)) = bounds {
        let centre: [f64; 3] = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]));
        let centre = centre.map(format_value).join(",");
        let look_there = format!("look at them (--look-at {centre})");
        let why = match camera.place_box(lo, hi, w, h) {
            BoxPlacement::Behind => format!("they are behind it: {look_there}"),
            BoxPlacement::Outside { right, below } => {
                let side = [
                    (right, "to its left", "to its right"),
                    (below, "above it", "below it"),
                ]
                .iter()
                .filter(|(s, ..)| *s != 0)
                .map(|&(s, before, after)| if s < 0 { before } else { after })
                .collect::<Vec<_>>()
                .join(" and ");
                let widen = match camera.projection {
                    Projection::Perspective => "widen the field of view (--fov)".to_string(),
                    Projection::Orthographic { height } => format!(
                        "make the view taller than its {} (--view-height)",
                        format_value(height)
                    ),
                };
                format!("they lie outside the frame, {side}: {look_there} or {widen}")
            }
            BoxPlacement::InView { pixels } if pixels < 2.0 => format!(
                "they span {} of its {w}x{h} frame {}",
                match pixels < 1.0 {
                    true => "less than a pixel".to_string(),
                    false => format!("{pixels:.1} pixels"),
                },
                match camera.projection {
                    Projection::Perspective => format!(
                        "with a {}-degree field of view: move the camera closer \
                         (--camera-pos) or narrow the field of view (--fov)",
                        camera.fov_deg
                    ),
                    Projection::Orthographic { height } => format!(
                        "{} tall: make the view shorter (--view-height)",
                        format_value(height)
                    ),
                }
            ),
            BoxPlacement::AroundCamera => {
                format!("they lie beside or around it, out of its view: {look_there}")
            }
            BoxPlacement::InView { .. } => match extreme_isovalue(scene) {
                Some(why) => why,
                None => "the surface inside them passes between its rays: move the camera \
                         closer (--camera-pos) or enlarge the frame (--size)"
                    .to_string(),
            },
        };
        eprintln!(
            "warning: {}: the frame shows none of the surface's {active} active voxels, which lie \
             in {} .. {}; for the camera at {} looking at {}, {why}",
            scene.path().display(),
            format_vector(lo),
            format_vector(hi),
            format_vector(camera.pos),
            format_vector(camera.look_at)
        );
        return;
    }
    if !scene.one_field() {
        let isos: Vec<String> = scene
            .isosurfaces()
            .iter()
            .map(|s| {
                let f = &scene.file().fields()[scene.surface_field(s)];
                format!(
                    "{} ({} ranges over [{}, {}])",
                    surface_value(scene, s),
                    f.name,
                    format_value(f64::from(f.min)),
                    format_value(f64::from(f.max))
                )
            })
            .collect();
        eprintln!(
            "warning: {}: the frame shows no surface: the isovalues are {} ({active} active voxels)",
            scene.path().display(),
            isos.join(", "),
        );
        return;
    }
    let f = &scene.file().fields()[scene.field()];
    let isos: Vec<String> = scene
        .isosurfaces()
        .iter()
        .map(|s| surface_value(scene, s))
        .collect();
    eprintln!(
        "warning: {}: the frame shows no surface: {} ranges over [{}, {}] and the isovalues are {} ({} active voxels)",
        scene.path().display(),
        f.name,
        format_value(f64::from(f.min)),
        format_value(f64::from(f.max)),
        isos.join(", "),
        active
    );
}

/// Why a surface in view shows nothing when its isovalue is at or within a thousandth of its
/// field's range from the field's largest or smallest value: the surface is then a speck around
/// where the field peaks (or a set of points at the extreme itself), which the rays pass by.
fn extreme_isovalue(scene: &Scene) -> Option<String> {
    scene.isosurfaces().iter().find_map(|s| {
        let f = &scene.file().fields()[scene.surface_field(s)];
        let (min, max) = (f64::from(f.min), f64::from(f.max));
        let near = 1e-3 * (max - min);
        let value = f64::from(s.value);
        let (which, extreme, exact, instead) = match value {
            v if v >= max - near => ("largest", max, f.max, "below"),
            v if v <= min + near => ("smallest", min, f.min, "above"),
            _ => return None,
        };
        let at = match value == extreme {
            true => "is".to_string(),
            false => format!("lies within {} of", format_value((value - extreme).abs())),
        };
        Some(format!(
            "the isovalue {} {at} {}'s {which} value, {}: the surface is a speck around where \
             the field reaches it, which the rays pass by; take a value further {instead} it, or \
             move the camera close to it (--camera-pos)",
            surface_value(scene, s),
            f.name,
            format_isovalue(exact)
        ))
    })
}

/// Notes when a `size` picture, written to `png`, has no room for `legend`, which is then left
/// out, with the smallest size of its shape that holds it; returns whether it noted.
pub(crate) fn note_no_room_for_legend(png: &Path, legend: &Legend, size: (u32, u32)) -> bool {
    if legend.fits(size.0, size.1) {
        return false;
    }
    let larger = match legend.smallest_fitting_size(size) {
        Some((w, h)) => format!("; it fits from --size {w}x{h}"),
        None => String::new(),
    };
    eprintln!(
        "note: {}: a {}x{} picture has no room for its legend, which is left out{larger}",
        png.display(),
        size.0,
        size.1
    );
    true
}
