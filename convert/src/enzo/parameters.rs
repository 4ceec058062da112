//! The parameter file (`NAME`, written by Enzo's `WriteParameterFile.C`): the few parameters
//! that place the grids — the root grid's size, the domain's edges and the refinement factor.

use std::path::{Path, PathBuf};

use super::error::{EnzoError, Result};
use super::text::{integer, key_value, read_text, three};

/// Largest `TopGridDimensions` entry accepted.
pub const MAX_TOP_DIM: i64 = 1 << 31;

/// What the converter needs from the parameter file.
#[derive(Clone, Debug, PartialEq)]
pub struct Parameters {
    /// The parameter file.
    pub path: PathBuf,
    /// `TopGridDimensions`: the root level's cells per axis.
    pub top_dims: [i64; 3],
    /// `RefineBy`: the ratio between consecutive levels, on every axis.
    pub refine_by: i64,
    /// `DomainLeftEdge`.
    pub left: [f64; 3],
    /// `DomainRightEdge`.
    pub right: [f64; 3],
    /// `InitialTime`: the simulation time of the output, when it parses.
    pub time: Option<f64>,
    /// `InitialCycleNumber`: the cycle of the output, when it parses.
    pub cycle: Option<i64>,
}

/// Reads and checks the parameter file `path`.
pub fn read_parameters(path: &Path) -> Result<Parameters> {
    let text = read_text(path)?;
    let mut rank = None;
    let mut top_dims = None;
    let mut refine_by = None;
    let mut left = None;
    let mut right = None;
    let (mut time, mut cycle) = (None, None);
    for (i, line) in text.lines().enumerate() {
        let Some((key, value)) = key_value(line) else {
            continue;
        };
        let syntax = |msg: String| EnzoError::Syntax {
            path: path.to_path_buf(),
            line: i + 1,
            msg: format!("{key}: {msg}"),
        };
        match key {
            "TopGridRank" => rank = Some(integer(value).map_err(syntax)?),
            "TopGridDimensions" => top_dims = Some(three::<i64>(value).map_err(syntax)?),
            "RefineBy" => refine_by = Some(integer(value).map_err(syntax)?),
            "DomainLeftEdge" => left = Some(three::<f64>(value).map_err(syntax)?),
            "DomainRightEdge" => right = Some(three::<f64>(value).map_err(syntax)?),
            // Labels only: a value that does not parse leaves the output unlabelled.
            "InitialTime" => time = value.trim().parse::<f64>().ok().filter(|t| t.is_finite()),
            "InitialCycleNumber" => cycle = value.trim().parse::<i64>().ok(),
            _ => {}
        }
    }
    let missing = |name: &str| {
        EnzoError::invalid(
            path,
            format!("no '{name}' parameter: not an Enzo parameter file, or a damaged one"),
        )
    };
    let rank = rank.ok_or_else(|| missing("TopGridRank"))?;
    if rank != 3 {
        return Err(EnzoError::unsupported(
            path,
            format!("a {rank}D dataset (TopGridRank = {rank}); only 3D datasets can be converted"),
        ));
    }
    let top_dims = top_dims.ok_or_else(|| missing("TopGridDimensions"))?;
    if top_dims.iter().any(|&d| !(1..=MAX_TOP_DIM).contains(&d)) {
        return Err(EnzoError::invalid(
            path,
            format!("TopGridDimensions = {top_dims:?}, expected 1 to {MAX_TOP_DIM} on each axis"),
        ));
    }
    let refine_by = refine_by.ok_or_else(|| missing("RefineBy"))?;
    if !(2..=1024).contains(&refine_by) {
        return Err(EnzoError::invalid(
            path,
            format!("RefineBy = {refine_by}, expected 2 to 1024"),
        ));
    }
    let left = left.ok_or_else(|| missing("DomainLeftEdge"))?;
    let right = right.ok_or_else(|| missing("DomainRightEdge"))?;
    if (0..3).any(|a| !(left[a].is_finite() && right[a].is_finite() && left[a] < right[a])) {
        return Err(EnzoError::invalid(
            path,
            format!("DomainLeftEdge {left:?} and DomainRightEdge {right:?} do not bound a domain"),
        ));
    }
    Ok(Parameters {
        path: path.to_path_buf(),
        top_dims,
        refine_by,
        left,
        right,
        time,
        cycle,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Parameters> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("DD0000");
        std::fs::write(&p, text).unwrap();
        read_parameters(&p)
    }

    #[test]
    fn reads_the_placing_parameters() {
        let p = parse("TopGridRank         = 3\nTopGridDimensions   = 16 8 4 \nRefineBy               = 2\nDomainLeftEdge         = 0 0 0 \nDomainRightEdge        = 1 0.5 0.25 \nDataLabel[0]              = Density\n").unwrap();
        assert_eq!(p.top_dims, [16, 8, 4]);
        assert_eq!(p.refine_by, 2);
        assert_eq!(p.right, [1.0, 0.5, 0.25]);
    }

    #[test]
    fn refuses_2d_and_missing_parameters() {
        let e = parse("TopGridRank = 2\n").unwrap_err().to_string();
        assert!(e.contains("2D"), "{e}");
        let e = parse("TopGridRank = 3\nTopGridDimensions = 4 4 4\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("no 'RefineBy' parameter"), "{e}");
        let e = parse("TopGridRank = 3\nTopGridDimensions = 4 4\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("line 2") && e.contains("2 values, expected 3"),
            "{e}"
        );
    }
}
