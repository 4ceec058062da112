//! A pinhole camera: validation of user input, automatic framing, and primary rays.

use thiserror::Error;

/// Why a camera cannot be used.
#[derive(Debug, Error, PartialEq)]
pub enum CameraError {
    /// A coordinate is NaN or infinite.
    #[error("camera {what} {value:?} is not finite")]
    NotFinite {
        /// Which vector.
        what: &'static str,
        /// Its value.
        value: [f64; 3],
    },
    /// The camera looks at its own position.
    #[error("--look-at equals --camera-pos ({0:?}): the view direction is undefined")]
    NoDirection([f64; 3]),
    /// The up vector is zero or parallel to the view direction.
    #[error("--up {0:?} is zero or parallel to the view direction; give a vector across it")]
    BadUp([f64; 3]),
    /// The field of view is outside `(0, 180)` degrees.
    #[error("--fov {0} is outside (0, 180) degrees")]
    BadFov(f64),
    /// Automatic framing of a domain failed: its size overflows the camera's arithmetic.
    #[error("the domain {lo:?}..{hi:?} is too large to frame automatically; place the camera with --camera-pos")]
    Unframeable {
        /// Lower corner.
        lo: [f64; 3],
        /// Upper corner.
        hi: [f64; 3],
    },
    /// The image has no pixels.
    #[error("image size {0}x{1} has no pixels")]
    EmptyImage(u32, u32),
}

/// A validated pinhole camera with an orthonormal basis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position, world coordinates.
    pub pos: [f64; 3],
    /// The point looked at.
    pub look_at: [f64; 3],
    /// The up vector as given.
    pub up: [f64; 3],
    /// Vertical field of view, degrees.
    pub fov_deg: f64,
    forward: [f64; 3],
    right: [f64; 3],
    true_up: [f64; 3],
}

impl Camera {
    /// Checks and builds a camera: positions finite, `look_at != pos`, `up` not parallel to the
    /// view direction, `fov_deg` in `(0, 180)`.
    pub fn new(
        pos: [f64; 3],
        look_at: [f64; 3],
        up: [f64; 3],
        fov_deg: f64,
    ) -> Result<Camera, CameraError> {
        for (what, value) in [("position", pos), ("look-at", look_at), ("up", up)] {
            if value.iter().any(|x| !x.is_finite()) {
                return Err(CameraError::NotFinite { what, value });
            }
        }
        if !(fov_deg > 0.0 && fov_deg < 180.0) {
            return Err(CameraError::BadFov(fov_deg));
        }
        let forward = normalize(sub(look_at, pos)).ok_or(CameraError::NoDirection(pos))?;
        let right = normalize(cross(forward, up)).ok_or(CameraError::BadUp(up))?;
        if length(cross(forward, normalize(up).ok_or(CameraError::BadUp(up))?)) < 1e-9 {
            return Err(CameraError::BadUp(up));
        }
        let true_up = cross(right, forward);
        Ok(Camera {
            pos,
            look_at,
            up,
            fov_deg,
            forward,
            right,
            true_up,
        })
    }

    /// A camera that shows the whole box `[lo, hi]` with the given field of view, looking at its
    /// centre from above the front right, with z up.
    pub fn framing(
        lo: [f64; 3],
        hi: [f64; 3],
        fov_deg: f64,
        aspect: f64,
    ) -> Result<Camera, CameraError> {
        let centre = [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a]));
        let radius = 0.5 * length(sub(hi, lo));
        let half = (0.5 * fov_deg).to_radians();
        let half_h = (half.tan() * aspect.min(1.0)).atan();
        let dist = radius / half_h.sin() * 1.02;
        let dir = normalize([1.0, -1.6, 0.9]).unwrap_or([1.0, 0.0, 0.0]);
        let pos = [0, 1, 2].map(|a| centre[a] + dir[a] * dist);
        if pos.iter().chain(&centre).any(|x| !x.is_finite()) {
            return Err(CameraError::Unframeable { lo, hi });
        }
        Camera::new(pos, centre, [0.0, 0.0, 1.0], fov_deg)
    }

    /// Unit direction of the view.
    pub fn forward(&self) -> [f64; 3] {
        self.forward
    }

    /// Unit vectors to the image's right and up.
    pub fn basis(&self) -> ([f64; 3], [f64; 3]) {
        (self.right, self.true_up)
    }

    /// Unit direction through image point `(x, y)` in pixels (`y` down) of a `w x h` image.
    pub fn ray_dir(&self, x: f64, y: f64, w: u32, h: u32) -> [f64; 3] {
        self.pixel_dirs(w, h).dir(x, y)
    }

    /// [`Camera::ray_dir`] for many points of one `w x h` image, the field of view's tangent
    /// computed once.
    pub fn pixel_dirs(&self, w: u32, h: u32) -> PixelDirs<'_> {
        PixelDirs {
            camera: self,
            tan: (0.5 * self.fov_deg).to_radians().tan(),
            w: f64::from(w),
            h: f64::from(h),
        }
    }
}

/// The directions through the points of one image ([`Camera::pixel_dirs`]).
pub struct PixelDirs<'a> {
    camera: &'a Camera,
    tan: f64,
    w: f64,
    h: f64,
}

impl PixelDirs<'_> {
    /// The camera's position, where every ray starts.
    pub fn origin(&self) -> [f64; 3] {
        self.camera.pos
    }

    /// Unit direction through image point `(x, y)` in pixels (`y` down).
    pub fn dir(&self, x: f64, y: f64) -> [f64; 3] {
        self.through(self.across(x), self.down(y))
    }

    /// The offset along the image's right vector of the points at `x` pixels from the left
    /// edge, for [`PixelDirs::through`]: one per column, shared by its points.
    #[inline]
    pub fn across(&self, x: f64) -> f64 {
        (2.0 * x / self.w - 1.0) * self.tan * self.w / self.h
    }

    /// The offset along the image's up vector of the points at `y` pixels from the top edge,
    /// for [`PixelDirs::through`]: one per row, shared by its points.
    #[inline]
    pub fn down(&self, y: f64) -> f64 {
        (1.0 - 2.0 * y / self.h) * self.tan
    }

    /// Unit direction through the image point with offsets `sx` ([`PixelDirs::across`]) and
    /// `sy` ([`PixelDirs::down`]).
    #[inline]
    pub fn through(&self, sx: f64, sy: f64) -> [f64; 3] {
        let c = self.camera;
        let d = [0, 1, 2].map(|a| c.forward[a] + sx * c.right[a] + sy * c.true_up[a]);
        normalize(d).unwrap_or(c.forward)
    }
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(crate) fn length(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// `a / |a|`, or `None` for a zero or non-finite vector. The vector is scaled by its largest
/// component first, so that vectors near the ends of the `f64` range (whose squared length
/// overflows or underflows) still have a direction.
#[inline]
pub(crate) fn normalize(a: [f64; 3]) -> Option<[f64; 3]> {
    let l = length(a);
    if l.is_normal() {
        return Some(a.map(|x| x / l));
    }
    normalize_scaled(a)
}

/// [`normalize`] for a vector whose squared length is not a normal number.
#[cold]
#[inline(never)]
fn normalize_scaled(a: [f64; 3]) -> Option<[f64; 3]> {
    let m = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if !(m > 0.0 && m.is_finite()) {
        return None;
    }
    let b = a.map(|x| x / m);
    let l = length(b);
    Some(b.map(|x| x / l))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn impossible_cameras_are_refused() {
        let o = [0.0; 3];
        let x = [1.0, 0.0, 0.0];
        assert_eq!(
            Camera::new(o, o, [0.0, 0.0, 1.0], 40.0),
            Err(CameraError::NoDirection(o))
        );
        assert_eq!(
            Camera::new(o, x, [0.0; 3], 40.0),
            Err(CameraError::BadUp([0.0; 3]))
        );
        assert_eq!(
            Camera::new(o, x, [2.0, 0.0, 0.0], 40.0),
            Err(CameraError::BadUp([2.0, 0.0, 0.0]))
        );
        assert_eq!(
            Camera::new(o, x, [0.0, 0.0, 1.0], 0.0),
            Err(CameraError::BadFov(0.0))
        );
        assert_eq!(
            Camera::new(o, x, [0.0, 0.0, 1.0], 180.0),
            Err(CameraError::BadFov(180.0))
        );
        assert!(matches!(
            Camera::new(o, x, [0.0, 0.0, 1.0], f64::NAN),
            Err(CameraError::BadFov(_))
        ));
        assert!(matches!(
            Camera::new([f64::NAN, 0.0, 0.0], x, [0.0, 0.0, 1.0], 40.0),
            Err(CameraError::NotFinite { .. })
        ));
    }

    #[test]
    fn extreme_but_finite_cameras_have_a_direction() {
        let far = Camera::new([1e308, 0.0, 0.0], [0.5; 3], [0.0, 0.0, 1.0], 40.0).unwrap();
        assert!((far.forward()[0] + 1.0).abs() < 1e-12);
        let near = Camera::new([1e-300, 0.0, 0.0], [0.0; 3], [0.0, 0.0, 1.0], 40.0).unwrap();
        assert!((near.forward()[0] + 1.0).abs() < 1e-12);
        let huge = Camera::framing([0.0; 3], [1e308; 3], 40.0, 1.0);
        assert!(
            matches!(huge, Err(CameraError::Unframeable { .. })),
            "{huge:?}"
        );
    }

    #[test]
    fn centre_pixel_looks_forward() {
        let c = Camera::new([0.0; 3], [0.0, 5.0, 0.0], [0.0, 0.0, 1.0], 60.0).unwrap();
        let d = c.ray_dir(50.0, 50.0, 100, 100);
        assert!((d[1] - 1.0).abs() < 1e-12);
        let top = c.ray_dir(50.0, 0.0, 100, 100);
        assert!(top[2] > 0.0);
        let right = c.ray_dir(100.0, 50.0, 100, 100);
        assert!(right[0] > 0.0);
    }
}
