//! The view frustum of a frame in grid coordinates: the half-spaces that hold every primary ray
//! of a `w x h` image (a pyramid from the eye, or a box's sides for an orthographic camera), for
//! extracting only what a view can see.

use crate::camera::{cross, dot, Camera};
use crate::extract::region::HalfSpace;
use crate::trace::GridFrame;

/// The sides of the space a view's primary rays sweep, in grid coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frustum {
    /// Left, top, right and bottom sides, then the camera's plane (what lies behind it is not
    /// seen), normals pointing inside.
    pub sides: [HalfSpace; 5],
}

impl Frustum {
    /// The frustum of `camera` rendering a `w x h` image, in the grid of `frame`: each side
    /// holds two neighbouring corner rays of the image, which bound the rays of every pixel
    /// sample (through the eye for a perspective camera, along the view for an orthographic
    /// one), and the camera's plane closes it.
    pub fn of_camera(camera: &Camera, (w, h): (u32, u32), frame: &GridFrame) -> Frustum {
        let (fw, fh) = (f64::from(w), f64::from(h));
        let corners = [(0.0, fh), (0.0, 0.0), (fw, 0.0), (fw, fh)].map(|(x, y)| {
            let (start, dir) = camera.ray(x, y, w, h);
            (frame.to_grid(start), frame.to_grid_dir(dir))
        });
        let forward = frame.to_grid_dir(camera.forward());
        let eye = frame.to_grid(camera.pos);
        let ahead = [0, 1, 2].map(|a| eye[a] + forward[a]);
        let [left, top, right, bottom] = [0, 1, 2, 3].map(|k| {
            let ((s0, d0), (s1, d1)) = (corners[k], corners[(k + 1) % 4]);
            let n = cross(d0, [0, 1, 2].map(|a| s1[a] + d1[a] - s0[a]));
            let normal = if dot(n, [0, 1, 2].map(|a| ahead[a] - s0[a])) < 0.0 {
                n.map(|x| -x)
            } else {
                n
            };
            HalfSpace { point: s0, normal }
        });
        let near = HalfSpace {
            point: eye,
            normal: forward,
        };
        let sides = [left, top, right, bottom, near];
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
            let d = cam.ray(x, y, 200, 100).1;
            assert!(
                inside([0, 1, 2].map(|a| cam.pos[a] + 7.0 * d[a])),
                "{x} {y}"
            );
        }
    }

    #[test]
    fn an_orthographic_frustum_is_the_box_its_rays_sweep() {
        let frame = GridFrame {
            origin: [0.0; 3],
            unit: [0.5, 0.25, 1.0],
            extent: [8.0, 16.0, 4.0],
        };
        let cam = Camera::new([2.0, -3.0, 2.0], [2.0, 2.0, 2.0], [0.0, 0.0, 1.0], 30.0)
            .unwrap()
            .orthographic(Some(2.0))
            .unwrap();
        let f = Frustum::of_camera(&cam, (200, 100), &frame);
        let inside = |p: [f64; 3]| {
            let g = frame.to_grid(p);
            f.sides.iter().all(|s| s.may_overlap(g, g, 0.0))
        };
        // Two units tall and four wide whatever the depth; nothing behind the camera's plane.
        for y in [-2.9, 0.0, 5.0, 1e3] {
            assert!(inside([2.0, y, 2.0]), "{y}");
            assert!(inside([2.0 + 1.99, y, 2.0 + 0.99]), "{y}");
            assert!(!inside([2.0 + 2.01, y, 2.0]), "{y}");
            assert!(!inside([2.0, y, 2.0 - 1.01]), "{y}");
        }
        assert!(!inside([2.0, -3.1, 2.0]), "behind the camera's plane");
        for (x, y) in [(0.01, 0.01), (199.9, 99.9), (100.0, 0.01)] {
            let (o, d) = cam.ray(x, y, 200, 100);
            assert!(inside([0, 1, 2].map(|a| o[a] + 7.0 * d[a])), "{x} {y}");
        }
    }
}
