//! A small AMReX plotfile writer for tests, following AMReX's conventions
//! (`WriteGenericPlotfileHeader` in AMReX_PlotFileUtil.cpp, `VisMF::Header` and
//! `FABio_binary::write_header` in AMReX_VisMF.cpp / AMReX_FArrayBox.cpp), with knobs for what
//! the shared plotfiles lack: float32, big-endian, ghost cells, `Cell_H` versions 1 to 4,
//! any origin, any ratio, several boxes per file, offsets above 4 GiB.

use std::fmt::Write as _;
use std::fs::{self, File, OpenOptions};
use std::io::{Seek, SeekFrom, Write};
use std::path::Path;

/// Number format of the data files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Real {
    /// IEEE float32 little-endian.
    F32Le,
    /// IEEE float32 big-endian.
    F32Be,
    /// IEEE float64 little-endian.
    F64Le,
    /// IEEE float64 big-endian.
    F64Be,
}

impl Real {
    /// The `RealDescriptor` as AMReX prints it (`operator<<` in AMReX_FabConv.cpp): the format
    /// array then the byte-order array, each `putarray`ed as `(number of entries, (entries))`;
    /// the format array always has 8 entries.
    pub fn descriptor(self) -> &'static str {
        match self {
            Real::F32Le => "((8, (32 8 23 0 1 9 0 127)),(4, (4 3 2 1)))",
            Real::F32Be => "((8, (32 8 23 0 1 9 0 127)),(4, (1 2 3 4)))",
            Real::F64Le => "((8, (64 11 52 0 1 12 0 1023)),(8, (8 7 6 5 4 3 2 1)))",
            Real::F64Be => "((8, (64 11 52 0 1 12 0 1023)),(8, (1 2 3 4 5 6 7 8)))",
        }
    }

    fn encode(self, v: f64, out: &mut Vec<u8>) {
        match self {
            Real::F32Le => out.extend_from_slice(&(v as f32).to_le_bytes()),
            Real::F32Be => out.extend_from_slice(&(v as f32).to_be_bytes()),
            Real::F64Le => out.extend_from_slice(&v.to_le_bytes()),
            Real::F64Be => out.extend_from_slice(&v.to_be_bytes()),
        }
    }

    /// The value as stored (float32 formats round it).
    pub fn stored(self, v: f64) -> f64 {
        match self {
            Real::F32Le | Real::F32Be => v as f32 as f64,
            _ => v,
        }
    }
}

/// An inclusive box `(lo, hi)`.
pub type Bx = ([i64; 3], [i64; 3]);

/// What to write.
#[derive(Clone, Debug)]
pub struct PlotSpec {
    /// First line of the Header.
    pub version: String,
    /// Field names.
    pub fields: Vec<String>,
    /// Dimension written in the Header (anything but 3 writes a header only).
    pub dim: usize,
    /// Physical corners of the problem domain.
    pub prob_lo: [f64; 3],
    /// Physical corners of the problem domain.
    pub prob_hi: [f64; 3],
    /// Level 0 index domain.
    pub domain: Bx,
    /// Ratio from each level to the next (one fewer than levels).
    pub ratios: Vec<[i64; 3]>,
    /// Valid boxes of each level.
    pub boxes: Vec<Vec<Bx>>,
    /// `Cell_H` version, 1 to 4.
    pub cell_h_version: u32,
    /// Number format.
    pub real: Real,
    /// Ghost cells written around every box.
    pub nghost: [i64; 3],
    /// Boxes per data file.
    pub boxes_per_file: usize,
    /// Where the first FAB of level 0's first file starts (a sparse gap before it).
    pub first_offset: u64,
}

impl PlotSpec {
    /// One level-0 box `[0, n)^3` on `[0, 1]^3`, one field, version 1, float64 little-endian.
    pub fn single(n: i64) -> PlotSpec {
        PlotSpec {
            version: "HyperCLaw-V1.1".into(),
            fields: vec!["density".into()],
            dim: 3,
            prob_lo: [0.0; 3],
            prob_hi: [1.0; 3],
            domain: ([0; 3], [n - 1; 3]),
            ratios: vec![],
            boxes: vec![vec![([0; 3], [n - 1; 3])]],
            cell_h_version: 1,
            real: Real::F64Le,
            nghost: [0; 3],
            boxes_per_file: 4,
            first_offset: 0,
        }
    }

    /// The index domain of level `l`.
    pub fn level_domain(&self, l: usize) -> Bx {
        let (mut lo, mut hi) = self.domain;
        for r in &self.ratios[..l] {
            for a in 0..3 {
                lo[a] *= r[a];
                hi[a] = (hi[a] + 1) * r[a] - 1;
            }
        }
        (lo, hi)
    }

    /// The cell size of level `l`.
    pub fn cell_size(&self, l: usize) -> [f64; 3] {
        let (lo, hi) = self.level_domain(l);
        [0, 1, 2].map(|a| (self.prob_hi[a] - self.prob_lo[a]) / (hi[a] - lo[a] + 1) as f64)
    }
}

/// A cell value: `(level, component, cell) -> value`.
pub type ValueFn<'a> = &'a dyn Fn(usize, usize, [i64; 3]) -> f64;

/// Writes the plotfile `spec` into the new directory `dir`; ghost cells get `ghost_value`.
pub fn write_plotfile(dir: &Path, spec: &PlotSpec, value: ValueFn, ghost_value: f64) {
    fs::create_dir_all(dir).unwrap();
    let nlev = spec.boxes.len();
    let mut h = String::new();
    writeln!(h, "{}", spec.version).unwrap();
    writeln!(h, "{}", spec.fields.len()).unwrap();
    for f in &spec.fields {
        writeln!(h, "{f}").unwrap();
    }
    writeln!(h, "{}", spec.dim).unwrap();
    if spec.dim != 3 {
        h.push_str("0\n0\n0 0 \n1 1 \n\n((0,0) (7,7) (0,0)) \n0 \n0.125 0.125 \n0\n0\n");
        fs::write(dir.join("Header"), h).unwrap();
        return;
    }
    let time = 0.25;
    writeln!(h, "{time}").unwrap();
    writeln!(h, "{}", nlev - 1).unwrap();
    let row = |v: [f64; 3]| format!("{:?} {:?} {:?} ", v[0], v[1], v[2]);
    writeln!(h, "{}", row(spec.prob_lo)).unwrap();
    writeln!(h, "{}", row(spec.prob_hi)).unwrap();
    for r in &spec.ratios {
        write!(h, "{} ", r[0]).unwrap();
    }
    h.push('\n');
    for l in 0..nlev {
        write!(h, "{} ", show(spec.level_domain(l))).unwrap();
    }
    h.push('\n');
    for _ in 0..nlev {
        h.push_str("0 ");
    }
    h.push('\n');
    for l in 0..nlev {
        writeln!(h, "{}", row(spec.cell_size(l))).unwrap();
    }
    h.push_str("0\n0\n");
    for (l, boxes) in spec.boxes.iter().enumerate() {
        writeln!(h, "{l} {} {time}", boxes.len()).unwrap();
        writeln!(h, "0").unwrap();
        let (dlo, _) = spec.level_domain(l);
        let dx = spec.cell_size(l);
        for (lo, hi) in boxes {
            for a in 0..3 {
                let p = |i: i64| spec.prob_lo[a] + (i - dlo[a]) as f64 * dx[a];
                writeln!(h, "{:?} {:?}", p(lo[a]), p(hi[a] + 1)).unwrap();
            }
        }
        writeln!(h, "Level_{l}/Cell").unwrap();
        write_level(&dir.join(format!("Level_{l}")), spec, l, value, ghost_value);
    }
    fs::write(dir.join("Header"), h).unwrap();
}

fn show((lo, hi): Bx) -> String {
    format!(
        "(({},{},{}) ({},{},{}) (0,0,0))",
        lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
    )
}

fn write_level(dir: &Path, spec: &PlotSpec, l: usize, value: ValueFn, ghost_value: f64) {
    fs::create_dir_all(dir).unwrap();
    let ncomp = spec.fields.len();
    let g = spec.nghost;
    let boxes = &spec.boxes[l];
    let mut fods = Vec::new();
    let mut mins = Vec::new();
    let mut maxs = Vec::new();
    for (file_no, chunk) in boxes.chunks(spec.boxes_per_file.max(1)).enumerate() {
        let name = format!("Cell_D_{file_no:05}");
        let mut f = OpenOptions::new()
            .create(true)
            .write(true)
            .truncate(true)
            .open(dir.join(&name))
            .unwrap();
        let mut offset = if l == 0 && file_no == 0 {
            spec.first_offset
        } else {
            0
        };
        f.seek(SeekFrom::Start(offset)).unwrap();
        for &(lo, hi) in chunk {
            let (dlo, dhi) = (
                [0, 1, 2].map(|a| lo[a] - g[a]),
                [0, 1, 2].map(|a| hi[a] + g[a]),
            );
            let mut bytes = Vec::new();
            if spec.cell_h_version == 1 {
                let line = format!(
                    "FAB {}{} {ncomp}\n",
                    spec.real.descriptor(),
                    show((dlo, dhi))
                );
                bytes.extend_from_slice(line.as_bytes());
            }
            let mut bmin = vec![f64::INFINITY; ncomp];
            let mut bmax = vec![f64::NEG_INFINITY; ncomp];
            for c in 0..ncomp {
                for z in dlo[2]..=dhi[2] {
                    for y in dlo[1]..=dhi[1] {
                        for x in dlo[0]..=dhi[0] {
                            let p = [x, y, z];
                            let inside = (0..3).all(|a| lo[a] <= p[a] && p[a] <= hi[a]);
                            let v = if inside { value(l, c, p) } else { ghost_value };
                            spec.real.encode(v, &mut bytes);
                            if inside {
                                bmin[c] = bmin[c].min(spec.real.stored(v));
                                bmax[c] = bmax[c].max(spec.real.stored(v));
                            }
                        }
                    }
                }
            }
            f.write_all(&bytes).unwrap();
            fods.push(format!("FabOnDisk: {name} {offset}"));
            offset += bytes.len() as u64;
            mins.push(bmin);
            maxs.push(bmax);
        }
    }
    let mut h = String::new();
    writeln!(h, "{}", spec.cell_h_version).unwrap();
    h.push_str("1\n");
    writeln!(h, "{ncomp}").unwrap();
    if g[0] == g[1] && g[1] == g[2] {
        writeln!(h, "{}", g[0]).unwrap();
    } else {
        writeln!(h, "({},{},{})", g[0], g[1], g[2]).unwrap();
    }
    writeln!(h, "({} 0", boxes.len()).unwrap();
    for b in boxes {
        writeln!(h, "{}", show(*b)).unwrap();
    }
    h.push_str(")\n");
    writeln!(h, "{}", boxes.len()).unwrap();
    for f in &fods {
        writeln!(h, "{f}").unwrap();
    }
    h.push('\n');
    let table = |h: &mut String, t: &[Vec<f64>]| {
        writeln!(h, "{},{ncomp}", t.len()).unwrap();
        for r in t {
            for v in r {
                write!(h, "{v:.16e},").unwrap();
            }
            h.push('\n');
        }
        h.push('\n');
    };
    match spec.cell_h_version {
        1 | 3 => {
            table(&mut h, &mins);
            table(&mut h, &maxs);
        }
        4 => {
            for (t, pick) in [(&mins, f64::min as fn(f64, f64) -> f64), (&maxs, f64::max)] {
                for c in 0..ncomp {
                    let v = t.iter().map(|r| r[c]).fold(t[0][c], pick);
                    write!(h, "{v:.16e},").unwrap();
                }
                h.push('\n');
            }
        }
        _ => {}
    }
    if spec.cell_h_version != 1 {
        writeln!(h, "{}", spec.real.descriptor()).unwrap();
    }
    let mut f = File::create(dir.join("Cell_H")).unwrap();
    f.write_all(h.as_bytes()).unwrap();
}
