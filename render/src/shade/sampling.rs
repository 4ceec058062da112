//! Deterministic per-pixel random numbers and direction sampling for anti-aliasing and
//! ambient occlusion: the same image on any number of threads.

/// A small counter-based generator (SplitMix64), seeded from the pixel and sample index.
#[derive(Clone, Copy, Debug)]
pub struct Rng(u64);

impl Rng {
    /// The generator for sample `s` of pixel `(x, y)`.
    pub fn for_pixel(x: u32, y: u32, s: u32) -> Rng {
        Rng((u64::from(x) << 40) ^ (u64::from(y) << 16) ^ u64::from(s) ^ 0x9e37_79b9_7f4a_7c15)
    }

    /// The next number in `[0, 1)`.
    pub fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// A cosine-weighted direction in the hemisphere around the unit vector `n`.
pub fn cosine_hemisphere(n: [f64; 3], u1: f64, u2: f64) -> [f64; 3] {
    let r = u1.sqrt();
    let phi = 2.0 * std::f64::consts::PI * u2;
    let (x, y, z) = (r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt());
    let a = if n[0].abs() > 0.9 {
        [0.0, 1.0, 0.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let t = crate::camera::normalize(crate::camera::cross(a, n)).unwrap_or([0.0, 0.0, 1.0]);
    let b = crate::camera::cross(n, t);
    [0, 1, 2].map(|i| x * t[i] + y * b[i] + z * n[i])
}
