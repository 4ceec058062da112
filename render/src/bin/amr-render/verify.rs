//! `amr-render verify FILE`: reads the whole file and checks everything `open` does not.

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
/// recomputes the stored tight leaf ranges (layout version 3), which must hold the data's.
pub fn run(args: &VerifyArgs) -> anyhow::Result<()> {
    let file = open_mapped(&args.file)?;
    let report = file
        .verify()
        .map_err(|e| e.in_file(&args.file))
        .map_err(|e| anyhow::anyhow!("verification failed: {e}"))?;
    let tight = check_tight_ranges(&file)
        .map_err(|e| anyhow::anyhow!("verification failed: {}: {e}", args.file.display()))?;
    println!("{}: OK: {report}{tight}", args.file.display());
    Ok(())
}

/// Recomputes every stored tight leaf range and checks that the stored one holds it: an error
/// naming the first leaf whose stored range misses values the data give (the extraction would
/// skip that leaf's surface) and their count, or what was checked. A stored range wider than the
/// data's is conservative, only slower to extract (a file written by an earlier, looser
/// computation), and is counted in the report.
fn check_tight_ranges(file: &MappedFile) -> anyhow::Result<String> {
    if !file.has_tight_ranges() {
        return Ok(String::new());
    }
    let (mut checked, mut wider) = (0usize, 0usize);
    for (field, info) in file.fields().iter().enumerate() {
        let mut ex = Extractor::new(file, field, CACHE_BYTES)?;
        ex.set_page_release(PageRelease::new(file));
        let computed = ex.computed_tight_ranges()?;
        let stored = |l: usize| {
            file.tight_range(field, l as u32)
                .unwrap_or((f32::NAN, f32::NAN))
        };
        // Stored ranges are validated at open (no NaN, `lo <= hi` or the empty range), so
        // these comparisons are exact; the empty computed range is held by every range.
        let holds = |s: (f32, f32), c: (f32, f32)| s.0 <= c.0 && c.1 <= s.1;
        let bad: Vec<_> = computed
            .iter()
            .enumerate()
            .filter(|&(l, &c)| !holds(stored(l), c))
            .collect();
        if let Some(&(leaf, &c)) = bad.first() {
            let s = stored(leaf);
            anyhow::bail!(
                "field '{}': {} of {} stored tight leaf ranges miss values the data give; leaf \
                 {leaf} stores {}..{}, the data give {}..{}",
                info.name,
                bad.len(),
                computed.len(),
                s.0,
                s.1,
                c.0,
                c.1
            );
        }
        wider += computed
            .iter()
            .enumerate()
            .filter(|&(l, &c)| {
                let s = stored(l);
                s.0.to_bits() != c.0.to_bits() || s.1.to_bits() != c.1.to_bits()
            })
            .count();
        checked += computed.len();
    }
    let wider = match wider {
        0 => String::new(),
        n => format!(" ({n} stored wider than the data's: correct, slower to extract)"),
    };
    Ok(format!("; {checked} tight leaf ranges recomputed{wider}"))
}
