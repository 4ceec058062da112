//! The plotfile's top-level `Header`: fields, problem domain, levels and where their data lives.
//!
//! Layout (AMReX `WriteGenericPlotfileHeader`): version string, field count, one field name per
//! line, dimension, time, finest level L, prob_lo, prob_hi, L refinement ratios, L+1 level index
//! domains, level steps, L+1 lines of cell sizes, coordinate system, boundary width, then per
//! level `lev ngrids time`, the step, one `lo hi` line per axis per grid and `Level_N/Cell`.

use std::io::BufRead;
use std::path::{Component, Path};

use amr_format::IBox;

use super::error::{AmrexError, Result};
use super::text::{parse_all, Scan, TextReader};

/// Largest number of fields accepted.
const MAX_FIELDS: usize = 1 << 16;
/// Largest number of levels accepted (the `.amrk` format's limit).
const MAX_LEVELS: usize = amr_format::hierarchy::MAX_LEVELS;
/// Largest number of grids on one level accepted.
const MAX_GRIDS: usize = 1 << 28;
/// Relative tolerance between a written cell size and the one implied by the domain.
const CELL_SIZE_TOLERANCE: f64 = 1e-4;

/// One level as described by the `Header`.
#[derive(Clone, Debug, PartialEq)]
pub struct HeaderLevel {
    /// The level's index domain (half-open).
    pub domain: IBox,
    /// Physical cell size per axis.
    pub cell_size: [f64; 3],
    /// Refinement ratio to the next finer level per axis (`[1, 1, 1]` on the finest level).
    pub ratio_to_next: [u32; 3],
    /// Number of grids the `Header` lists for this level.
    pub ngrids: usize,
    /// The level's MultiFab prefix relative to the plotfile, e.g. `Level_0/Cell`.
    pub cell_prefix: String,
}

/// The parsed `Header` of a 3D plotfile.
#[derive(Clone, Debug, PartialEq)]
pub struct PlotHeader {
    /// The version string on the first line (`HyperCLaw-V1.1`, `CartGrid-V2.0`, ...).
    pub version: String,
    /// Field names in component order.
    pub fields: Vec<String>,
    /// Simulation time.
    pub time: f64,
    /// Level 0's step, when the level-steps line holds one.
    pub step: Option<i64>,
    /// Physical lower corner of the problem domain.
    pub prob_lo: [f64; 3],
    /// Physical upper corner of the problem domain.
    pub prob_hi: [f64; 3],
    /// Levels, coarsest first.
    pub levels: Vec<HeaderLevel>,
}

/// True when `line` looks like a plotfile version string such as `HyperCLaw-V1.1`.
pub fn looks_like_version(line: &str) -> bool {
    let line = line.trim();
    let Some((name, ver)) = line.rsplit_once("-V") else {
        return false;
    };
    !name.is_empty()
        && line.len() <= 64
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
        && ver.starts_with(|c: char| c.is_ascii_digit())
        && ver.bytes().all(|b| b.is_ascii_digit() || b == b'.')
}

/// Reads and checks the `Header` file at `path`.
pub fn read_header(path: &Path) -> Result<PlotHeader> {
    parse_header(TextReader::open(path)?)
}

/// Parses a `Header` from any line reader.
pub(crate) fn parse_header<R: BufRead>(mut r: TextReader<R>) -> Result<PlotHeader> {
    let version = r.next("the version string")?.trim().to_string();
    if !looks_like_version(&version) {
        return Err(r.error(format!(
            "'{version}' is not a plotfile version string (like HyperCLaw-V1.1): not an AMReX plotfile"
        )));
    }
    let nfields: usize = one(&mut r, "the number of fields")?;
    if nfields == 0 || nfields > MAX_FIELDS {
        return Err(r.error(format!("{nfields} fields (expected 1 to {MAX_FIELDS})")));
    }
    let mut fields = Vec::with_capacity(nfields.min(1024));
    for i in 0..nfields {
        let name = r
            .next(&format!("the name of field {i} of {nfields}"))?
            .trim()
            .to_string();
        if name.is_empty() {
            return Err(r.error(format!("field {i} has an empty name")));
        }
        if fields.contains(&name) {
            return Err(r.error(format!("field name '{name}' appears twice")));
        }
        fields.push(name);
    }
    let dim: i64 = one(&mut r, "the dimension")?;
    match dim {
        3 => {}
        1 | 2 => {
            return Err(AmrexError::unsupported(
                r.path(),
                format!("{dim}D is not supported: this reader converts 3D plotfiles only"),
            ))
        }
        _ => return Err(r.error(format!("dimension {dim} (expected 3)"))),
    }
    let time: f64 = one(&mut r, "the time")?;
    let finest: usize = one(&mut r, "the finest level")?;
    if finest >= MAX_LEVELS {
        return Err(r.error(format!(
            "finest level {finest}: at most {MAX_LEVELS} levels are supported"
        )));
    }
    let nlev = finest + 1;
    let prob_lo = vec3(&mut r, "prob_lo")?;
    let prob_hi = vec3(&mut r, "prob_hi")?;
    if (0..3)
        .any(|a| !(prob_lo[a].is_finite() && prob_hi[a].is_finite() && prob_hi[a] > prob_lo[a]))
    {
        return Err(r.error(format!(
            "problem domain {prob_lo:?} to {prob_hi:?} is empty or not finite"
        )));
    }
    let ratio_items = ratio_line(&mut r, finest)?;
    let domains = domain_line(&mut r, nlev)?;
    // AMReX writes each level's step; level 0's is the run's step.
    let step = r
        .next("the level steps")?
        .split_whitespace()
        .next()
        .and_then(|s| s.parse::<i64>().ok());
    let mut cell_sizes = Vec::with_capacity(nlev);
    for l in 0..nlev {
        cell_sizes.push(vec3(&mut r, &format!("the cell size of level {l}"))?);
    }
    let coord: i64 = one(&mut r, "the coordinate system")?;
    if coord != 0 {
        return Err(AmrexError::unsupported(
            r.path(),
            format!("coordinate system {coord} (only Cartesian, 0, is supported)"),
        ));
    }
    r.next("the boundary width")?;
    let mut levels = Vec::with_capacity(nlev);
    for l in 0..nlev {
        let (ngrids, cell_prefix) = level_block(&mut r, l)?;
        let ratio_to_next = if l < finest {
            ratio(&r, l, &domains, ratio_items[l])?
        } else {
            [1; 3]
        };
        check_cell_size(&r, l, &domains[l], &cell_sizes[l], &prob_lo, &prob_hi)?;
        levels.push(HeaderLevel {
            domain: domains[l],
            cell_size: cell_sizes[l],
            ratio_to_next,
            ngrids,
            cell_prefix,
        });
    }
    Ok(PlotHeader {
        version,
        fields,
        time,
        step,
        prob_lo,
        prob_hi,
        levels,
    })
}

fn one<T: std::str::FromStr, R: BufRead>(r: &mut TextReader<R>, what: &str) -> Result<T> {
    let line = r.next(what)?;
    let t = line.trim();
    t.parse::<T>()
        .map_err(|_| r.error(format!("expected {what}, found '{t}'")))
}

fn vec3<R: BufRead>(r: &mut TextReader<R>, what: &str) -> Result<[f64; 3]> {
    let line = r.next(what)?;
    let v: Vec<f64> = parse_all(&line).map_err(|e| r.error(format!("{what}: {e}")))?;
    if v.len() < 3 {
        return Err(r.error(format!("{what}: expected 3 numbers, found {}", v.len())));
    }
    Ok([v[0], v[1], v[2]])
}

/// One refinement ratio from the `Header`: AMReX writes one integer per level (the x ratio);
/// some writers write a whole `IntVect`.
#[derive(Clone, Copy, Debug, PartialEq)]
enum RatioItem {
    Scalar(i64),
    Vector([i64; 3]),
}

fn ratio_line<R: BufRead>(r: &mut TextReader<R>, finest: usize) -> Result<Vec<RatioItem>> {
    if finest == 0 {
        // AMReX writes an empty line; tolerate a writer that leaves it out.
        if r.peek()?.is_some_and(|l| !l.contains("((")) {
            r.next("the refinement ratios")?;
        }
        return Ok(Vec::new());
    }
    let line = r.next("the refinement ratios")?;
    let mut s = Scan::new(&line);
    let mut items = Vec::new();
    while !s.at_end() {
        let item = if s.peek() == Some('(') {
            s.ivect().map(RatioItem::Vector)
        } else {
            s.int().map(RatioItem::Scalar)
        };
        items.push(item.map_err(|e| r.error(format!("refinement ratios: {e}")))?);
    }
    if items.len() < finest {
        return Err(r.error(format!(
            "{} refinement ratios for {} levels (expected {finest})",
            items.len(),
            finest + 1
        )));
    }
    Ok(items)
}

fn domain_line<R: BufRead>(r: &mut TextReader<R>, nlev: usize) -> Result<Vec<IBox>> {
    let line = r.next("the level domains")?;
    let mut s = Scan::new(&line);
    let mut out = Vec::with_capacity(nlev);
    for l in 0..nlev {
        let b = s
            .amrex_box()
            .map_err(|e| r.error(format!("domain of level {l}: {e}")))?;
        if b.centering != [0; 3] {
            return Err(AmrexError::unsupported(
                r.path(),
                format!("level {l} domain is not cell-centred"),
            ));
        }
        out.push(
            b.to_ibox()
                .map_err(|e| r.error(format!("domain of level {l}: {e}")))?,
        );
    }
    Ok(out)
}

fn level_block<R: BufRead>(r: &mut TextReader<R>, l: usize) -> Result<(usize, String)> {
    let what = format!("'{l} ngrids time' opening level {l}");
    let line = r.next(&what)?;
    let t: Vec<&str> = line.split_whitespace().collect();
    let (lev, ngrids) = match t.as_slice() {
        [a, b, ..] => (a.parse::<usize>().ok(), b.parse::<usize>().ok()),
        _ => (None, None),
    };
    if lev != Some(l) {
        return Err(r.error(format!("expected {what}, found '{line}'")));
    }
    let ngrids = ngrids.ok_or_else(|| r.error(format!("level {l}: bad grid count in '{line}'")))?;
    if ngrids == 0 || ngrids > MAX_GRIDS {
        return Err(r.error(format!(
            "level {l}: {ngrids} grids (expected 1 to {MAX_GRIDS})"
        )));
    }
    r.next(&format!("the step of level {l}"))?;
    for g in 0..ngrids {
        for a in 0..3 {
            let line = r.next(&format!("the physical extent of grid {g} of level {l}"))?;
            let v: Vec<f64> = parse_all(&line)
                .map_err(|e| r.error(format!("grid {g} of level {l}, axis {a}: {e}")))?;
            if v.len() != 2 {
                return Err(r.error(format!(
                    "grid {g} of level {l}, axis {a}: expected 'lo hi', found '{line}' (is the grid count {ngrids} right?)"
                )));
            }
        }
    }
    let prefix = r
        .next(&format!("the data path of level {l}"))?
        .trim()
        .to_string();
    let p = Path::new(&prefix);
    if prefix.is_empty() || !p.components().all(|c| matches!(c, Component::Normal(_))) {
        return Err(r.error(format!(
            "level {l}: data path '{prefix}' is not a plain relative path"
        )));
    }
    Ok((ngrids, prefix))
}

fn ratio<R: BufRead>(
    r: &TextReader<R>,
    l: usize,
    domains: &[IBox],
    item: RatioItem,
) -> Result<[u32; 3]> {
    let (c, f) = (domains[l].extent(), domains[l + 1].extent());
    let mut out = [0u32; 3];
    for a in 0..3 {
        let q = f[a] / c[a];
        if q * c[a] != f[a]
            || domains[l].refine([q, q, q]).map(|d| (d.lo[a], d.hi[a]))
                != Some((domains[l + 1].lo[a], domains[l + 1].hi[a]))
        {
            return Err(AmrexError::invalid(
                r.path(),
                format!(
                    "level {} domain {:?} is not level {l} domain {:?} refined by a whole ratio",
                    l + 1,
                    domains[l + 1],
                    domains[l]
                ),
            ));
        }
        if q < 2 {
            return Err(AmrexError::unsupported(
                r.path(),
                format!(
                    "refinement ratio {q} on axis {a} from level {l} to {} (a quasi-2D ratio such as 2 2 1): \
                     .amrk needs a ratio of at least 2 on every axis (docs/format.md, \"Why every ratio is at least 2\")",
                    l + 1
                ),
            ));
        }
        out[a] = u32::try_from(q).map_err(|_| {
            AmrexError::invalid(r.path(), format!("refinement ratio {q} is too large"))
        })?;
    }
    let stated = match item {
        RatioItem::Scalar(x) => vec![(0, x)],
        RatioItem::Vector(v) => vec![(0, v[0]), (1, v[1]), (2, v[2])],
    };
    for (a, s) in stated {
        if s != i64::from(out[a]) {
            return Err(AmrexError::invalid(
                r.path(),
                format!("refinement ratio from level {l} is given as {s} on axis {a}, but the level domains imply {}", out[a]),
            ));
        }
    }
    Ok(out)
}

fn check_cell_size<R: BufRead>(
    r: &TextReader<R>,
    l: usize,
    domain: &IBox,
    dx: &[f64; 3],
    lo: &[f64; 3],
    hi: &[f64; 3],
) -> Result<()> {
    let e = domain.extent();
    for a in 0..3 {
        let implied = (hi[a] - lo[a]) / e[a] as f64;
        if !(dx[a].is_finite() && dx[a] > 0.0)
            || ((dx[a] - implied) / implied).abs() > CELL_SIZE_TOLERANCE
        {
            return Err(AmrexError::invalid(
                r.path(),
                format!("level {l}: cell size {} on axis {a} disagrees with the problem domain / level domain = {implied}", dx[a]),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<PlotHeader> {
        parse_header(TextReader::new(text.as_bytes(), Path::new("Header")))
    }

    const TWO_LEVELS: &str = "CartGrid-V2.0\n2\nrho\nY(H2) [kg]\n3\n0.5\n1\n-1 -2 0\n1 2 4\n4 4 9\n\
((0,0,0) (1,3,3) (0,0,0)) ((0,0,0) (7,15,15) (0,0,0))\n0 0\n1 1 1\n0.25 0.25 0.25\n0\n0\n\
0 1 0.5\n0\n-1 1\n-2 2\n0 4\nLevel_0/Cell\n1 1 0.5\n0\n-1 0\n-2 0\n0 1\nLevel_1/Cell\nextra stuff\n";

    #[test]
    fn parses_versions_names_and_ratios() {
        let h = parse(TWO_LEVELS).unwrap();
        assert_eq!(h.version, "CartGrid-V2.0");
        assert_eq!(h.fields, ["rho", "Y(H2) [kg]"]);
        assert_eq!(h.levels.len(), 2);
        assert_eq!(h.levels[0].ratio_to_next, [4, 4, 4]);
        assert_eq!(h.levels[1].domain, IBox::new([0; 3], [8, 16, 16]));
        assert_eq!(h.levels[1].cell_prefix, "Level_1/Cell");
        assert_eq!(h.prob_lo, [-1.0, -2.0, 0.0]);
    }

    #[test]
    fn rejects_2d_and_wrong_ratio() {
        let e = parse(&TWO_LEVELS.replace("Y(H2) [kg]\n3\n", "Y(H2) [kg]\n2\n")).unwrap_err();
        assert!(e.to_string().contains("2D is not supported"), "{e}");
        let e = parse(&TWO_LEVELS.replace("\n4 4 9\n", "\n2\n")).unwrap_err();
        assert!(e.to_string().contains("imply 4"), "{e}");
    }

    #[test]
    fn version_strings() {
        assert!(looks_like_version("HyperCLaw-V1.1"));
        assert!(looks_like_version("CartGrid-V2.0\r"));
        assert!(!looks_like_version("hello world"));
        assert!(!looks_like_version("-V1"));
    }
}
