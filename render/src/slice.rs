//! Slices: planes through the domain painted with a field through the frame's colour scale,
//! composited with the isosurfaces in depth order (yt's `SlicePlot` inside the 3D view).

use crate::camera::normalize;

/// A plane through the domain, world coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slice {
    /// A point of the plane.
    pub point: [f64; 3],
    /// The plane's unit normal.
    pub normal: [f64; 3],
    /// Opacity in `[0, 1]`; 1 hides what is behind.
    pub opacity: f32,
}

impl Slice {
    /// The plane through `point` with normal `normal` (any length but zero), opaque.
    pub fn new(point: [f64; 3], normal: [f64; 3]) -> Result<Slice, String> {
        if point.iter().chain(&normal).any(|x| !x.is_finite()) {
            return Err(format!("slice plane {point:?} {normal:?} is not finite"));
        }
        let normal = normalize(normal).ok_or("a slice plane's normal must not be zero")?;
        Ok(Slice {
            point,
            normal,
            opacity: 1.0,
        })
    }

    /// Parses `AXIS=VALUE[:OPACITY]` (`z=0.008`): the plane across `AXIS` at `VALUE`.
    pub fn parse_axis(s: &str) -> Result<Slice, String> {
        let (plane, opacity) = split_opacity(s)?;
        let (axis, value) = plane
            .split_once('=')
            .ok_or_else(|| format!("slice '{s}' is not AXIS=VALUE (x=0.5)"))?;
        let a = match axis.trim().to_ascii_lowercase().as_str() {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ => return Err(format!("slice axis '{axis}' in '{s}' is not x, y or z")),
        };
        let v: f64 = value
            .trim()
            .parse()
            .map_err(|_| format!("slice position '{value}' in '{s}' is not a number"))?;
        let mut point = [0.0; 3];
        let mut normal = [0.0; 3];
        point[a] = v;
        normal[a] = 1.0;
        Ok(Slice {
            opacity,
            ..Slice::new(point, normal)?
        })
    }

    /// Parses `PX,PY,PZ,NX,NY,NZ[:OPACITY]`: the plane through `P` with normal `N`.
    pub fn parse_plane(s: &str) -> Result<Slice, String> {
        let (plane, opacity) = split_opacity(s)?;
        let v: Vec<f64> = plane
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("slice plane '{s}' is not PX,PY,PZ,NX,NY,NZ"))?;
        let [px, py, pz, nx, ny, nz] = v[..] else {
            return Err(format!("slice plane '{s}' is not PX,PY,PZ,NX,NY,NZ"));
        };
        Ok(Slice {
            opacity,
            ..Slice::new([px, py, pz], [nx, ny, nz])?
        })
    }

    /// True when the plane meets the world box `lo..hi` (its faces included).
    pub fn meets_box(&self, lo: [f64; 3], hi: [f64; 3]) -> bool {
        let side = |c: usize| -> f64 {
            (0..3)
                .map(|a| {
                    let x = if c >> a & 1 == 1 { hi[a] } else { lo[a] };
                    self.normal[a] * (x - self.point[a])
                })
                .sum()
        };
        let (min, max) = (0..8)
            .map(side)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(m, n), d| {
                (m.min(d), n.max(d))
            });
        min <= 0.0 && max >= 0.0
    }

    /// The ray parameter where the world ray `o + t d` meets the plane, if it does.
    pub fn intersect(&self, o: [f64; 3], d: [f64; 3]) -> Option<f64> {
        let den: f64 = (0..3).map(|a| self.normal[a] * d[a]).sum();
        if den.abs() < 1e-300 {
            return None;
        }
        let num: f64 = (0..3)
            .map(|a| self.normal[a] * (self.point[a] - o[a]))
            .sum();
        Some(num / den)
    }
}

/// Splits an optional `:OPACITY` off `s`.
fn split_opacity(s: &str) -> Result<(&str, f32), String> {
    let Some((plane, o)) = s.rsplit_once(':') else {
        return Ok((s, 1.0));
    };
    let opacity: f32 = o
        .trim()
        .parse()
        .map_err(|_| format!("slice opacity '{o}' in '{s}' is not a number"))?;
    if !(0.0..=1.0).contains(&opacity) {
        return Err(format!(
            "slice opacity {opacity} in '{s}' is outside [0, 1]"
        ));
    }
    Ok((plane, opacity))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planes_meet_a_box_through_it_or_its_faces_only() {
        let (lo, hi) = ([0.0; 3], [1.0, 2.0, 3.0]);
        for (text, meets) in [
            ("z=1.5", true),
            ("z=3", true),
            ("z=0", true),
            ("z=3.0001", false),
            ("x=-1", false),
            ("y=99", false),
        ] {
            let s = Slice::parse_axis(text).unwrap();
            assert_eq!(s.meets_box(lo, hi), meets, "{text}");
        }
        // Diagonal planes: through the far corner, and just beyond it.
        let corner = Slice::new([1.0, 2.0, 3.0], [1.0, 1.0, 1.0]).unwrap();
        assert!(corner.meets_box(lo, hi));
        let beyond = Slice::new([1.0, 2.0, 3.01], [1.0, 1.0, 1.0]).unwrap();
        assert!(!beyond.meets_box(lo, hi));
        let across = Slice::new([5.0, 5.0, 1.0], [1.0, -1.0, 0.0]).unwrap();
        assert!(across.meets_box(lo, hi));
    }

    #[test]
    fn parses_slices() {
        let s = Slice::parse_axis("z=0.25").unwrap();
        assert_eq!(
            (s.point, s.normal, s.opacity),
            ([0.0, 0.0, 0.25], [0.0, 0.0, 1.0], 1.0)
        );
        let s = Slice::parse_axis("X=-1:0.5").unwrap();
        assert_eq!((s.point[0], s.normal[0], s.opacity), (-1.0, 1.0, 0.5));
        let s = Slice::parse_plane("0,0,0,0,3,4").unwrap();
        assert!((s.normal[1] - 0.6).abs() < 1e-12);
        assert!(Slice::parse_axis("w=1").is_err());
        assert!(Slice::parse_axis("z=1:2").is_err());
        assert!(Slice::parse_plane("0,0,0,0,0,0").is_err());
        assert!(Slice::parse_plane("0,0,0,1").is_err());
        assert_eq!(s.intersect([0.0, -5.0, 0.0], [0.0, 1.0, 0.0]), Some(5.0));
    }
}
