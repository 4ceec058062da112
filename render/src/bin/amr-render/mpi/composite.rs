//! Sort-last compositing of the partitioned mode's partial frames by direct send: the image is
//! cut into one band of rows per rank, every rank sends each band of its frame to the band's
//! rank, which composites the band from all parts, and rank 0 gathers the bands.
//!
//! Colour and coverage are composited front to back in rank order, which is the parts'
//! visibility order ([`super::partition`]); the first-hit channels (Z, N, P, level) come from the
//! part with the nearest hit (a depth composite).

use ::mpi::datatype::{Partition, PartitionMut};
use ::mpi::topology::SimpleCommunicator;
use ::mpi::traits::*;
use anyhow::bail;

use super::pixels::{self, offsets, RECORD};
use amr_render::output::frame::{FrameBuffer, PixelSample};

/// One pixel from its samples in the parts, front to back.
pub fn over(parts: impl IntoIterator<Item = PixelSample>) -> PixelSample {
    let mut out = PixelSample::MISS;
    let mut rgb = [0.0f32; 3];
    let mut transmittance = 1.0f32;
    for p in parts {
        for (acc, c) in rgb.iter_mut().zip(p.rgb) {
            *acc += transmittance * c;
        }
        transmittance *= 1.0 - p.alpha;
        if p.z < out.z {
            out = p;
        }
    }
    out.rgb = rgb;
    out.alpha = 1.0 - transmittance;
    out
}

/// The rows `[lo, hi)` of band `b` of `h` rows cut into `n` bands.
fn band(b: usize, n: usize, h: usize) -> (usize, usize) {
    (b * h / n, (b + 1) * h / n)
}

/// Counts and displacements (in `f32` values) of the `n` bands of a `w x h` frame.
fn band_layout(n: usize, w: usize, h: usize) -> anyhow::Result<(Vec<i32>, Vec<i32>)> {
    if (w * h * RECORD) > i32::MAX as usize {
        bail!("a {w}x{h} frame is too large for one MPI message (at most 2^31 values)");
    }
    let counts: Vec<i32> = (0..n)
        .map(|b| {
            let (lo, hi) = band(b, n, h);
            ((hi - lo) * w * RECORD) as i32
        })
        .collect();
    let displs = offsets(&counts);
    Ok((counts, displs))
}

/// Composites every rank's partial frame `fb` (all of one size); returns the frame on rank 0,
/// `None` elsewhere, and the bytes this rank sent.
pub fn direct_send(
    world: &SimpleCommunicator,
    fb: &FrameBuffer,
) -> anyhow::Result<(Option<FrameBuffer>, u64)> {
    let n = world.size() as usize;
    let me = world.rank() as usize;
    let (w, h) = (fb.width as usize, fb.height as usize);
    let (counts, displs) = band_layout(n, w, h)?;
    let mut send = Vec::with_capacity(w * h * RECORD);
    for i in 0..w * h {
        pixels::push(&mut send, &fb.sample(i));
    }
    let (lo, hi) = band(me, n, h);
    let mine = (hi - lo) * w;
    let mut recv = vec![0.0f32; mine * RECORD * n];
    let recv_counts = vec![(mine * RECORD) as i32; n];
    let recv_displs: Vec<i32> = (0..n).map(|k| (k * mine * RECORD) as i32).collect();
    {
        let sbuf = Partition::new(&send[..], &counts[..], &displs[..]);
        let mut rbuf = PartitionMut::new(&mut recv[..], &recv_counts[..], &recv_displs[..]);
        world.all_to_all_varcount_into(&sbuf, &mut rbuf);
    }
    let mut sent = 4 * (send.len() - counts[me] as usize) as u64;
    drop(send);
    let mut band_out = Vec::with_capacity(mine * RECORD);
    for i in 0..mine {
        let parts = (0..n).map(|k| pixels::read(&recv[(k * mine + i) * RECORD..][..RECORD]));
        pixels::push(&mut band_out, &over(parts));
    }
    drop(recv);
    let root = world.process_at_rank(0);
    if me != 0 {
        root.gather_varcount_into(&band_out[..]);
        sent += 4 * band_out.len() as u64;
        return Ok((None, sent));
    }
    let mut all = vec![0.0f32; w * h * RECORD];
    {
        let mut rbuf = PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
        root.gather_varcount_into_root(&band_out[..], &mut rbuf);
    }
    let samples: Vec<PixelSample> = all.chunks(RECORD).map(pixels::read).collect();
    let frame = FrameBuffer::from_pixels(fb.width, fb.height, &samples, fb.p_origin);
    Ok((Some(frame), sent))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(rgb: f32, alpha: f32, z: f32) -> PixelSample {
        PixelSample {
            rgb: [rgb; 3],
            alpha,
            z,
            n: [0.0, 0.0, 1.0],
            p: [z; 3],
            level: 1.0,
            color_value: f32::NAN,
        }
    }

    #[test]
    fn over_is_front_to_back_with_the_nearest_first_hit() {
        let front = sample(0.25, 0.5, 3.0);
        let back = sample(0.8, 1.0, 2.0);
        let c = over([front, PixelSample::MISS, back]);
        assert_eq!(c.rgb, [0.25 + 0.5 * 0.8; 3]);
        assert_eq!(c.alpha, 1.0);
        assert_eq!(c.z, 2.0);
        assert_eq!(c.p, [2.0; 3]);
        let none = over([PixelSample::MISS, PixelSample::MISS]);
        assert_eq!(none.alpha, 0.0);
        assert!(none.z.is_infinite() && none.p[0].is_nan() && none.level == -1.0);
    }

    #[test]
    fn bands_cover_the_frame() {
        let (counts, displs) = band_layout(3, 5, 7).unwrap();
        assert_eq!(counts.iter().sum::<i32>() as usize, 5 * 7 * RECORD);
        assert_eq!(displs[0], 0);
        assert_eq!(displs[2], counts[0] + counts[1]);
    }
}
