//! One FAB on disk: the number format (AMReX `RealDescriptor`), the text header line that
//! precedes version-1 data, and decoding raw numbers to checked `f32`.
//!
//! A header reads `FAB ((8, (64 11 52 0 1 12 0 1023)),(8, (8 7 6 5 4 3 2 1)))((lo) (hi) (t)) n`:
//! two arrays, each printed as `(number of entries, (entries))`: the float layout (always 8
//! entries: bits, exponent bits, mantissa bits, ..., bias) and the byte order (one entry per
//! byte: which byte of the number is stored first), then the box the data covers and the
//! component count. A float32 little-endian header reads
//! `FAB ((8, (32 8 23 0 1 9 0 127)),(4, (4 3 2 1)))...`. `docs/amrex.md` cites AMReX's writer.

use amr_format::IBox;

use super::text::Scan;

/// Longest FAB header line accepted.
pub const MAX_FAB_HEADER: usize = 4096;

const IEEE64: [i64; 8] = [64, 11, 52, 0, 1, 12, 0, 1023];
const IEEE32: [i64; 8] = [32, 8, 23, 0, 1, 9, 0, 127];

/// A supported number format of FAB data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RealFormat {
    /// IEEE binary32, little-endian.
    F32Le,
    /// IEEE binary32, big-endian.
    F32Be,
    /// IEEE binary64, little-endian.
    F64Le,
    /// IEEE binary64, big-endian.
    F64Be,
}

impl RealFormat {
    /// Bytes per number.
    pub fn size(self) -> usize {
        match self {
            RealFormat::F32Le | RealFormat::F32Be => 4,
            RealFormat::F64Le | RealFormat::F64Be => 8,
        }
    }

    /// Scans a real descriptor: `(` format array `,` order array `)`, each array written by
    /// AMReX's `putarray` as `(N, (e1 ... eN))` with `N` the number of entries. The outer error
    /// is a syntax error; the inner one a valid descriptor of a format this reader does not
    /// decode.
    pub(crate) fn scan(s: &mut Scan) -> Result<Result<RealFormat, String>, String> {
        s.expect('(')?;
        let layout = counted_list(s, "format")?;
        s.expect(',')?;
        let order = counted_list(s, "byte order")?;
        s.expect(')')?;
        let n = order.len() as i64;
        let le: Vec<i64> = (1..=n).rev().collect();
        let be: Vec<i64> = (1..=n).collect();
        let f = match (layout.as_slice(), n) {
            (l, 8) if l == IEEE64 && order == le => RealFormat::F64Le,
            (l, 8) if l == IEEE64 && order == be => RealFormat::F64Be,
            (l, 4) if l == IEEE32 && order == le => RealFormat::F32Le,
            (l, 4) if l == IEEE32 && order == be => RealFormat::F32Be,
            _ => {
                return Ok(Err(format!(
                    "number format {layout:?} with byte order {order:?}: only IEEE float32 and float64, little- or big-endian, are read"
                )))
            }
        };
        Ok(Ok(f))
    }

    /// Decodes `bytes` into `out` (one value per `size()` bytes), checking that every value is
    /// a finite number within the `f32` range; on failure returns the first bad index and value.
    pub fn decode(self, bytes: &[u8], out: &mut [f32]) -> Result<(), (usize, f64)> {
        debug_assert_eq!(bytes.len(), out.len() * self.size());
        let mut ok = true;
        match self {
            RealFormat::F32Le => decode32(bytes, out, f32::from_le_bytes, &mut ok),
            RealFormat::F32Be => decode32(bytes, out, f32::from_be_bytes, &mut ok),
            RealFormat::F64Le => decode64(bytes, out, f64::from_le_bytes, &mut ok),
            RealFormat::F64Be => decode64(bytes, out, f64::from_be_bytes, &mut ok),
        }
        if ok {
            return Ok(());
        }
        let n = self.size();
        for (i, c) in bytes.chunks_exact(n).enumerate() {
            let v = match self {
                RealFormat::F32Le => {
                    f64::from(f32::from_le_bytes(c.try_into().unwrap_or_default()))
                }
                RealFormat::F32Be => {
                    f64::from(f32::from_be_bytes(c.try_into().unwrap_or_default()))
                }
                RealFormat::F64Le => f64::from_le_bytes(c.try_into().unwrap_or_default()),
                RealFormat::F64Be => f64::from_be_bytes(c.try_into().unwrap_or_default()),
            };
            if !in_f32_range(v) {
                return Err((i, v));
            }
        }
        Ok(())
    }
}

/// True when `v` is finite and no larger in magnitude than `f32::MAX`.
pub fn in_f32_range(v: f64) -> bool {
    v.abs() <= f64::from(f32::MAX)
}

/// Why `v` cannot be stored, for error messages.
pub fn why_not_f32(v: f64) -> &'static str {
    if v.is_nan() {
        "a NaN"
    } else if v.is_infinite() {
        "an infinite value"
    } else {
        "a value outside the f32 range"
    }
}

fn decode32(bytes: &[u8], out: &mut [f32], from: fn([u8; 4]) -> f32, ok: &mut bool) {
    let mut all = true;
    for (o, c) in out.iter_mut().zip(bytes.chunks_exact(4)) {
        let v = from([c[0], c[1], c[2], c[3]]);
        all &= v.is_finite();
        *o = v;
    }
    *ok = all;
}

fn decode64(bytes: &[u8], out: &mut [f32], from: fn([u8; 8]) -> f64, ok: &mut bool) {
    let mut all = true;
    for (o, c) in out.iter_mut().zip(bytes.chunks_exact(8)) {
        let v = from([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]);
        all &= in_f32_range(v);
        *o = v as f32;
    }
    *ok = all;
}

/// One array as AMReX's `putarray` writes it: `(N, (e1 e2 ... eN))`.
fn counted_list(s: &mut Scan, what: &str) -> Result<Vec<i64>, String> {
    s.expect('(')?;
    let n = s.int()?;
    if !(1..=64).contains(&n) {
        return Err(format!("{what} array of {n} entries"));
    }
    s.expect(',')?;
    s.expect('(')?;
    let mut v = Vec::with_capacity(n as usize);
    while !s.eat(')') {
        if v.len() as i64 == n {
            return Err(format!(
                "{what} array has more than the {n} entries it announces"
            ));
        }
        v.push(s.int()?);
    }
    if v.len() as i64 != n {
        return Err(format!(
            "{what} array announces {n} entries but holds {}",
            v.len()
        ));
    }
    s.expect(')')?;
    Ok(v)
}

/// The text line preceding a FAB's data in version-1 files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FabHeader {
    /// Number format of the data that follows.
    pub format: RealFormat,
    /// The box the data covers (half-open): the valid box, possibly grown by ghost cells.
    pub data_box: IBox,
    /// Number of components stored.
    pub ncomp: usize,
}

impl FabHeader {
    /// Parses a header line (without its newline). The outer error is a syntax error; the
    /// inner one a format this reader does not support.
    pub fn parse(line: &str) -> Result<Result<FabHeader, String>, String> {
        let mut s = Scan::new(line);
        s.expect_word("FAB")
            .map_err(|e| format!("not a FAB header: {e}"))?;
        let format = match RealFormat::scan(&mut s)? {
            Ok(f) => f,
            Err(e) => return Ok(Err(e)),
        };
        let b = s.amrex_box()?;
        if b.centering != [0; 3] {
            return Ok(Err(format!("node-centred data {:?}", b.centering)));
        }
        let data_box = b.to_ibox()?;
        let n = s.int()?;
        if !s.at_end() {
            return Err(format!(
                "unexpected text after the component count: '{}'",
                s.rest()
            ));
        }
        let ncomp = usize::try_from(n).map_err(|_| format!("component count {n}"))?;
        Ok(Ok(FabHeader {
            format,
            data_box,
            ncomp,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_documented_header() {
        let h = FabHeader::parse("FAB ((8, (64 11 52 0 1 12 0 1023)),(8, (8 7 6 5 4 3 2 1)))((0,8,8) (7,15,15) (0,0,0)) 38")
            .unwrap()
            .unwrap();
        assert_eq!(h.format, RealFormat::F64Le);
        assert_eq!(h.data_box, IBox::new([0, 8, 8], [8, 16, 16]));
        assert_eq!(h.ncomp, 38);
        let h = FabHeader::parse(
            "FAB ((8, (32 8 23 0 1 9 0 127)),(4, (1 2 3 4)))((-1,0,0) (3,3,3) (0,0,0)) 1",
        )
        .unwrap()
        .unwrap();
        assert_eq!(h.format, RealFormat::F32Be);
        assert!(FabHeader::parse(
            "FAB ((8, (64 11 52 0 1 12 0 1023)),(8, (2 1 4 3 6 5 8 7)))((0,0,0) (1,1,1) (0,0,0)) 1"
        )
        .unwrap()
        .is_err());
        assert!(FabHeader::parse("FAB 8BIT").is_err());
    }

    #[test]
    fn float32_headers_as_amrex_prints_them() {
        let h = FabHeader::parse(
            "FAB ((8, (32 8 23 0 1 9 0 127)),(4, (4 3 2 1)))((0,0,0) (1,1,1) (0,0,0)) 2",
        )
        .unwrap()
        .unwrap();
        assert_eq!(h.format, RealFormat::F32Le);
        assert_eq!(h.ncomp, 2);
        for wrong in [
            "FAB ((4, (32 8 23 0 1 9 0 127)),(4, (4 3 2 1)))((0,0,0) (1,1,1) (0,0,0)) 2",
            "FAB ((8, (32 8 23 0 1 9 0)),(4, (4 3 2 1)))((0,0,0) (1,1,1) (0,0,0)) 2",
            "FAB ((8, (32 8 23 0 1 9 0 127)),(5, (4 3 2 1)))((0,0,0) (1,1,1) (0,0,0)) 2",
        ] {
            let e = FabHeader::parse(wrong).unwrap_err();
            assert!(e.contains("entries"), "{wrong}: {e}");
        }
    }

    #[test]
    fn decode_rounds_and_refuses_out_of_range() {
        let vals = [1.0f64 / 3.0, -2.5e10, 1e-320];
        let bytes: Vec<u8> = vals.iter().flat_map(|v| v.to_be_bytes()).collect();
        let mut out = [0f32; 3];
        RealFormat::F64Be.decode(&bytes, &mut out).unwrap();
        assert_eq!(out, [vals[0] as f32, vals[1] as f32, 0.0]);
        let bytes: Vec<u8> = [0.0, 1e39, f64::NAN]
            .iter()
            .flat_map(|v: &f64| v.to_le_bytes())
            .collect();
        assert_eq!(
            RealFormat::F64Le.decode(&bytes, &mut out).unwrap_err(),
            (1, 1e39)
        );
    }
}
