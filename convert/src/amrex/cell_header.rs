//! A level's `Cell_H` (AMReX `VisMF::Header`): the boxes, where each box's data sits, and the
//! number format when the data files carry no per-FAB header.
//!
//! Layout: version, how, ncomp, nghost (an integer or an `IntVect`), the box array
//! `(N 0` / N boxes / `)`, N and N `FabOnDisk: file offset` lines, then by version:
//! 1 per-box min and max (`N,ncomp` and N rows, twice); 2 nothing; 3 per-box min and max;
//! 4 one row of whole-level minima and one of maxima. Versions 2 to 4 end with the real
//! descriptor of the headerless data.

use std::io::BufRead;
use std::path::{Component, Path};

use amr_format::IBox;

use super::error::{AmrexError, Result};
use super::fab::RealFormat;
use super::text::{Scan, TextReader};

/// Largest number of boxes on one level accepted.
const MAX_BOXES: usize = 1 << 28;
/// Largest number of components accepted.
const MAX_COMPONENTS: usize = 1 << 16;
/// Largest ghost width accepted.
const MAX_GHOST: i64 = 1 << 10;

/// One box's data location: a file in the level directory and a byte offset into it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FabOnDisk {
    /// File name relative to the level directory, e.g. `Cell_D_00003`.
    pub file: String,
    /// Byte offset of the FAB (header line or raw data) in that file.
    pub offset: u64,
}

/// The parsed `Cell_H` of one level.
#[derive(Clone, Debug, PartialEq)]
pub struct CellHeader {
    /// `VisMF` header version, 1 to 4.
    pub version: u32,
    /// Number of components (fields) stored per box.
    pub ncomp: usize,
    /// Ghost cells stored around each box, per axis.
    pub nghost: [i64; 3],
    /// The valid boxes (half-open), in data order.
    pub boxes: Vec<IBox>,
    /// Where each box's data is.
    pub fabs: Vec<FabOnDisk>,
    /// Number format of headerless data (versions 2 to 4); version 1 has a header per FAB.
    pub real_format: Option<RealFormat>,
}

/// Reads and checks the `Cell_H` at `path`.
pub fn read_cell_header(path: &Path) -> Result<CellHeader> {
    parse_cell_header(TextReader::open(path)?)
}

/// Parses a `Cell_H` from any line reader.
pub(crate) fn parse_cell_header<R: BufRead>(mut r: TextReader<R>) -> Result<CellHeader> {
    let version: u32 = int_line(&mut r, "the VisMF header version")?;
    if !(1..=4).contains(&version) {
        return Err(AmrexError::unsupported(
            r.path(),
            format!("VisMF header version {version} (versions 1 to 4 are known)"),
        ));
    }
    int_line::<i64, _>(&mut r, "the 'how' flag")?;
    let ncomp: usize = int_line(&mut r, "the number of components")?;
    if ncomp == 0 || ncomp > MAX_COMPONENTS {
        return Err(r.error(format!(
            "{ncomp} components (expected 1 to {MAX_COMPONENTS})"
        )));
    }
    let nghost = ghost_line(&mut r)?;
    let boxes = box_array(&mut r)?;
    let fabs = fab_list(&mut r, boxes.len())?;
    match version {
        1 | 3 => {
            min_max_table(&mut r, "minima", boxes.len(), ncomp)?;
            min_max_table(&mut r, "maxima", boxes.len(), ncomp)?;
        }
        4 => {
            min_max_row(&mut r, "the level minima", ncomp)?;
            min_max_row(&mut r, "the level maxima", ncomp)?;
        }
        _ => {}
    }
    let real_format = if version == 1 {
        None
    } else {
        let line = content_line(&mut r, "the real descriptor of the data")?;
        let mut s = Scan::new(&line);
        let f = RealFormat::scan(&mut s).map_err(|e| r.error(e))?;
        Some(f.map_err(|e| AmrexError::unsupported(r.path(), e))?)
    };
    Ok(CellHeader {
        version,
        ncomp,
        nghost,
        boxes,
        fabs,
        real_format,
    })
}

/// The next non-empty line.
fn content_line<R: BufRead>(r: &mut TextReader<R>, what: &str) -> Result<String> {
    while r.peek()?.is_some_and(|l| l.trim().is_empty()) {
        r.next(what)?;
    }
    r.next(what)
}

fn int_line<T: std::str::FromStr, R: BufRead>(r: &mut TextReader<R>, what: &str) -> Result<T> {
    let line = content_line(r, what)?.trim().to_string();
    line.parse::<T>()
        .map_err(|_| r.error(format!("expected {what}, found '{line}'")))
}

fn ghost_line<R: BufRead>(r: &mut TextReader<R>) -> Result<[i64; 3]> {
    let line = content_line(r, "the ghost width")?;
    let mut s = Scan::new(&line);
    let g = if s.peek() == Some('(') {
        s.ivect()
    } else {
        s.int().map(|g| [g; 3])
    };
    let g = g.map_err(|e| r.error(format!("ghost width: {e}")))?;
    if g.iter().any(|&x| !(0..=MAX_GHOST).contains(&x)) || !s.at_end() {
        return Err(r.error(format!("ghost width '{line}' (expected 0 to {MAX_GHOST})")));
    }
    Ok(g)
}

fn box_array<R: BufRead>(r: &mut TextReader<R>) -> Result<Vec<IBox>> {
    let line = content_line(r, "the box array '(N 0'")?;
    let mut s = Scan::new(&line);
    let n = s
        .expect('(')
        .and_then(|_| s.int())
        .map_err(|e| r.error(format!("box array: {e}")))?;
    let n = usize::try_from(n)
        .ok()
        .filter(|&n| n > 0 && n <= MAX_BOXES)
        .ok_or_else(|| {
            r.error(format!(
                "box array of {n} boxes (expected 1 to {MAX_BOXES})"
            ))
        })?;
    let mut boxes = Vec::with_capacity(n.min(1 << 16));
    for i in 0..n {
        let line = r.next(&format!("box {i} of {n}"))?;
        let mut s = Scan::new(&line);
        let b = s
            .amrex_box()
            .map_err(|e| r.error(format!("box {i} of {n}: {e}")))?;
        if b.centering != [0; 3] {
            return Err(AmrexError::unsupported(
                r.path(),
                format!("box {i} is not cell-centred"),
            ));
        }
        boxes.push(b.to_ibox().map_err(|e| r.error(format!("box {i}: {e}")))?);
    }
    let line = r.next("')' closing the box array")?;
    if line.trim() != ")" {
        return Err(r.error(format!(
            "expected ')' closing the box array of {n} boxes, found '{line}'"
        )));
    }
    Ok(boxes)
}

fn fab_list<R: BufRead>(r: &mut TextReader<R>, nboxes: usize) -> Result<Vec<FabOnDisk>> {
    let n: usize = int_line(r, "the number of FabOnDisk lines")?;
    if n != nboxes {
        return Err(r.error(format!("{n} FabOnDisk lines for {nboxes} boxes")));
    }
    let mut fabs = Vec::with_capacity(n.min(1 << 16));
    for i in 0..n {
        let line = r.next(&format!("FabOnDisk line {i} of {n}"))?;
        let t: Vec<&str> = line.split_whitespace().collect();
        let (file, offset) = match t.as_slice() {
            ["FabOnDisk:", file, off] => (*file, off.parse::<u64>().ok()),
            _ => ("", None),
        };
        let Some(offset) = offset else {
            return Err(r.error(format!(
                "expected 'FabOnDisk: FILE OFFSET' for box {i}, found '{line}'"
            )));
        };
        let mut comps = Path::new(file).components();
        if !matches!(
            (comps.next(), comps.next()),
            (Some(Component::Normal(_)), None)
        ) {
            return Err(r.error(format!(
                "box {i}: data file '{file}' is not a plain file name"
            )));
        }
        fabs.push(FabOnDisk {
            file: file.to_string(),
            offset,
        });
    }
    Ok(fabs)
}

fn min_max_table<R: BufRead>(
    r: &mut TextReader<R>,
    what: &str,
    nboxes: usize,
    ncomp: usize,
) -> Result<()> {
    let line = content_line(r, &format!("the table of per-box {what}"))?;
    let dims: Vec<Option<usize>> = line.split(',').map(|t| t.trim().parse().ok()).collect();
    if dims != [Some(nboxes), Some(ncomp)] {
        return Err(r.error(format!(
            "expected '{nboxes},{ncomp}' opening the per-box {what}, found '{line}'"
        )));
    }
    for i in 0..nboxes {
        min_max_row(r, &format!("the {what} of box {i}"), ncomp)?;
    }
    Ok(())
}

fn min_max_row<R: BufRead>(r: &mut TextReader<R>, what: &str, ncomp: usize) -> Result<()> {
    let line = content_line(r, what)?;
    let n = line.trim().trim_end_matches(',').split(',').count();
    if n != ncomp {
        return Err(r.error(format!("{what}: {n} values for {ncomp} components")));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<CellHeader> {
        parse_cell_header(TextReader::new(text.as_bytes(), Path::new("Cell_H")))
    }

    #[test]
    fn version_1_with_min_max() {
        let h = parse(
            "1\n1\n2\n0\n(2 0\n((0,0,0) (7,7,7) (0,0,0))\n((8,0,0) (15,7,7) (0,0,0))\n)\n2\n\
FabOnDisk: Cell_D_00000 0\nFabOnDisk: Cell_D_00001 5000000000\n\n2,2\n1,2,\n3,4,\n\n2,2\n5,6,\n7,8,\n\n",
        )
        .unwrap();
        assert_eq!(h.boxes[1], IBox::new([8, 0, 0], [16, 8, 8]));
        assert_eq!(h.fabs[1].offset, 5_000_000_000);
        assert_eq!(h.real_format, None);
    }

    #[test]
    fn version_2_with_ghost_vector_and_descriptor() {
        let h = parse(
            "2\n1\n1\n(1,1,2)\n(1 0\n((0,0,0) (3,3,3) (0,0,0))\n)\n1\nFabOnDisk: Cell_D_00000 0\n\n\
((8, (32 8 23 0 1 9 0 127)),(4, (1 2 3 4)))\n",
        )
        .unwrap();
        assert_eq!(h.nghost, [1, 1, 2]);
        assert_eq!(h.real_format, Some(RealFormat::F32Be));
    }

    #[test]
    fn missing_box_line_is_an_error() {
        let e = parse("1\n1\n1\n0\n(2 0\n((0,0,0) (7,7,7) (0,0,0))\n)\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("box 1 of 2"), "{e}");
    }
}
