//! Brick encodings: raw little-endian f32, or zstd over the f32 bytes shuffled into byte planes.
//!
//! Shuffling puts the four bytes of every value into four planes (all low bytes, then all
//! second bytes, ...). Neighbouring values of a smooth field share their high bytes, so the
//! planes compress far better than interleaved floats do.

use crate::error::{FormatError, Result};
use crate::raw::{ENCODING_RAW, ENCODING_ZSTD_SHUFFLED};

/// How one brick's values are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// Raw little-endian f32, x fastest ([`ENCODING_RAW`]).
    Raw,
    /// One zstd frame over the byte-shuffled f32 ([`ENCODING_ZSTD_SHUFFLED`]).
    ZstdShuffled,
}

impl Encoding {
    /// The encoding stored as `tag`, `None` for an unknown tag.
    pub fn from_raw(tag: u32) -> Option<Self> {
        match tag {
            ENCODING_RAW => Some(Encoding::Raw),
            ENCODING_ZSTD_SHUFFLED => Some(Encoding::ZstdShuffled),
            _ => None,
        }
    }

    /// The tag stored in the file.
    pub fn raw(self) -> u32 {
        match self {
            Encoding::Raw => ENCODING_RAW,
            Encoding::ZstdShuffled => ENCODING_ZSTD_SHUFFLED,
        }
    }
}

/// Encodes `values` with zstd at `level` after shuffling; returns `None` when that is not
/// smaller than the raw bytes (the brick is then stored raw).
pub fn encode_zstd_shuffled(values: &[f32], level: i32) -> Option<Vec<u8>> {
    let n = values.len();
    let mut planes = vec![0u8; n * 4];
    for (i, v) in values.iter().enumerate() {
        let b = v.to_le_bytes();
        for (p, byte) in b.iter().enumerate() {
            planes[p * n + i] = *byte;
        }
    }
    let packed = zstd::bulk::compress(&planes, level).ok()?;
    (packed.len() < n * 4).then_some(packed)
}

/// Decodes `bytes` stored with `encoding` into `out`, which receives exactly `cells` values.
pub fn decode_into(encoding: u32, bytes: &[u8], cells: usize, out: &mut Vec<f32>) -> Result<()> {
    let want = cells
        .checked_mul(4)
        .ok_or_else(|| FormatError::Corrupt(format!("brick of {cells} cells is too large")))?;
    out.clear();
    match encoding {
        ENCODING_RAW => {
            if bytes.len() != want {
                return Err(FormatError::Corrupt(format!(
                    "raw brick holds {} bytes, expected {want}",
                    bytes.len()
                )));
            }
            out.extend(
                bytes
                    .chunks_exact(4)
                    .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])),
            );
        }
        ENCODING_ZSTD_SHUFFLED => {
            let planes = zstd::bulk::decompress(bytes, want).map_err(|e| {
                FormatError::Corrupt(format!("zstd brick does not decompress: {e}"))
            })?;
            if planes.len() != want {
                return Err(FormatError::Corrupt(format!(
                    "zstd brick decompresses to {} bytes, expected {want}",
                    planes.len()
                )));
            }
            out.extend((0..cells).map(|i| {
                f32::from_le_bytes([
                    planes[i],
                    planes[cells + i],
                    planes[2 * cells + i],
                    planes[3 * cells + i],
                ])
            }));
        }
        other => {
            return Err(FormatError::Corrupt(format!(
                "unknown brick encoding {other}"
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shuffled_zstd_round_trips() {
        let values: Vec<f32> = (0..4096).map(|i| (i as f32 * 0.01).sin()).collect();
        let packed = encode_zstd_shuffled(&values, 3).expect("a smooth field compresses");
        let mut out = Vec::new();
        decode_into(ENCODING_ZSTD_SHUFFLED, &packed, values.len(), &mut out).unwrap();
        assert_eq!(out, values);
    }

    #[test]
    fn corrupt_frame_is_an_error() {
        let mut out = Vec::new();
        assert!(decode_into(ENCODING_ZSTD_SHUFFLED, &[1, 2, 3, 4], 16, &mut out).is_err());
        assert!(decode_into(ENCODING_RAW, &[0; 12], 4, &mut out).is_err());
        assert!(decode_into(7, &[0; 16], 4, &mut out).is_err());
    }
}
