//! Cameras for many frames of one scene: an orbit around the point looked at, and keyframes
//! with the cameras between them interpolated.

use serde::{Deserialize, Serialize};

use crate::camera::{cross, dot, normalize, Camera};
use crate::error::{RenderError, Result};
use crate::view::CameraPlacement;

/// `frames` cameras on a circle around `start`'s look-at point, about its up vector, starting at
/// `start` and turning by `degrees` in all (positive: counter-clockwise seen from above). A whole
/// number of turns leaves out the last camera (it would repeat the first, and a looped movie
/// would stutter); any other angle ends exactly at `degrees`.
pub fn orbit(start: &Camera, frames: u32, degrees: f64) -> Result<Vec<CameraPlacement>> {
    if frames == 0 || !degrees.is_finite() {
        return Err(RenderError::Invalid(format!(
            "an orbit needs at least one frame and a finite angle (got {frames} frames, {degrees} degrees)"
        )));
    }
    let axis = normalize(start.up).ok_or_else(|| {
        RenderError::Invalid(format!("the camera's up vector {:?} is zero", start.up))
    })?;
    let whole_turns = (degrees / 360.0).fract() == 0.0 && degrees != 0.0;
    let steps = if whole_turns || frames == 1 {
        f64::from(frames)
    } else {
        f64::from(frames - 1)
    };
    let arm = [0, 1, 2].map(|a| start.pos[a] - start.look_at[a]);
    Ok((0..frames)
        .map(|k| {
            let angle = (degrees * f64::from(k) / steps).to_radians();
            let r = rotate(arm, axis, angle);
            CameraPlacement {
                pos: [0, 1, 2].map(|a| start.look_at[a] + r[a]),
                look_at: Some(start.look_at),
                up: Some(start.up),
            }
        })
        .collect())
}

/// `v` turned by `angle` radians about the unit vector `axis` (Rodrigues' formula).
fn rotate(v: [f64; 3], axis: [f64; 3], angle: f64) -> [f64; 3] {
    let (s, c) = angle.sin_cos();
    let k = cross(axis, v);
    let d = dot(axis, v) * (1.0 - c);
    [0, 1, 2].map(|a| v[a] * c + k[a] * s + axis[a] * d)
}

/// A camera fixed at one frame of an animation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraKey {
    /// The frame (from 0).
    pub frame: u32,
    /// Camera position.
    pub pos: [f64; 3],
    /// Point looked at.
    pub look_at: [f64; 3],
    /// Up vector (default: z).
    #[serde(default = "z_up")]
    pub up: [f64; 3],
}

fn z_up() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// The camera of frame `frame` between `keys` (sorted by frame, at least one): position, point
/// looked at and up vector interpolated linearly between the keys around it, held constant
/// before the first and after the last.
pub fn interpolate(keys: &[CameraKey], frame: u32) -> Result<CameraPlacement> {
    let (Some(first), Some(last)) = (keys.first(), keys.last()) else {
        return Err(RenderError::Invalid("no camera keyframes".into()));
    };
    if keys.windows(2).any(|w| w[0].frame >= w[1].frame) {
        return Err(RenderError::Invalid(
            "camera keyframes must have increasing frame numbers".into(),
        ));
    }
    let place = |k: &CameraKey| CameraPlacement {
        pos: k.pos,
        look_at: Some(k.look_at),
        up: Some(k.up),
    };
    if frame <= first.frame {
        return Ok(place(first));
    }
    if frame >= last.frame {
        return Ok(place(last));
    }
    let i = keys.partition_point(|k| k.frame <= frame);
    let (a, b) = (&keys[i - 1], &keys[i]);
    let t = f64::from(frame - a.frame) / f64::from(b.frame - a.frame);
    let lerp = |x: [f64; 3], y: [f64; 3]| [0, 1, 2].map(|c| x[c] + (y[c] - x[c]) * t);
    Ok(CameraPlacement {
        pos: lerp(a.pos, b.pos),
        look_at: Some(lerp(a.look_at, b.look_at)),
        up: Some(lerp(a.up, b.up)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn start() -> Camera {
        Camera::new([3.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0], 40.0).unwrap()
    }

    #[test]
    fn a_whole_turn_keeps_the_radius_height_and_target_and_leaves_out_the_repeat() {
        let path = orbit(&start(), 4, 360.0).unwrap();
        let expect = [[3.0, 0.0], [0.0, 3.0], [-3.0, 0.0], [0.0, -3.0]];
        for (p, e) in path.iter().zip(expect) {
            assert!(
                (p.pos[0] - e[0]).abs() < 1e-12 && (p.pos[1] - e[1]).abs() < 1e-12,
                "{p:?}"
            );
            assert_eq!(p.pos[2], 1.0);
            assert_eq!(p.look_at, Some([0.0, 0.0, 1.0]));
        }
    }

    #[test]
    fn a_partial_orbit_ends_at_its_angle() {
        let path = orbit(&start(), 3, 90.0).unwrap();
        assert_eq!(path.len(), 3);
        let end = path[2].pos;
        assert!(
            end[0].abs() < 1e-12 && (end[1] - 3.0).abs() < 1e-12,
            "{end:?}"
        );
        assert!(orbit(&start(), 0, 90.0).is_err());
    }

    #[test]
    fn keyframes_interpolate_and_hold() {
        let k = |frame, x| CameraKey {
            frame,
            pos: [x, 0.0, 0.0],
            look_at: [0.0, 1.0, 0.0],
            up: z_up(),
        };
        let keys = [k(2, 0.0), k(6, 4.0)];
        assert_eq!(interpolate(&keys, 0).unwrap().pos, [0.0, 0.0, 0.0]);
        assert_eq!(interpolate(&keys, 3).unwrap().pos, [1.0, 0.0, 0.0]);
        assert_eq!(interpolate(&keys, 9).unwrap().pos, [4.0, 0.0, 0.0]);
        assert!(interpolate(&[k(2, 0.0), k(2, 1.0)], 2).is_err());
        assert!(interpolate(&[], 0).is_err());
    }
}
