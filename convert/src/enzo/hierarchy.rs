//! The hierarchy file (`NAME.hierarchy`): one block per grid as Enzo's `Grid_Group_WriteGrid.C`
//! prints it (`Grid = N`, `GridRank`, `GridDimension`, `GridStartIndex`, `GridEndIndex`,
//! `GridLeftEdge`, `GridRightEdge`, `NumberOfBaryonFields`, `BaryonFileName`, ...), and the
//! `Pointer: Grid[a]->NextGrid{This,Next}Level = b` lines that link grids into levels (written
//! by `WriteDataHierarchy.C`; yt's Enzo frontend derives the levels from them the same way).

use std::path::Path;

use super::error::{EnzoError, Result};
use super::text::{integer, key_value, read_text, three};

/// One grid's block, as written (nothing checked but the syntax).
#[derive(Clone, Debug, PartialEq)]
pub struct GridEntry {
    /// `Grid = N`: the grid's number, from 1.
    pub id: usize,
    /// Line of `Grid = N`, for messages.
    pub line: usize,
    /// `GridRank`.
    pub rank: Option<i64>,
    /// `GridDimension`: cells stored per axis, ghost zones included.
    pub dims: Option<[i64; 3]>,
    /// `GridStartIndex`: first active cell per axis (0-based, into `dims`).
    pub start: Option<[i64; 3]>,
    /// `GridEndIndex`: last active cell per axis (inclusive).
    pub end: Option<[i64; 3]>,
    /// `GridLeftEdge`: the active region's lower corner, in domain units.
    pub left: Option<[f64; 3]>,
    /// `GridRightEdge`: the active region's upper corner.
    pub right: Option<[f64; 3]>,
    /// `NumberOfBaryonFields`.
    pub nfields: Option<i64>,
    /// `BaryonFileName` as written (often an absolute path of the machine that wrote it).
    pub file: Option<String>,
    /// The grid's level, from the pointers.
    pub level: usize,
    /// The grid's parent (an index into the grid list), from the pointers; `None` on level 0.
    pub parent: Option<usize>,
}

/// Reads the hierarchy file: its grids, numbered 1 to N in order, with levels and parents.
pub fn read_hierarchy(path: &Path) -> Result<Vec<GridEntry>> {
    let text = read_text(path)?;
    let mut grids: Vec<GridEntry> = Vec::new();
    let mut pointers: Vec<(usize, usize, bool, usize)> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        let syntax = |msg: String| EnzoError::Syntax {
            path: path.to_path_buf(),
            line: n,
            msg,
        };
        if let Some(rest) = line.trim().strip_prefix("Pointer:") {
            pointers.push(
                parse_pointer(rest)
                    .map(|(a, this, b)| (n, a, this, b))
                    .map_err(syntax)?,
            );
            continue;
        }
        let Some((key, value)) = key_value(line) else {
            continue;
        };
        if key == "Grid" {
            let id: usize = value
                .parse()
                .map_err(|_| syntax(format!("Grid = '{value}' is not a grid number")))?;
            if id != grids.len() + 1 {
                return Err(syntax(format!(
                    "grid {id} follows grid {}: Enzo numbers grids 1, 2, 3, ... in order",
                    grids.len()
                )));
            }
            grids.push(GridEntry {
                id,
                line: n,
                rank: None,
                dims: None,
                start: None,
                end: None,
                left: None,
                right: None,
                nfields: None,
                file: None,
                level: 0,
                parent: None,
            });
            continue;
        }
        let Some(g) = grids.last_mut() else {
            continue;
        };
        let field = |msg: String| syntax(format!("grid {}, {key}: {msg}", g.id));
        match key {
            "GridRank" => g.rank = Some(integer(value).map_err(field)?),
            "GridDimension" => g.dims = Some(three(value).map_err(field)?),
            "GridStartIndex" => g.start = Some(three(value).map_err(field)?),
            "GridEndIndex" => g.end = Some(three(value).map_err(field)?),
            "GridLeftEdge" => g.left = Some(three(value).map_err(field)?),
            "GridRightEdge" => g.right = Some(three(value).map_err(field)?),
            "NumberOfBaryonFields" => g.nfields = Some(integer(value).map_err(field)?),
            "BaryonFileName" => g.file = Some(value.to_string()),
            _ => {}
        }
    }
    if grids.is_empty() {
        return Err(EnzoError::invalid(
            path,
            "no 'Grid = 1' line: not an Enzo hierarchy file",
        ));
    }
    link_levels(path, &mut grids, &pointers)?;
    Ok(grids)
}

/// `Grid[a]->NextGridThisLevel = b` as `(a, true, b)`, `...NextGridNextLevel...` as `(a, false, b)`.
fn parse_pointer(rest: &str) -> std::result::Result<(usize, bool, usize), String> {
    let bad = || format!("cannot read the pointer '{}'", rest.trim());
    let (lhs, rhs) = rest.split_once('=').ok_or_else(bad)?;
    let lhs = lhs.trim();
    let a = lhs
        .strip_prefix("Grid[")
        .and_then(|s| s.split_once(']'))
        .ok_or_else(bad)?;
    let from: usize = a.0.parse().map_err(|_| bad())?;
    let this = match a.1 {
        "->NextGridThisLevel" => true,
        "->NextGridNextLevel" => false,
        _ => return Err(bad()),
    };
    let to: usize = rhs.trim().parse().map_err(|_| bad())?;
    Ok((from, this, to))
}

/// Gives every grid its level and parent: grid 1 is on level 0; `NextGridNextLevel` makes the
/// target a child of the source (one level finer), `NextGridThisLevel` a sibling. Every grid
/// must be reached exactly once.
fn link_levels(
    path: &Path,
    grids: &mut [GridEntry],
    pointers: &[(usize, usize, bool, usize)],
) -> Result<()> {
    let n = grids.len();
    let mut reached = vec![false; n];
    reached[0] = true;
    for &(line, from, this, to) in pointers {
        let syntax = |msg: String| EnzoError::Syntax {
            path: path.to_path_buf(),
            line,
            msg,
        };
        if to == 0 {
            continue;
        }
        if from == 0 || from > n || to > n {
            return Err(syntax(format!(
                "a pointer from grid {from} to grid {to}, but the grids are numbered 1 to {n}"
            )));
        }
        let (f, t) = (from - 1, to - 1);
        if !reached[f] {
            return Err(syntax(format!(
                "a pointer from grid {from}, which no earlier pointer links to grid 1"
            )));
        }
        if reached[t] {
            return Err(syntax(format!(
                "grid {to} is linked into the hierarchy twice"
            )));
        }
        reached[t] = true;
        if this {
            grids[t].level = grids[f].level;
            grids[t].parent = grids[f].parent;
        } else {
            grids[t].level = grids[f].level + 1;
            grids[t].parent = Some(f);
        }
    }
    if let Some(i) = reached.iter().position(|r| !r) {
        return Err(EnzoError::invalid(
            path,
            format!("grid {} is linked to no level by the Pointer lines", i + 1),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pointers_give_levels_and_parents() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.hierarchy");
        std::fs::write(
            &p,
            "\nGrid = 1\nGridDimension     = 22 22 22 \n\
Pointer: Grid[1]->NextGridThisLevel = 0\nPointer: Grid[1]->NextGridNextLevel = 2\n\n\
Grid = 2\nPointer: Grid[2]->NextGridThisLevel = 3\n\nGrid = 3\n\
Pointer: Grid[3]->NextGridThisLevel = 0\nPointer: Grid[3]->NextGridNextLevel = 0\n\
Pointer: Grid[2]->NextGridNextLevel = 0\n",
        )
        .unwrap();
        let g = read_hierarchy(&p).unwrap();
        assert_eq!(g.iter().map(|g| g.level).collect::<Vec<_>>(), [0, 1, 1]);
        assert_eq!(g[2].parent, Some(0));
        assert_eq!(g[0].dims, Some([22, 22, 22]));
        std::fs::write(&p, "Grid = 1\nGrid = 2\n").unwrap();
        let e = read_hierarchy(&p).unwrap_err().to_string();
        assert!(e.contains("grid 2 is linked to no level"), "{e}");
    }
}
