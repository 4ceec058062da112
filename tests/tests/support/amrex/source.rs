//! An independent, deliberately naive reader of AMReX plotfiles for checking the converter:
//! it shares no code with `amr_convert::amrex`, loads everything into memory and panics on
//! anything unexpected.

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::Path;

/// One box of one level with all its values.
pub struct SrcBox {
    /// Inclusive lower corner.
    pub lo: [i64; 3],
    /// Inclusive upper corner.
    pub hi: [i64; 3],
    /// Values over the valid box, `[component][cell]`, x fastest.
    pub values: Vec<Vec<f64>>,
    /// Per-component minimum from `Cell_H`, when it has one.
    pub min: Option<Vec<f64>>,
    /// Per-component maximum from `Cell_H`, when it has one.
    pub max: Option<Vec<f64>>,
}

impl SrcBox {
    /// The value of component `c` at cell `p` (which must lie in the box).
    pub fn at(&self, c: usize, p: [i64; 3]) -> f64 {
        let e = [0, 1, 2].map(|a| self.hi[a] - self.lo[a] + 1);
        let (x, y, z) = (p[0] - self.lo[0], p[1] - self.lo[1], p[2] - self.lo[2]);
        self.values[c][(x + e[0] * (y + e[1] * z)) as usize]
    }

    /// True when cell `p` lies in the box.
    pub fn contains(&self, p: [i64; 3]) -> bool {
        (0..3).all(|a| self.lo[a] <= p[a] && p[a] <= self.hi[a])
    }
}

/// A whole plotfile in memory.
pub struct SrcPlotfile {
    /// Field names.
    pub fields: Vec<String>,
    /// `[level][box]`.
    pub levels: Vec<Vec<SrcBox>>,
}

/// All integers in `s`, in order (a `-` directly before digits makes it negative).
fn ints(s: &str) -> Vec<i64> {
    let mut out = Vec::new();
    let mut cur = String::new();
    for ch in s.chars().chain(std::iter::once(' ')) {
        if ch.is_ascii_digit() || (ch == '-' && cur.is_empty()) {
            cur.push(ch);
        } else {
            if cur.len() > 1 || cur.chars().any(|c| c.is_ascii_digit()) {
                out.push(cur.parse().unwrap());
            }
            cur.clear();
            if ch == '-' {
                cur.push(ch);
            }
        }
    }
    out
}

/// Reads the whole plotfile at `dir`.
pub fn read_plotfile(dir: &Path) -> SrcPlotfile {
    let header = std::fs::read_to_string(dir.join("Header")).unwrap();
    let lines: Vec<&str> = header.lines().collect();
    let n: usize = lines[1].trim().parse().unwrap();
    let fields: Vec<String> = lines[2..2 + n]
        .iter()
        .map(|s| s.trim().to_string())
        .collect();
    let finest: usize = lines[2 + n + 2].trim().parse().unwrap();
    let levels = (0..=finest)
        .map(|l| read_level(&dir.join(format!("Level_{l}")), n))
        .collect();
    SrcPlotfile { fields, levels }
}

fn read_level(dir: &Path, ncomp: usize) -> Vec<SrcBox> {
    let text = std::fs::read_to_string(dir.join("Cell_H")).unwrap();
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    let version: u32 = lines[0].trim().parse().unwrap();
    assert_eq!(lines[2].trim().parse::<usize>().unwrap(), ncomp);
    let g = ints(lines[3]);
    let ghost = if g.len() == 1 {
        [g[0]; 3]
    } else {
        [g[0], g[1], g[2]]
    };
    let nboxes = ints(lines[4])[0] as usize;
    let mut boxes = Vec::new();
    for line in &lines[5..5 + nboxes] {
        let v = ints(line);
        boxes.push(([v[0], v[1], v[2]], [v[3], v[4], v[5]]));
    }
    let mut k = 5 + nboxes + 2;
    let mut fods = Vec::new();
    for line in &lines[k..k + nboxes] {
        let t: Vec<&str> = line.split_whitespace().collect();
        fods.push((t[1].to_string(), t[2].parse::<u64>().unwrap()));
    }
    k += nboxes;
    let table = |k: usize| -> Vec<Vec<f64>> {
        lines[k + 1..k + 1 + nboxes]
            .iter()
            .map(|l| {
                l.split(',')
                    .filter(|t| !t.trim().is_empty())
                    .map(|t| t.trim().parse().unwrap())
                    .collect()
            })
            .collect()
    };
    let (mins, maxs) = if version == 1 || version == 3 {
        (Some(table(k)), Some(table(k + 1 + nboxes)))
    } else {
        (None, None)
    };
    let rd = if version == 1 {
        None
    } else {
        Some(ints(lines.last().unwrap()))
    };
    let mut out = Vec::new();
    for (i, &(lo, hi)) in boxes.iter().enumerate() {
        let (file, offset) = &fods[i];
        let mut f = BufReader::new(File::open(dir.join(file)).unwrap());
        f.seek(SeekFrom::Start(*offset)).unwrap();
        let (desc, dlo, dhi) = match &rd {
            Some(rd) => (rd.clone(), lo, hi),
            None => {
                let mut line = String::new();
                f.read_line(&mut line).unwrap();
                assert!(line.starts_with("FAB "), "{line}");
                let v = ints(&line);
                let nb = v[9] as usize;
                let b = &v[10 + nb..];
                assert_eq!(b[9] as usize, ncomp, "component count in the FAB header");
                (
                    v[..10 + nb].to_vec(),
                    [b[0], b[1], b[2]],
                    [b[3], b[4], b[5]],
                )
            }
        };
        let (dlo, dhi) = if rd.is_some() {
            (
                [0, 1, 2].map(|a| dlo[a] - ghost[a]),
                [0, 1, 2].map(|a| dhi[a] + ghost[a]),
            )
        } else {
            (dlo, dhi)
        };
        // `((8, (format)),(N, (order)))`: 8 format entries, then one order entry per byte.
        assert_eq!(desc[0], 8, "the format array has 8 entries");
        let size = desc[9] as usize;
        assert_eq!(desc[1] as usize, 8 * size, "bits per number");
        let big = desc[10] == 1 && size > 1;
        let de = [0, 1, 2].map(|a| (dhi[a] - dlo[a] + 1) as usize);
        let ncells = de[0] * de[1] * de[2];
        let mut raw = vec![0u8; ncells * ncomp * size];
        f.read_exact(&mut raw).unwrap();
        let decode = |c: &[u8]| -> f64 {
            match (size, big) {
                (8, false) => f64::from_le_bytes(c.try_into().unwrap()),
                (8, true) => f64::from_be_bytes(c.try_into().unwrap()),
                (4, false) => f32::from_le_bytes(c.try_into().unwrap()) as f64,
                (4, true) => f32::from_be_bytes(c.try_into().unwrap()) as f64,
                _ => panic!("unknown real size {size}"),
            }
        };
        let mut values = Vec::new();
        for c in 0..ncomp {
            let mut v = Vec::new();
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let idx = (x - dlo[0]) as usize
                            + de[0] * ((y - dlo[1]) as usize + de[1] * (z - dlo[2]) as usize)
                            + c * ncells;
                        v.push(decode(&raw[idx * size..(idx + 1) * size]));
                    }
                }
            }
            values.push(v);
        }
        let min = mins.as_ref().map(|m| m[i].clone());
        let max = maxs.as_ref().map(|m| m[i].clone());
        out.push(SrcBox {
            lo,
            hi,
            values,
            min,
            max,
        });
    }
    out
}

#[test]
fn ints_reads_negatives_and_nested_parentheses() {
    assert_eq!(
        ints("((-1,0,12) (3,-4,5) (0,0,0)) 7"),
        [-1, 0, 12, 3, -4, 5, 0, 0, 0, 7]
    );
}
