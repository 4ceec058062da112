//! Pixel samples as flat `f32` records, the unit of every image message (bit for bit: NaN
//! positions and infinite depths survive).

use amr_render::output::frame::PixelSample;

/// `f32` values per pixel record: R, G, B, A, Z, N (3), P (3), level, painted value.
pub const RECORD: usize = 13;

/// Appends `s` to `out` as one record.
pub fn push(out: &mut Vec<f32>, s: &PixelSample) {
    out.extend_from_slice(&s.rgb);
    out.push(s.alpha);
    out.push(s.z);
    out.extend_from_slice(&s.n);
    out.extend_from_slice(&s.p);
    out.push(s.level);
    out.push(s.color_value);
}

/// The sample a record holds (`r` has [`RECORD`] values).
pub fn read(r: &[f32]) -> PixelSample {
    PixelSample {
        rgb: [r[0], r[1], r[2]],
        alpha: r[3],
        z: r[4],
        n: [r[5], r[6], r[7]],
        p: [r[8], r[9], r[10]],
        level: r[11],
        color_value: r[12],
    }
}

/// Exclusive prefix sums of message counts: the displacements of a varcount collective.
pub fn offsets(counts: &[i32]) -> Vec<i32> {
    counts
        .iter()
        .scan(0i32, |at, &c| {
            let d = *at;
            *at += c;
            Some(d)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip_bit_for_bit() {
        let s = PixelSample {
            rgb: [0.1, 0.2, 0.3],
            alpha: 0.5,
            z: 2.5,
            n: [0.0, 1.0, -0.0],
            p: [1.0, 2.0, 3.0],
            level: 2.0,
            color_value: 0.25,
        };
        for s in [s, PixelSample::MISS] {
            let mut v = Vec::new();
            push(&mut v, &s);
            assert_eq!(v.len(), RECORD);
            let back = read(&v);
            let bits = |p: &PixelSample| {
                let mut v = Vec::new();
                push(&mut v, p);
                v.iter().map(|x| x.to_bits()).collect::<Vec<u32>>()
            };
            assert_eq!(bits(&back), bits(&s));
        }
    }
}
