//! Deterministic per-pixel random numbers and direction sampling for anti-aliasing and
//! ambient occlusion: the same image on any number of threads.
//!
//! The ambient-occlusion rays of one hit are not independent: they are a stratified pattern
//! (one ray per band of the cosine-weighted hemisphere's radius, spread in angle by the golden
//! ratio), rotated per pixel by interleaved gradient noise (Jimenez 2014), so that a few rays
//! per hit give about half the error of independent ones and what error is left is fine-grained
//! (`docs/benchmarks-render.md`, "Ambient occlusion pattern").
//!
//! When the ambient occlusion is filtered across pixels ([`crate::shade::ao_filter`]), the
//! pattern is spread over a 4x4 tile of pixels instead: each pixel of the tile takes other
//! strata of one 16-point set, so that the filter, which averages a pixel's neighbours, sees
//! the whole set even at one ray per hit.

/// The golden ratio's inverse: the most evenly spread increment modulo 1.
const GOLDEN: f64 = 0.618_033_988_749_894_9;

/// Pixels per side of the tile the filtered ambient-occlusion pattern is spread over.
pub const TILE: u32 = 4;
/// Strata of the filtered pattern per ray and hit: one per pixel of a tile.
const TILE_STRATA: u32 = TILE * TILE;
/// The order of the strata over a tile (a Bayer matrix): neighbouring pixels take strata far
/// apart, so that any 2x2 block of pixels covers the set evenly.
const TILE_ORDER: [[u32; 4]; 4] = [[0, 8, 2, 10], [12, 4, 14, 6], [3, 11, 1, 9], [15, 7, 13, 5]];
/// Steps of a pixel's stratum from one hit along its ray to the next (coprime to 16).
const STRATA_PER_HIT: u32 = 7;

/// A small counter-based generator (SplitMix64), seeded from the pixel and sample index, and
/// the pixel's rotation of the ambient-occlusion pattern.
#[derive(Clone, Copy, Debug)]
pub struct Rng {
    state: u64,
    /// The rotation of the next hit's ambient-occlusion pattern, in `[0, 1)^2`.
    shift: [f64; 2],
    /// The pixel's stratum in its tile for the next hit.
    stratum: u32,
    /// The rotation of the pixel's tile's pattern about the normal, in `[0, 1)`.
    tile_turn: f64,
}

impl Rng {
    /// The generator for sample `s` of pixel `(x, y)`.
    pub fn for_pixel(x: u32, y: u32, s: u32) -> Rng {
        let state =
            (u64::from(x) << 40) ^ (u64::from(y) << 16) ^ u64::from(s) ^ 0x9e37_79b9_7f4a_7c15;
        let frame = 5.588_238 * f64::from(s);
        let (fx, fy) = (f64::from(x) + frame, f64::from(y) + frame);
        let (tx, ty) = (x / TILE, y / TILE);
        Rng {
            state,
            shift: [
                interleaved_gradient_noise(fx, fy),
                interleaved_gradient_noise(fy + 17.0, fx + 41.0),
            ],
            stratum: TILE_ORDER[(y % TILE) as usize][(x % TILE) as usize],
            tile_turn: interleaved_gradient_noise(f64::from(tx) + frame, f64::from(ty) + frame),
        }
    }

    /// Where in its pixel a sample's ray passes, in `[0, 1)^2`: the centre for one sample per
    /// pixel, else two draws from this generator.
    pub fn subpixel(&mut self, spp: u32) -> (f64, f64) {
        if spp == 1 {
            (0.5, 0.5)
        } else {
            (self.next_f64(), self.next_f64())
        }
    }

    /// The `n` points in `[0, 1)^2` that place the ambient-occlusion rays of one hit when they
    /// are filtered across pixels: the pixel's stratum `k` of the tile's `16 n` points, whose
    /// point `s` lies in the `s`-th of `16 n` equal bands of the first coordinate and at `s`
    /// golden-ratio steps in the second (a Fibonacci lattice), turned per tile in the second.
    /// Point `j` of the pixel is the set's point `k + 16 j`, so that each pixel's own points
    /// are stratified too. Each call moves the pixel to another stratum, the same way in
    /// every pixel, so that the hits behind a transparent surface cover the set as well.
    pub fn ao_tile_pattern(&mut self, n: u32) -> impl Iterator<Item = (f64, f64)> {
        let k = self.stratum;
        self.stratum = (k + STRATA_PER_HIT) % TILE_STRATA;
        let turn = self.tile_turn;
        let total = f64::from(TILE_STRATA * n.max(1));
        (0..n).map(move |j| {
            let s = f64::from(k + TILE_STRATA * j);
            ((s + 0.5) / total, (s * GOLDEN + turn).fract())
        })
    }

    /// The `n` points in `[0, 1)^2` that place the ambient-occlusion rays of one hit: point `k`
    /// lies in the `k`-th of `n` equal bands of the first coordinate and at `k` golden-ratio
    /// steps in the second, the whole set rotated (modulo 1) by the pixel's shift. Each call
    /// moves the shift on, so that the hits behind a transparent surface get another rotation.
    pub fn ao_pattern(&mut self, n: u32) -> impl Iterator<Item = (f64, f64)> {
        let [s0, s1] = self.shift;
        self.shift = [(s0 + GOLDEN).fract(), (s1 + GOLDEN * GOLDEN).fract()];
        let inv = 1.0 / f64::from(n.max(1));
        (0..n).map(move |k| {
            let k = f64::from(k);
            ((k * inv + s0).fract(), (k * GOLDEN + s1).fract())
        })
    }

    /// The next number in `[0, 1)`.
    pub fn next_f64(&mut self) -> f64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Interleaved gradient noise at pixel `(x, y)`: a value in `[0, 1)` that differs strongly
/// between neighbouring pixels, so that patterns rotated by it leave fine-grained noise.
fn interleaved_gradient_noise(x: f64, y: f64) -> f64 {
    (52.982_918_9 * (0.067_110_56 * x + 0.005_837_15 * y).fract()).fract()
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
    let along = |i: usize| x * t[i] + y * b[i] + z * n[i];
    [along(0), along(1), along(2)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ao_pattern_puts_one_point_in_each_band_and_moves_on_per_hit() {
        for (x, y) in [(0, 0), (3, 7), (640, 481)] {
            let mut rng = Rng::for_pixel(x, y, 0);
            for n in [1, 2, 4, 7, 16] {
                let first: Vec<(f64, f64)> = rng.ao_pattern(n).collect();
                assert_eq!(first.len(), n as usize);
                let mut u: Vec<f64> = first.iter().map(|p| p.0).collect();
                u.sort_by(f64::total_cmp);
                for w in u.windows(2) {
                    assert!((w[1] - w[0] - 1.0 / f64::from(n)).abs() < 1e-9, "{u:?}");
                }
                assert!(first
                    .iter()
                    .all(|&(a, b)| (0.0..1.0).contains(&a) && (0.0..1.0).contains(&b)));
                let next: Vec<(f64, f64)> = rng.ao_pattern(n).collect();
                assert_ne!(first, next);
            }
        }
    }

    #[test]
    fn a_tile_covers_every_stratum_of_the_filtered_pattern_once() {
        for n in [1, 2, 4] {
            for hit in 0..3 {
                let mut u: Vec<f64> = (0..TILE * TILE)
                    .flat_map(|i| {
                        let mut rng = Rng::for_pixel(8 + i % TILE, 4 + i / TILE, 0);
                        for _ in 0..hit {
                            let _ = rng.ao_tile_pattern(n).count();
                        }
                        rng.ao_tile_pattern(n).map(|p| p.0).collect::<Vec<_>>()
                    })
                    .collect();
                u.sort_by(f64::total_cmp);
                let total = f64::from(TILE * TILE * n);
                for (s, v) in u.iter().enumerate() {
                    assert!(
                        (v - (s as f64 + 0.5) / total).abs() < 1e-12,
                        "{n} {hit} {u:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn neighbouring_pixels_get_different_rotations() {
        let a = Rng::for_pixel(10, 10, 0).shift;
        let b = Rng::for_pixel(11, 10, 0).shift;
        let c = Rng::for_pixel(10, 11, 0).shift;
        assert!((a[0] - b[0]).abs() > 1e-3 && (a[0] - c[0]).abs() > 1e-3);
        assert_eq!(a, Rng::for_pixel(10, 10, 0).shift);
    }
}
