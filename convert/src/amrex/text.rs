//! Reading AMReX's text headers: a line reader with line numbers, and a scanner for the
//! parenthesised integer syntax of boxes, `IntVect`s and real descriptors.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

use amr_format::IBox;

use super::error::{AmrexError, Result};

/// Largest magnitude of a cell index accepted (far beyond any real domain, far below overflow).
const MAX_INDEX: i64 = 1 << 40;
/// Longest header line accepted (a `Cell_H` min/max row of a few thousand components fits).
const MAX_LINE: u64 = 16 << 20;

/// Reads a text file line by line, counting lines for error messages.
pub(crate) struct TextReader<R> {
    inner: R,
    path: PathBuf,
    line: usize,
    buf: String,
    peeked: bool,
    eof: bool,
}

impl TextReader<BufReader<File>> {
    /// Opens `path` for line reading.
    pub(crate) fn open(path: &Path) -> Result<Self> {
        let file = File::open(path).map_err(|e| AmrexError::io(path, "cannot open", e))?;
        Ok(TextReader::new(BufReader::new(file), path))
    }
}

impl<R: BufRead> TextReader<R> {
    /// Reads lines from `inner`; `path` names it in errors.
    pub(crate) fn new(inner: R, path: &Path) -> Self {
        TextReader {
            inner,
            path: path.to_path_buf(),
            line: 0,
            buf: String::new(),
            peeked: false,
            eof: false,
        }
    }

    /// The file being read.
    pub(crate) fn path(&self) -> &Path {
        &self.path
    }

    /// The next line; the end of the file is an error saying that `what` was expected.
    pub(crate) fn next(&mut self, what: &str) -> Result<String> {
        if !self.peeked {
            self.fill()?;
        }
        self.peeked = false;
        if self.eof {
            return Err(self.error(format!("expected {what}, found the end of the file")));
        }
        Ok(self.buf.trim_end_matches(['\n', '\r']).to_string())
    }

    /// The next line, left to be returned again by the next call to [`TextReader::next`].
    pub(crate) fn peek(&mut self) -> Result<Option<&str>> {
        if !self.peeked {
            self.fill()?;
            self.peeked = true;
        }
        Ok(if self.eof {
            None
        } else {
            Some(self.buf.trim_end_matches(['\n', '\r']))
        })
    }

    /// A syntax error at the current line.
    pub(crate) fn error(&self, msg: impl Into<String>) -> AmrexError {
        AmrexError::Syntax {
            path: self.path.clone(),
            line: self.line,
            msg: msg.into(),
        }
    }

    fn fill(&mut self) -> Result<()> {
        self.buf.clear();
        if self.eof {
            return Ok(());
        }
        self.line += 1;
        let n = (&mut self.inner)
            .take(MAX_LINE)
            .read_line(&mut self.buf)
            .map_err(|e| {
                if e.kind() == std::io::ErrorKind::InvalidData {
                    self.error("not text (invalid UTF-8): is this really an AMReX header?")
                } else {
                    AmrexError::io(&self.path, format!("reading line {}", self.line), e)
                }
            })?;
        if n == 0 {
            self.eof = true;
        } else if n as u64 == MAX_LINE && !self.buf.ends_with('\n') {
            return Err(self.error(format!("line longer than {MAX_LINE} bytes")));
        }
        Ok(())
    }
}

/// The parts of one line parsed as whitespace-separated values of type `T`.
pub(crate) fn parse_all<T: std::str::FromStr>(line: &str) -> std::result::Result<Vec<T>, String> {
    line.split_whitespace()
        .map(|t| {
            t.parse::<T>()
                .map_err(|_| format!("'{t}' is not a {}", short_type::<T>()))
        })
        .collect()
}

fn short_type<T>() -> &'static str {
    let name = std::any::type_name::<T>();
    if name.contains("f64") || name.contains("f32") {
        "number"
    } else {
        "integer"
    }
}

/// A box as AMReX writes it: inclusive corners and a centring per axis (0 = cell-centred).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct AmrexBox {
    /// Lowest cell on each axis.
    pub lo: [i64; 3],
    /// Highest cell on each axis (inclusive).
    pub hi: [i64; 3],
    /// 0 for cell-centred, 1 for node-centred, per axis.
    pub centering: [i64; 3],
}

impl AmrexBox {
    /// The same cells as a half-open [`IBox`], or an error for an inverted or overflowing box.
    pub(crate) fn to_ibox(self) -> std::result::Result<IBox, String> {
        // `unsigned_abs`: `i64::MIN.abs()` overflows (it wraps to itself in a release build).
        if self
            .lo
            .iter()
            .chain(&self.hi)
            .any(|c| c.unsigned_abs() > MAX_INDEX as u64)
        {
            return Err(format!(
                "box {:?}..={:?} has an index beyond +-{MAX_INDEX}",
                self.lo, self.hi
            ));
        }
        let mut hi = [0i64; 3];
        for a in 0..3 {
            hi[a] = self.hi[a].checked_add(1).ok_or("box corner overflows")?;
            if hi[a] <= self.lo[a] {
                return Err(format!(
                    "box {:?}..={:?} is empty or inverted",
                    self.lo, self.hi
                ));
            }
        }
        let b = IBox::new(self.lo, hi);
        b.num_cells()
            .ok_or_else(|| format!("box {:?}..={:?} has too many cells", self.lo, self.hi))?;
        Ok(b)
    }
}

/// A cursor over one line of AMReX's parenthesised syntax.
pub(crate) struct Scan<'a> {
    s: &'a [u8],
    pos: usize,
}

impl<'a> Scan<'a> {
    /// Scans `s` from its start.
    pub(crate) fn new(s: &'a str) -> Self {
        Scan {
            s: s.as_bytes(),
            pos: 0,
        }
    }

    fn skip_ws(&mut self) {
        while self.pos < self.s.len() && self.s[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
    }

    /// True when only whitespace is left.
    pub(crate) fn at_end(&mut self) -> bool {
        self.skip_ws();
        self.pos >= self.s.len()
    }

    /// The next non-blank character, not consumed.
    pub(crate) fn peek(&mut self) -> Option<char> {
        self.skip_ws();
        self.s.get(self.pos).map(|&c| c as char)
    }

    /// Consumes `c` if it comes next.
    pub(crate) fn eat(&mut self, c: char) -> bool {
        if self.peek() == Some(c) {
            self.pos += 1;
            true
        } else {
            false
        }
    }

    /// Consumes `c` or fails saying what came instead.
    pub(crate) fn expect(&mut self, c: char) -> std::result::Result<(), String> {
        if self.eat(c) {
            Ok(())
        } else {
            Err(format!(
                "expected '{c}' at column {}, found {}",
                self.pos + 1,
                self.found()
            ))
        }
    }

    /// Consumes the literal word `w` or fails.
    pub(crate) fn expect_word(&mut self, w: &str) -> std::result::Result<(), String> {
        self.skip_ws();
        if self.s[self.pos..].starts_with(w.as_bytes()) {
            self.pos += w.len();
            Ok(())
        } else {
            Err(format!(
                "expected '{w}' at column {}, found {}",
                self.pos + 1,
                self.found()
            ))
        }
    }

    fn found(&self) -> String {
        match self.s.get(self.pos..) {
            Some(rest) if !rest.is_empty() => {
                let rest = String::from_utf8_lossy(&rest[..rest.len().min(20)]).into_owned();
                format!("'{rest}'")
            }
            _ => "the end of the line".to_string(),
        }
    }

    /// A signed decimal integer.
    pub(crate) fn int(&mut self) -> std::result::Result<i64, String> {
        self.skip_ws();
        let start = self.pos;
        if matches!(self.s.get(self.pos), Some(b'-' | b'+')) {
            self.pos += 1;
        }
        while self.pos < self.s.len() && self.s[self.pos].is_ascii_digit() {
            self.pos += 1;
        }
        let text = std::str::from_utf8(&self.s[start..self.pos]).unwrap_or("");
        text.parse::<i64>().map_err(|_| {
            self.pos = start;
            format!(
                "expected an integer at column {}, found {}",
                start + 1,
                self.found()
            )
        })
    }

    /// An `IntVect` `(a,b,c)`; a vector of another length is an error naming its dimension.
    pub(crate) fn ivect(&mut self) -> std::result::Result<[i64; 3], String> {
        self.expect('(')?;
        let mut v = Vec::with_capacity(3);
        loop {
            v.push(self.int()?);
            if self.eat(')') {
                break;
            }
            self.expect(',')?;
        }
        <[i64; 3]>::try_from(v.as_slice()).map_err(|_| {
            format!(
                "expected a 3D index vector, found one with {} components",
                v.len()
            )
        })
    }

    /// A box `((lo) (hi) (type))`.
    pub(crate) fn amrex_box(&mut self) -> std::result::Result<AmrexBox, String> {
        self.expect('(')?;
        let lo = self.ivect()?;
        let hi = self.ivect()?;
        let centering = self.ivect()?;
        self.expect(')')?;
        Ok(AmrexBox { lo, hi, centering })
    }

    /// The rest of the line, consumed.
    pub(crate) fn rest(&mut self) -> &'a str {
        let r = &self.s[self.pos..];
        self.pos = self.s.len();
        std::str::from_utf8(r).unwrap_or("")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scans_boxes_and_vectors() {
        let mut s = Scan::new(" ((0,-8,0) (7, 15,7) (0,0,0)) (2,2,1)");
        let b = s.amrex_box().unwrap();
        assert_eq!(b.lo, [0, -8, 0]);
        assert_eq!(b.to_ibox().unwrap(), IBox::new([0, -8, 0], [8, 16, 8]));
        assert_eq!(s.ivect().unwrap(), [2, 2, 1]);
        assert!(s.at_end());
        let huge = Scan::new("((-9000000000000000000,0,0) (9000000000000000000,1,1) (0,0,0))")
            .amrex_box()
            .unwrap();
        assert!(huge.to_ibox().unwrap_err().contains("beyond"));
        // The most negative i64, whose `abs` overflows (found by the dump fuzzer: a domain
        // from i64::MIN to 7 passed and divided by zero later).
        let least = Scan::new("((-9223372036854775808,0,0) (7,7,7) (0,0,0))")
            .amrex_box()
            .unwrap();
        assert!(least.to_ibox().unwrap_err().contains("beyond"));
        assert!(Scan::new("((0,0) (7,7) (0,0))")
            .amrex_box()
            .unwrap_err()
            .contains("2 components"));
    }

    #[test]
    fn reader_counts_lines_and_peeks() {
        let text = "a\r\nb\n\nc";
        let mut r = TextReader::new(text.as_bytes(), Path::new("x"));
        assert_eq!(r.next("a").unwrap(), "a");
        assert_eq!(r.peek().unwrap(), Some("b"));
        assert_eq!(r.next("b").unwrap(), "b");
        assert_eq!(r.next("blank").unwrap(), "");
        assert_eq!(r.next("c").unwrap(), "c");
        let e = r.next("more").unwrap_err().to_string();
        assert!(e.contains("line 5") && e.contains("expected more"), "{e}");
    }
}
