//! The camera, perspective (a pinhole) or orthographic: validation of user input, automatic
//! framing, and primary rays.

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
    /// The direction an automatic camera looks from is zero or not finite.
    #[error("--view-from {0:?} is not a direction: give an axis (+x, -z, ...) or a vector that is not zero")]
    NoViewDirection([f64; 3]),
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
    /// An orthographic picture's height is not a positive finite number of world units.
    #[error("--view-height {0} is not a positive, finite length in world units")]
    BadViewHeight(f64),
}

/// How a camera maps the world onto its picture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Rays from the camera's position through the picture's pixels: nearer things look
    /// larger, as the eye sees them.
    Perspective,
    /// Parallel rays along the view, each starting on the plane through the camera's position
    /// square to the view: a length looks as long at every depth, as in a slice plot. The
    /// picture spans `height` world units from top to bottom.
    Orthographic {
        /// The picture's height, world units.
        height: f64,
    },
}

/// Where a world box falls in a camera's image ([`Camera::place_box`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BoxPlacement {
    /// Behind the camera, or in the plane through it square to the view.
    Behind,
    /// In front of the camera, reaching past the image's edges but not into it: `right` is -1
    /// when it lies to the image's left, 1 to its right, 0 across it; `below` likewise, -1
    /// above.
    Outside {
        /// -1 left, 1 right, 0 across the image's width.
        right: i8,
        /// -1 above, 1 below, 0 across the image's height.
        below: i8,
    },
    /// In front of the camera and over the image, spanning `pixels` pixels on its longer side.
    InView {
        /// The box's extent in the image, pixels, on its longer side.
        pixels: f64,
    },
    /// Partly behind the camera and partly in front of it.
    AroundCamera,
}

/// Where the automatic camera looks from, in place of its default view from above the front
/// right: for views along an axis (`--view-from +z`) or any other direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewFrom {
    /// Direction from the framed box's centre to the camera (any length but zero).
    pub dir: [f64; 3],
    /// Up vector (`None`: z, or y when `dir` is along z).
    pub up: Option<[f64; 3]>,
    /// Fit the box's eight corners to the picture (`true`), or the sphere around the box
    /// (`false`), which stays in the picture however the camera turns about the centre, as an
    /// orbit turns it.
    pub tight: bool,
}

/// A validated camera with an orthonormal basis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position, world coordinates: where every ray of a perspective camera starts, the
    /// centre of the plane an orthographic camera's rays start from.
    pub pos: [f64; 3],
    /// The point looked at.
    pub look_at: [f64; 3],
    /// The up vector as given.
    pub up: [f64; 3],
    /// Vertical field of view, degrees (of a perspective camera; an orthographic camera keeps
    /// it for framing).
    pub fov_deg: f64,
    /// Perspective or orthographic.
    pub projection: Projection,
    forward: [f64; 3],
    right: [f64; 3],
    true_up: [f64; 3],
}

impl Camera {
    /// Checks and builds a perspective camera: positions finite, `look_at != pos`, `up` not
    /// parallel to the view direction, `fov_deg` in `(0, 180)`.
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
            projection: Projection::Perspective,
            forward,
            right,
            true_up,
        })
    }

    /// This camera made orthographic, its picture `height` world units tall; `None` makes it as
    /// tall as this camera's perspective picture is at the point looked at (`2 d tan(fov / 2)`
    /// at distance `d`), so that a switch of projection keeps the scale there and moving the
    /// camera nearer zooms in, as it does a perspective camera.
    pub fn orthographic(mut self, height: Option<f64>) -> Result<Camera, CameraError> {
        let height = height.unwrap_or_else(|| {
            2.0 * length(sub(self.look_at, self.pos)) * (0.5 * self.fov_deg).to_radians().tan()
        });
        if !(height > 0.0 && height.is_finite()) {
            return Err(CameraError::BadViewHeight(height));
        }
        self.projection = Projection::Orthographic { height };
        Ok(self)
    }

    /// An orthographic camera's picture height, world units; `None` for a perspective camera.
    pub fn projection_height(&self) -> Option<f64> {
        match self.projection {
            Projection::Orthographic { height } => Some(height),
            Projection::Perspective => None,
        }
    }

    /// True for an orthographic camera.
    pub fn is_orthographic(&self) -> bool {
        matches!(self.projection, Projection::Orthographic { .. })
    }

    /// An orthographic camera that shows box `[lo, hi]` as this perspective camera, looking at
    /// the box's centre, frames it: its picture as tall as holds the box with the same margins
    /// (`tight`: the box's eight corners fitted to the picture, as [`Camera::framing_from`]
    /// fits them; else the sphere around the box, as [`Camera::framing`] fits it), or `height`
    /// tall when given. It stands along the same direction, as far as makes the perspective
    /// picture at the box's centre that tall (so that a placement of it, made orthographic
    /// without a height, is the same camera), and farther when the box needs it to lie wholly
    /// in front of the camera's plane.
    pub fn orthographic_framing(
        &self,
        (lo, hi): ([f64; 3], [f64; 3]),
        aspect: f64,
        tight: bool,
        height: Option<f64>,
    ) -> Result<Camera, CameraError> {
        let centre = self.look_at;
        let corners = box_corners(lo, hi).map(|c| sub(c, centre));
        let fitted = if tight {
            corners.iter().fold(0.0f64, |h, &q| {
                let (x, y) = (dot(q, self.right), dot(q, self.true_up));
                h.max(2.0 * x.abs() / (0.88 * aspect))
                    .max(2.0 * y.abs() / 0.88)
            })
        } else {
            2.04 * 0.5 * length(sub(hi, lo)) / aspect.min(1.0)
        };
        let tan = (0.5 * self.fov_deg).to_radians().tan();
        let size = length(sub(hi, lo));
        let behind = corners
            .iter()
            .fold(0.0f64, |d, &q| d.max(-dot(q, self.forward)));
        let dist = (0.5 * fitted / tan)
            .max(1.02 * behind + 1e-3 * size)
            .max(if size > 0.0 { 1e-3 * size } else { 1.0 });
        let pos = [0, 1, 2].map(|a| centre[a] - self.forward[a] * dist);
        if pos.iter().any(|x| !x.is_finite()) {
            return Err(CameraError::Unframeable { lo, hi });
        }
        // A box without extent (a point) keeps the height its distance gives.
        let height = height.or((fitted > 0.0).then_some(fitted));
        Camera::new(pos, centre, self.up, self.fov_deg)?.orthographic(height)
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

    /// A camera that shows the whole box `[lo, hi]` looking at its centre from `from`, with the
    /// given field of view and aspect ratio (width / height).
    pub fn framing_from(
        lo: [f64; 3],
        hi: [f64; 3],
        from: &ViewFrom,
        fov_deg: f64,
        aspect: f64,
    ) -> Result<Camera, CameraError> {
        let unframeable = CameraError::Unframeable { lo, hi };
        let dir = Some(from.dir)
            .filter(|d| d.iter().all(|x| x.is_finite()))
            .and_then(normalize)
            .ok_or(CameraError::NoViewDirection(from.dir))?;
        let up = match from.up {
            Some(up) => up,
            None if dir[2].abs() > 0.999 => [0.0, 1.0, 0.0],
            None => [0.0, 0.0, 1.0],
        };
        // A camera a unit from the centre along `dir`: its basis is the framing camera's.
        let centre = [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a]));
        if centre.iter().any(|x| !x.is_finite()) {
            return Err(unframeable);
        }
        let probe = Camera::new([0, 1, 2].map(|a| centre[a] + dir[a]), centre, up, fov_deg)?;
        if !from.tight {
            let sphere = Camera::framing(lo, hi, fov_deg, aspect)?;
            let dist = length(sub(sphere.pos, sphere.look_at));
            let pos = [0, 1, 2].map(|a| centre[a] + dir[a] * dist);
            return Camera::new(pos, centre, up, fov_deg);
        }
        // Each corner at depth `dist + z` (z along the view) must lie within the half-widths
        // `tan * depth`, with a margin of 6 % of the picture on each side: room for the
        // coordinate labels along the box's edges.
        let tan_y = 0.88 * (0.5 * fov_deg).to_radians().tan();
        let tan_x = tan_y * aspect;
        let mut dist = 0.0f64;
        for corner in box_corners(lo, hi) {
            let q = sub(corner, centre);
            let (x, y, z) = (
                dot(q, probe.right),
                dot(q, probe.true_up),
                dot(q, probe.forward),
            );
            dist = dist.max(x.abs() / tan_x - z).max(y.abs() / tan_y - z);
        }
        // A box without extent (a single point) is seen from a unit's distance.
        let size = length(sub(hi, lo));
        let dist = dist.max(if size > 0.0 { 1e-3 * size } else { 1.0 });
        let pos = [0, 1, 2].map(|a| centre[a] + dir[a] * dist);
        if pos.iter().any(|x| !x.is_finite()) {
            return Err(unframeable);
        }
        Camera::new(pos, centre, up, fov_deg)
    }

    /// Unit direction of the view.
    pub fn forward(&self) -> [f64; 3] {
        self.forward
    }

    /// Unit vectors to the image's right and up.
    pub fn basis(&self) -> ([f64; 3], [f64; 3]) {
        (self.right, self.true_up)
    }

    /// The ray through image point `(x, y)` in pixels (`y` down) of a `w x h` image: where it
    /// starts and its unit direction.
    pub fn ray(&self, x: f64, y: f64, w: u32, h: u32) -> ([f64; 3], [f64; 3]) {
        self.pixel_dirs(w, h).ray(x, y)
    }

    /// Where world point `p` appears in a `w x h` image, in pixels (`y` down; the image spans
    /// `0..w` and `0..h`, and points outside it give coordinates outside those): the inverse of
    /// [`Camera::ray`]. `None` for a point in the camera's plane or behind it.
    pub fn image_point(&self, p: [f64; 3], w: u32, h: u32) -> Option<[f64; 2]> {
        let d = sub(p, self.pos);
        let depth = dot(d, self.forward);
        if !(depth > 0.0) {
            return None;
        }
        let dirs = self.pixel_dirs(w, h);
        let depth = if dirs.parallel { 1.0 } else { depth };
        let sx = dot(d, self.right) / depth / (dirs.half * dirs.w / dirs.h);
        let sy = dot(d, self.true_up) / depth / dirs.half;
        Some([0.5 * (sx + 1.0) * dirs.w, 0.5 * (1.0 - sy) * dirs.h])
    }

    /// True when the camera sees the outer side of the face of box `[lo, hi]` square to `axis`
    /// on its `high` end (from outside the box, beyond that face's plane; an orthographic
    /// camera, from its direction of view).
    pub fn sees_face(&self, axis: usize, high: bool, (lo, hi): ([f64; 3], [f64; 3])) -> bool {
        match (self.projection, high) {
            (Projection::Perspective, true) => self.pos[axis] > hi[axis],
            (Projection::Perspective, false) => self.pos[axis] < lo[axis],
            (Projection::Orthographic { .. }, true) => self.forward[axis] < 0.0,
            (Projection::Orthographic { .. }, false) => self.forward[axis] > 0.0,
        }
    }

    /// The size of one pixel of an `h` pixels tall image at `distance` from the camera along
    /// a ray, world units (for an orthographic camera, the same at every distance).
    pub fn pixel_size(&self, distance: f64, h: u32) -> f64 {
        let dirs = self.pixel_dirs(1, h);
        let span = if dirs.parallel { 1.0 } else { distance };
        2.0 * dirs.half * span / dirs.h
    }

    /// Where world box `[lo, hi]` falls in a `w x h` image, from its eight corners
    /// ([`Camera::image_point`]): what a frame that shows nothing of a surface inside the box
    /// tells about why.
    pub fn place_box(&self, lo: [f64; 3], hi: [f64; 3], w: u32, h: u32) -> BoxPlacement {
        let points: Vec<Option<[f64; 2]>> = box_corners(lo, hi)
            .into_iter()
            .map(|c| self.image_point(c, w, h))
            .collect();
        if points.iter().all(Option::is_none) {
            return BoxPlacement::Behind;
        }
        let Some(points) = points.into_iter().collect::<Option<Vec<_>>>() else {
            return BoxPlacement::AroundCamera;
        };
        let span = |a: usize| {
            points
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, u), p| {
                    (l.min(p[a]), u.max(p[a]))
                })
        };
        let side = |(l, u): (f64, f64), size: u32| {
            if u < 0.0 {
                -1
            } else if l > f64::from(size) {
                1
            } else {
                0
            }
        };
        let (x, y) = (span(0), span(1));
        match (side(x, w), side(y, h)) {
            (0, 0) => BoxPlacement::InView {
                pixels: (x.1 - x.0).max(y.1 - y.0),
            },
            (right, below) => BoxPlacement::Outside { right, below },
        }
    }

    /// [`Camera::ray`] for many points of one `w x h` image, the picture's extent computed once.
    pub fn pixel_dirs(&self, w: u32, h: u32) -> PixelDirs<'_> {
        let (half, parallel) = match self.projection {
            Projection::Perspective => ((0.5 * self.fov_deg).to_radians().tan(), false),
            Projection::Orthographic { height } => (0.5 * height, true),
        };
        PixelDirs {
            camera: self,
            half,
            parallel,
            w: f64::from(w),
            h: f64::from(h),
        }
    }
}

/// The rays through the points of one image ([`Camera::pixel_dirs`]).
pub struct PixelDirs<'a> {
    camera: &'a Camera,
    /// Half the picture's height: at a unit's distance (perspective) or in world units
    /// (orthographic).
    half: f64,
    /// Orthographic: the rays are parallel and start across the camera's plane.
    parallel: bool,
    w: f64,
    h: f64,
}

impl PixelDirs<'_> {
    /// True when every ray starts at the camera's position (a perspective camera).
    pub fn from_one_point(&self) -> bool {
        !self.parallel
    }

    /// The ray through image point `(x, y)` in pixels (`y` down): its start and unit direction.
    pub fn ray(&self, x: f64, y: f64) -> ([f64; 3], [f64; 3]) {
        let (sx, sy) = (self.across(x), self.down(y));
        (self.start(sx, sy), self.through(sx, sy))
    }

    /// The offset along the image's right vector of the points at `x` pixels from the left
    /// edge, for [`PixelDirs::through`] and [`PixelDirs::start`]: one per column, shared by its
    /// points.
    #[inline]
    pub fn across(&self, x: f64) -> f64 {
        (2.0 * x / self.w - 1.0) * self.half * self.w / self.h
    }

    /// The offset along the image's up vector of the points at `y` pixels from the top edge,
    /// for [`PixelDirs::through`] and [`PixelDirs::start`]: one per row, shared by its points.
    #[inline]
    pub fn down(&self, y: f64) -> f64 {
        (1.0 - 2.0 * y / self.h) * self.half
    }

    /// Unit direction of the ray through the image point with offsets `sx`
    /// ([`PixelDirs::across`]) and `sy` ([`PixelDirs::down`]).
    #[inline]
    pub fn through(&self, sx: f64, sy: f64) -> [f64; 3] {
        let c = self.camera;
        if self.parallel {
            return c.forward;
        }
        let d = [0, 1, 2].map(|a| c.forward[a] + sx * c.right[a] + sy * c.true_up[a]);
        normalize(d).unwrap_or(c.forward)
    }

    /// Where the ray through the image point with offsets `sx` and `sy` starts.
    #[inline]
    pub fn start(&self, sx: f64, sy: f64) -> [f64; 3] {
        let c = self.camera;
        if !self.parallel {
            return c.pos;
        }
        [0, 1, 2].map(|a| c.pos[a] + sx * c.right[a] + sy * c.true_up[a])
    }
}

/// The eight corners of the box `[lo, hi]`, corner `n` taking `hi` on the axes of `n`'s set bits.
pub(crate) fn box_corners(lo: [f64; 3], hi: [f64; 3]) -> [[f64; 3]; 8] {
    std::array::from_fn(|n| std::array::from_fn(|a| if n >> a & 1 == 1 { hi[a] } else { lo[a] }))
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

    /// The pixel coordinates of a box's eight corners seen by `c` in a `w x h` picture.
    fn corners_in_picture(c: &Camera, lo: [f64; 3], hi: [f64; 3], w: u32, h: u32) -> Vec<[f64; 2]> {
        box_corners(lo, hi)
            .into_iter()
            .map(|p| c.image_point(p, w, h).expect("a corner behind the camera"))
            .collect()
    }

    #[test]
    fn a_camera_from_a_direction_fits_the_box_to_the_picture() {
        let boxes = [
            ([0.0; 3], [1.0; 3]),
            ([-3.0, 2.0, 1e6], [5.0, 2.5, 1e6 + 0.01]),
            ([0.0; 3], [1.0, 1.0, 0.05]),
        ];
        let dirs = [
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [1.0, 0.0, 0.0],
            [0.0, -2.0, 0.0],
            [1.0, 1.0, 1.0],
            [-0.3, 0.8, -0.1],
        ];
        for (lo, hi) in boxes {
            for dir in dirs {
                for (w, h) in [(1024, 768), (300, 900), (64, 64)] {
                    let from = ViewFrom {
                        dir,
                        up: None,
                        tight: true,
                    };
                    let c = Camera::framing_from(lo, hi, &from, 40.0, f64::from(w) / f64::from(h))
                        .unwrap();
                    let back = normalize(sub(c.pos, c.look_at)).unwrap();
                    let want = normalize(dir).unwrap();
                    assert!(length(sub(back, want)) < 1e-9, "{dir:?}: {back:?}");
                    // Inside, with the 6 % margin, and touching it on some side.
                    let points = corners_in_picture(&c, lo, hi, w, h);
                    let (w, h) = (f64::from(w), f64::from(h));
                    let inside = |[x, y]: [f64; 2]| {
                        x >= 0.059 * w && x <= 0.941 * w && y >= 0.059 * h && y <= 0.941 * h
                    };
                    assert!(
                        points.iter().all(|&p| inside(p)),
                        "{lo:?} {dir:?}: {points:?}"
                    );
                    let touches = points.iter().any(|&[x, y]| {
                        let m = (x / w).min(1.0 - x / w).min(y / h).min(1.0 - y / h);
                        m < 0.061
                    });
                    assert!(touches, "{lo:?} {dir:?} {w}x{h}: not fitted: {points:?}");
                }
            }
        }
    }

    #[test]
    fn a_camera_from_an_axis_has_a_natural_up_and_a_loose_fit_keeps_the_default_distance() {
        let (lo, hi) = ([0.0; 3], [2.0, 1.0, 1.0]);
        let from = |dir, up, tight| ViewFrom { dir, up, tight };
        // Down on the x-y plane: x to the right, y up, as a map.
        let top =
            Camera::framing_from(lo, hi, &from([0.0, 0.0, 1.0], None, true), 40.0, 1.5).unwrap();
        let (right, up) = top.basis();
        assert!(length(sub(right, [1.0, 0.0, 0.0])) < 1e-12, "{right:?}");
        assert!(length(sub(up, [0.0, 1.0, 0.0])) < 1e-12, "{up:?}");
        // From the front (-y): z up, x to the right.
        let front =
            Camera::framing_from(lo, hi, &from([0.0, -1.0, 0.0], None, true), 40.0, 1.5).unwrap();
        let (right, up) = front.basis();
        assert!(length(sub(right, [1.0, 0.0, 0.0])) < 1e-12, "{right:?}");
        assert!(length(sub(up, [0.0, 0.0, 1.0])) < 1e-12, "{up:?}");
        let given = Camera::framing_from(
            lo,
            hi,
            &from([0.0, 0.0, 1.0], Some([1.0, 0.0, 0.0]), true),
            40.0,
            1.5,
        )
        .unwrap();
        assert!(length(sub(given.basis().1, [1.0, 0.0, 0.0])) < 1e-12);
        let loose =
            Camera::framing_from(lo, hi, &from([0.0, 0.0, 1.0], None, false), 40.0, 1.5).unwrap();
        let default = Camera::framing(lo, hi, 40.0, 1.5).unwrap();
        let dist = |c: &Camera| length(sub(c.pos, c.look_at));
        assert!((dist(&loose) - dist(&default)).abs() < 1e-12);
        assert!(dist(&top) < dist(&loose));
        for bad in [[0.0; 3], [f64::NAN, 0.0, 1.0]] {
            assert!(matches!(
                Camera::framing_from(lo, hi, &from(bad, None, true), 40.0, 1.5),
                Err(CameraError::NoViewDirection(_))
            ));
        }
        assert!(matches!(
            Camera::framing_from(
                lo,
                hi,
                &from([0.0, 0.0, 1.0], Some([0.0, 0.0, 2.0]), true),
                40.0,
                1.5
            ),
            Err(CameraError::BadUp(_))
        ));
    }

    #[test]
    fn centre_pixel_looks_forward() {
        let c = Camera::new([0.0; 3], [0.0, 5.0, 0.0], [0.0, 0.0, 1.0], 60.0).unwrap();
        let d = c.ray(50.0, 50.0, 100, 100).1;
        assert!((d[1] - 1.0).abs() < 1e-12);
        let top = c.ray(50.0, 0.0, 100, 100).1;
        assert!(top[2] > 0.0);
        let right = c.ray(100.0, 50.0, 100, 100).1;
        assert!(right[0] > 0.0);
    }

    #[test]
    fn orthographic_rays_are_parallel_and_start_across_the_cameras_plane() {
        let c = Camera::new([0.0; 3], [0.0, 5.0, 0.0], [0.0, 0.0, 1.0], 60.0).unwrap();
        // As tall as the perspective picture at the point looked at: 2 * 5 * tan(30 degrees).
        let o = c.orthographic(None).unwrap();
        let Projection::Orthographic { height } = o.projection else {
            panic!("not orthographic");
        };
        assert!((height - 10.0 * 30f64.to_radians().tan()).abs() < 1e-12);
        let o = c.orthographic(Some(2.0)).unwrap();
        let (w, h) = (200, 100);
        for (x, y) in [(0.0, 0.0), (100.0, 50.0), (200.0, 100.0), (37.5, 80.0)] {
            let (start, dir) = o.ray(x, y, w, h);
            assert_eq!(dir, o.forward());
            assert_eq!(start[1], 0.0, "on the camera's plane");
            // Two world units tall, four wide: x across, z up.
            assert!((start[0] - (x / 50.0 - 2.0)).abs() < 1e-12, "{start:?}");
            assert!((start[2] - (1.0 - y / 50.0)).abs() < 1e-12, "{start:?}");
        }
        assert_eq!(o.pixel_size(1.0, h), 0.02);
        assert_eq!(o.pixel_size(1e3, h), 0.02);
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                c.orthographic(Some(bad)),
                Err(CameraError::BadViewHeight(_))
            ));
        }
    }

    #[test]
    fn an_orthographic_framing_fits_the_box_in_front_of_the_camera() {
        let boxes = [
            ([0.0; 3], [1.0; 3]),
            ([0.0; 3], [1.0, 1.0, 20.0]),
            ([-3.0, 2.0, 1e6], [5.0, 2.5, 1e6 + 0.01]),
        ];
        let (w, h) = (300, 200);
        for (lo, hi) in boxes {
            for dir in [[0.0, 0.0, 1.0], [1.0, -1.6, 0.9], [0.2, 0.1, -1.0]] {
                for tight in [true, false] {
                    let from = ViewFrom {
                        dir,
                        up: None,
                        tight,
                    };
                    let p = Camera::framing_from(lo, hi, &from, 40.0, 1.5).unwrap();
                    let o = p.orthographic_framing((lo, hi), 1.5, tight, None).unwrap();
                    assert!(o.is_orthographic());
                    assert!((0..3).all(|a| (o.forward()[a] - p.forward()[a]).abs() < 1e-9));
                    for q in corners_in_picture(&o, lo, hi, w, h) {
                        assert!(
                            (0.0..=300.0).contains(&q[0]) && (0.0..=200.0).contains(&q[1]),
                            "{lo:?} {hi:?} {dir:?} {tight}: {q:?}"
                        );
                    }
                    // The fit is exact: the corners reach the margin of 6 % on one axis.
                    if tight {
                        let reach = corners_in_picture(&o, lo, hi, w, h)
                            .iter()
                            .map(|q| (q[0] / 150.0 - 1.0).abs().max((q[1] / 100.0 - 1.0).abs()))
                            .fold(0.0f64, f64::max);
                        assert!(
                            (reach - 0.88).abs() < 1e-9,
                            "{lo:?} {hi:?} {dir:?}: {reach}"
                        );
                    }
                    // A wide field of view frames as tightly: the camera's distance, which
                    // keeps the box in front of it, does not set the height.
                    let wide = Camera::framing_from(lo, hi, &from, 170.0, 1.5).unwrap();
                    let wide = wide
                        .orthographic_framing((lo, hi), 1.5, tight, None)
                        .unwrap();
                    let height = |c: &Camera| match c.projection {
                        Projection::Orthographic { height } => height,
                        Projection::Perspective => panic!("not orthographic"),
                    };
                    assert!((height(&wide) - height(&o)).abs() <= 1e-9 * height(&o));
                    for q in corners_in_picture(&wide, lo, hi, w, h) {
                        assert!((0.0..=300.0).contains(&q[0]) && (0.0..=200.0).contains(&q[1]));
                    }
                }
            }
        }
    }

    #[test]
    fn image_points_invert_rays() {
        let c = Camera::new([0.3, -2.0, 0.7], [0.5, 0.4, 0.2], [0.1, 0.0, 1.0], 35.0).unwrap();
        let (w, h) = (160, 90);
        for cam in [
            c,
            c.orthographic(None).unwrap(),
            c.orthographic(Some(0.01)).unwrap(),
        ] {
            for (x, y) in [(0.0, 0.0), (80.0, 45.0), (159.5, 3.25), (-40.0, 200.0)] {
                let (o, d) = cam.ray(x, y, w, h);
                for t in [0.01, 1.0, 1e3] {
                    let p = [0, 1, 2].map(|a| o[a] + t * d[a]);
                    let [px, py] = cam.image_point(p, w, h).unwrap();
                    assert!(
                        (px - x).abs() < 1e-6 && (py - y).abs() < 1e-6,
                        "{:?} {x},{y} at {t}: {px},{py}",
                        cam.projection
                    );
                }
            }
        }
        let far = |d: [f64; 3], r: f64| {
            let p: [f64; 3] = std::array::from_fn(|a| c.pos[a] + 10.0 * d[a]);
            ([0, 1, 2].map(|a| p[a] - r), [0, 1, 2].map(|a| p[a] + r))
        };
        let (lo, hi) = far(c.ray(80.0, 45.0, w, h).1, 1e-4);
        let BoxPlacement::InView { pixels } = c.place_box(lo, hi, w, h) else {
            panic!("a small box at the centre is in view");
        };
        assert!(pixels > 0.0 && pixels < 1.0, "{pixels}");
        let (lo, hi) = far(c.ray(80.0, 45.0, w, h).1, 1.0);
        assert!(
            matches!(c.place_box(lo, hi, w, h), BoxPlacement::InView { pixels } if pixels > 10.0)
        );
        let (lo, hi) = far(c.ray(-300.0, 45.0, w, h).1, 0.1);
        assert_eq!(
            c.place_box(lo, hi, w, h),
            BoxPlacement::Outside {
                right: -1,
                below: 0
            }
        );
        let (lo, hi) = far(c.ray(400.0, 500.0, w, h).1, 0.1);
        assert_eq!(
            c.place_box(lo, hi, w, h),
            BoxPlacement::Outside { right: 1, below: 1 }
        );
        let (lo, hi) = far(c.forward().map(|v| -v), 1.0);
        assert_eq!(c.place_box(lo, hi, w, h), BoxPlacement::Behind);
        let (lo, hi) = far([0.0; 3], 1.0);
        assert_eq!(c.place_box(lo, hi, w, h), BoxPlacement::AroundCamera);
        let behind = [0, 1, 2].map(|a| c.pos[a] - c.forward()[a]);
        assert_eq!(c.image_point(behind, w, h), None);
        assert_eq!(c.image_point(c.pos, w, h), None);
    }
}
