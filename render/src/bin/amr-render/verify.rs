//! `amr-render verify FILE`: reads the whole file and checks everything `open` does not.

use std::io::Write;
use std::path::PathBuf;

use amr_render::extract::Extractor;
use amr_render::mapping::{open_mapped, MappedFile, PageRelease};

/// Bytes of the shared cache of decoded compressed bricks while the tight ranges are recomputed.
const CACHE_BYTES: usize = 256 << 20;

/// Arguments of `amr-render verify`.
#[derive(clap::Args, Debug)]
pub struct VerifyArgs {
    /// The .amrk file.
    file: PathBuf,
}

/// Checks data checksums, the tree's tiling, brick lists and conservative ranges, and
/// recomputes the stored tight leaf ranges (layout version 3) and part bounds (version 4),
/// which must hold the data's.
pub fn run(args: &VerifyArgs) -> anyhow::Result<()> {
    let file = open_mapped(&args.file)?;
    let report = file
        .verify()
        .map_err(|e| e.in_file(&args.file))
        .map_err(|e| anyhow::anyhow!("verification failed: {e}"))?;
    let tight = check_tight_ranges(&file)
        .map_err(|e| anyhow::anyhow!("verification failed: {}: {e}", args.file.display()))?;
    writeln!(
        std::io::stdout(),
        "{}: OK: {report}{tight}",
        args.file.display()
    )?;
    Ok(())
}

/// Recomputes every stored tight leaf range and part bound and checks that the stored one holds
/// it: an error naming the first leaf (or part) whose stored range misses values the data give
/// (the extraction would skip that surface) and their count, or what was checked. A stored range
/// wider than the data's is conservative, only slower to extract (a file written by an earlier,
/// looser computation), and is counted in the report.
fn check_tight_ranges(file: &MappedFile) -> anyhow::Result<String> {
    if !file.has_tight_ranges() && file.part_cells().is_none() {
        return Ok(String::new());
    }
    // Stored ranges are validated at open (no NaN, `lo <= hi` or the empty range), so these
    // comparisons are exact; the empty computed range is held by every range.
    let holds = |s: (f32, f32), c: (f32, f32)| c.0 > c.1 || (s.0 <= c.0 && c.1 <= s.1);
    let same = |s: (f32, f32), c: (f32, f32)| {
        s.0.to_bits() == c.0.to_bits() && s.1.to_bits() == c.1.to_bits()
    };
    let mut leaves = Tally::default();
    let mut parts = Tally::default();
    for (field, info) in file.fields().iter().enumerate() {
        let mut ex = Extractor::new(file, field, CACHE_BYTES)?;
        ex.set_page_release(PageRelease::new(file));
        let stored_parts = ex.stored_part_ranges();
        ex.computed_tables(|leaf, c, computed| {
            if let Some(s) = file.tight_range(field, leaf) {
                leaves.add(holds(s, c), same(s, c), || {
                    format!(
                        "field '{}': leaf {leaf} stores {}..{}, the data give {}..{}",
                        info.name, s.0, s.1, c.0, c.1
                    )
                });
            }
            let stored = file.part_ranges(field, leaf).filter(|_| stored_parts);
            for (p, (s, &c)) in stored.unwrap_or(&[]).iter().zip(computed).enumerate() {
                let s = (s.min.get(), s.max.get());
                parts.add(holds(s, c), same(s, c), || {
                    format!(
                        "field '{}': leaf {leaf}, part {p} stores {}..{}, the data give {}..{}",
                        info.name, s.0, s.1, c.0, c.1
                    )
                });
            }
            Ok(())
        })?;
    }
    leaves.check("tight leaf ranges")?;
    parts.check("part bounds")?;
    Ok(format!(
        "{}{}",
        leaves.report("tight leaf ranges"),
        parts.report("part bounds")
    ))
}

/// Stored ranges checked against the data's.
#[derive(Default)]
struct Tally {
    checked: usize,
    /// Stored ranges wider than the data's.
    wider: usize,
    /// Stored ranges that miss values the data give, and the first one's description.
    missing: usize,
    first: Option<String>,
}

impl Tally {
    /// Counts one stored range: whether it holds the data's, whether it equals it, and (asked
    /// only for the first that does not hold) what it is.
    fn add(&mut self, holds: bool, same: bool, what: impl FnOnce() -> String) {
        self.checked += 1;
        if !holds {
            self.missing += 1;
            if self.first.is_none() {
                self.first = Some(what());
            }
        } else if !same {
            self.wider += 1;
        }
    }

    /// An error when a stored range misses values the data give.
    fn check(&self, what: &str) -> anyhow::Result<()> {
        match &self.first {
            None => Ok(()),
            Some(first) => anyhow::bail!(
                "{} of {} stored {what} miss values the data give; {first}",
                self.missing,
                self.checked
            ),
        }
    }

    /// What was checked, for the report.
    fn report(&self, what: &str) -> String {
        if self.checked == 0 {
            return String::new();
        }
        let wider = match self.wider {
            0 => String::new(),
            n => format!(" ({n} stored wider than the data's: correct, slower to extract)"),
        };
        format!("; {} {what} recomputed{wider}", self.checked)
    }
}
