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
/// recomputes the stored tight leaf ranges (layout version 3).
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

/// Recomputes every stored tight leaf range and compares it, bit for bit, with the stored one:
/// an error naming the first mismatch and their count, or what was checked.
fn check_tight_ranges(file: &MappedFile) -> anyhow::Result<String> {
    if !file.has_tight_ranges() {
        return Ok(String::new());
    }
    let mut checked = 0usize;
    for (field, info) in file.fields().iter().enumerate() {
        let mut ex = Extractor::new(file, field, CACHE_BYTES)?;
        ex.set_page_release(PageRelease::new(file));
        let computed = ex.computed_tight_ranges()?;
        let differ = |(l, c): (usize, &(f32, f32))| {
            let stored = file
                .tight_range(field, l as u32)
                .unwrap_or((f32::NAN, f32::NAN));
            let same = stored.0.to_bits() == c.0.to_bits() && stored.1.to_bits() == c.1.to_bits();
            (!same).then_some((l, stored, *c))
        };
        let bad: Vec<_> = computed.iter().enumerate().filter_map(differ).collect();
        if let Some(&(leaf, stored, c)) = bad.first() {
            anyhow::bail!(
                "field '{}': {} of {} stored tight leaf ranges differ from the data's; leaf \
                 {leaf} stores {}..{}, the data give {}..{}",
                info.name,
                bad.len(),
                computed.len(),
                stored.0,
                stored.1,
                c.0,
                c.1
            );
        }
        checked += computed.len();
    }
    Ok(format!("; {checked} tight leaf ranges recomputed"))
}
