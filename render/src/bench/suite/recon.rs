//! Suite section `recon` (not yet written).

use super::Ctx;

/// Runs the section and returns its markdown.
pub fn run(_ctx: &Ctx) -> anyhow::Result<String> {
    Ok(String::new())
}
