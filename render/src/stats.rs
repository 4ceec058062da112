//! Typed statistics of a frame, and the serializers that give their JSON keys the units and
//! precision the `--stats-json` files have always had (`extract_ms` with three decimals, ...).

use std::time::Duration;

use serde::{Serialize, Serializer};

/// What rendering one frame cost and what it shows.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FrameStats {
    /// Frame time.
    #[serde(rename = "render_ms", serialize_with = "millis")]
    pub render: Duration,
    /// Ray queries (one per ray and isosurface).
    pub rays: u64,
    /// Ray queries per second of frame time.
    #[serde(serialize_with = "whole")]
    pub rays_per_second: f64,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Pixels that show a surface.
    pub covered_pixels: u64,
}

impl FrameStats {
    /// The statistics of a frame of `width x height` that took `render` for `rays` queries
    /// and covered `covered_pixels`.
    pub fn new(
        render: Duration,
        rays: u64,
        (width, height): (u32, u32),
        covered_pixels: u64,
    ) -> Self {
        FrameStats {
            render,
            rays,
            rays_per_second: rays as f64 / render.as_secs_f64().max(1e-9),
            width,
            height,
            covered_pixels,
        }
    }
}

/// Milliseconds of `d`.
pub fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// `bytes / octants`, with no octants counted as one.
pub fn per_octant(bytes: u64, octants: u64) -> f64 {
    bytes as f64 / octants.max(1) as f64
}

/// Serializes a duration as milliseconds with three decimals.
pub fn millis<S: Serializer>(d: &Duration, s: S) -> Result<S::Ok, S::Error> {
    rounded(ms(*d), 1e3, s)
}

/// Serializes a number with two decimals.
pub fn two_decimals<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
    rounded(*v, 1e2, s)
}

/// Serializes a number rounded to a whole one (`null` when not finite).
pub fn whole<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
    if !v.is_finite() {
        return s.serialize_none();
    }
    s.serialize_i64(v.round() as i64)
}

/// `v` rounded to `1 / scale` (non-finite values as `null`).
fn rounded<S: Serializer>(v: f64, scale: f64, s: S) -> Result<S::Ok, S::Error> {
    if !v.is_finite() {
        return s.serialize_none();
    }
    s.serialize_f64((v * scale).round() / scale)
}
