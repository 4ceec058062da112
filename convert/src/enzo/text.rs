//! The `Key = values` lines Enzo's text files are made of (`fprintf(fptr, "Key = ...")` in
//! `WriteParameterFile.C` and `Grid_Group_WriteGrid.C`), read with a size cap.

use std::path::Path;
use std::str::FromStr;

use super::error::{EnzoError, Result};

/// Largest parameter or hierarchy file read (a hierarchy takes about 700 bytes per grid).
pub const MAX_TEXT: u64 = 1 << 30;

/// The whole text file `path`, refused above [`MAX_TEXT`] bytes or when not UTF-8.
pub fn read_text(path: &Path) -> Result<String> {
    let len = std::fs::metadata(path)
        .map_err(|e| EnzoError::io(path, "cannot open", e))?
        .len();
    if len > MAX_TEXT {
        return Err(EnzoError::invalid(
            path,
            format!("{len} bytes, more than the {MAX_TEXT} a text file of Enzo's is read up to"),
        ));
    }
    let bytes = std::fs::read(path).map_err(|e| EnzoError::io(path, "cannot read", e))?;
    String::from_utf8(bytes).map_err(|e| {
        EnzoError::invalid(
            path,
            format!(
                "not text: invalid UTF-8 at byte {}",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

/// `Key = value` split at the first `=`, both trimmed; `None` for other lines.
pub fn key_value(line: &str) -> Option<(&str, &str)> {
    let (k, v) = line.split_once('=')?;
    Some((k.trim(), v.trim()))
}

/// One integer.
pub fn integer(value: &str) -> std::result::Result<i64, String> {
    value
        .parse()
        .map_err(|_| format!("'{value}' is not an integer"))
}

/// Exactly `n` whitespace-separated numbers.
pub fn numbers<T: FromStr>(value: &str, n: usize) -> std::result::Result<Vec<T>, String> {
    let v: Vec<T> = value
        .split_whitespace()
        .map(|w| w.parse::<T>().map_err(|_| format!("'{w}' is not a number")))
        .collect::<std::result::Result<_, _>>()?;
    if v.len() != n {
        return Err(format!("{} values, expected {n}", v.len()));
    }
    Ok(v)
}

/// Three numbers, as an array.
pub fn three<T: FromStr + Copy>(value: &str) -> std::result::Result<[T; 3], String> {
    let v = numbers::<T>(value, 3)?;
    Ok([v[0], v[1], v[2]])
}
