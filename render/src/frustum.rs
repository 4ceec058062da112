//! The view frustum of a frame in grid coordinates: the four half-spaces through the eye that
//! hold every primary ray of a `w x h` image, for extracting only what a view can see.

use crate::camera::{cross, dot, Camera};
use crate::extract::region::HalfSpace;
use crate::trace::GridFrame;

/// The sides of a view's pyramid of primary rays, in grid coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frustum {
    /// Left, top, right and bottom sides, normals pointing inside.
    pub sides: [HalfSpace; 4],
}

impl Frustum {
    /// The frustum of `camera` rendering a `w x h` image, in the grid of `frame`: its sides pass
    /// through the eye and the image's corner rays, which bound the rays of every pixel sample.
    pub fn of_camera(camera: &Camera, (w, h): (u32, u32), frame: &GridFrame) -> Frustum {
        let (fw, fh) = (f64::from(w), f64::from(h));
        let corners = [(0.0, fh), (0.0, 0.0), (fw, 0.0), (fw, fh)]
            .map(|(x, y)| frame.to_grid_dir(camera.ray_dir(x, y, w, h)));
        let forward = frame.to_grid_dir(camera.forward());
        let eye = frame.to_grid(camera.pos);
        let sides = [0, 1, 2, 3].map(|k| {
            let n = cross(corners[k], corners[(k + 1) % 4]);
            let normal = if dot(n, forward) < 0.0 {
                n.map(|x| -x)
            } else {
                n
            };
            HalfSpace { point: eye, normal }
        });
        Frustum { sides }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holds_what_the_camera_sees_and_not_what_is_behind() {
        let frame = GridFrame {
            origin: [0.0; 3],
            unit: [0.5, 0.25, 1.0],
            extent: [8.0, 16.0, 4.0],
        };
        let cam = Camera::new([2.0, -3.0, 2.0], [2.0, 2.0, 2.0], [0.0, 0.0, 1.0], 30.0).unwrap();
        let f = Frustum::of_camera(&cam, (200, 100), &frame);
        let inside = |p: [f64; 3]| {
            let g = frame.to_grid(p);
            f.sides.iter().all(|s| s.may_overlap(g, g, 0.0))
        };
        assert!(inside([2.0, 2.0, 2.0]));
        assert!(!inside([2.0, -4.0, 2.0]), "behind the eye");
        // tan 15 degrees is 0.268: 5 units ahead the image spans +-1.34 high, +-2.68 wide.
        assert!(inside([2.0 + 2.6, 2.0, 2.0]));
        assert!(!inside([2.0 + 2.8, 2.0, 2.0]));
        assert!(inside([2.0, 2.0, 2.0 + 1.3]));
        assert!(!inside([2.0, 2.0, 2.0 + 1.4]));
        for (x, y) in [(0.01, 0.01), (199.9, 99.9), (100.0, 0.01)] {
            let d = cam.ray_dir(x, y, 200, 100);
            assert!(
                inside([0, 1, 2].map(|a| cam.pos[a] + 7.0 * d[a])),
                "{x} {y}"
            );
        }
    }
}
