//! `amr-bench suite`: regenerates `docs/benchmarks-suite.md` and its plots in one run.
//!
//! Every section is measured in this one process on this one machine, seeded, so that numbers
//! quoted side by side are comparable and a rerun reproduces everything but the timings.
//!
//! - [`figure8`]: the paper's Figure 8, isocontours of the four reconstructions.
//! - [`recon`]: reconstruction error against the analytic field, and leaks through a closed surface.
//! - [`tradeoff`]: run time against hit and image error, hybrid against sample mode.
//! - [`stress`]: random hierarchies, placements, scales and cameras.
//! - [`scale`]: synthesis, open, extraction, BVH and frame cost against cell count.

pub mod common;
pub mod figure8;
pub mod plot;
pub mod recon;
pub mod scale;
pub mod scale_render;
pub mod stress;
pub mod tradeoff;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;

pub use common::Machine;

/// What `amr-bench suite` is asked to do, validated.
#[derive(Clone, Debug)]
pub struct SuiteConfig {
    /// Directory that receives `benchmarks-suite.md` and `img/*.png`.
    pub out: PathBuf,
    /// Small sizes and few repetitions (about a minute), for smoke tests.
    pub quick: bool,
    /// Skip the scale section (which writes the largest files).
    pub skip_scale: bool,
    /// Run only the scale section and replace it in the existing `benchmarks-suite.md`.
    pub scale_only: bool,
    /// Largest cell count of the scale section: sizes above it are left out, and a larger value
    /// is added as one more size (the file larger than memory is about 8e9 cells).
    pub max_cells: Option<u64>,
    /// Directory for the datasets (default: the system's temporary directory); the scale
    /// section's largest file needs about 4 bytes per cell of free space there.
    pub scratch: Option<PathBuf>,
    /// The `amr-bench` executable the scale section renders with, in a child process
    /// ([`scale_render`]) so that peak RSS is the render's own; `None` renders in this process.
    pub render_exe: Option<PathBuf>,
    /// Run only these sections ([`SECTIONS`] names) and replace them in the existing document;
    /// empty: run every section and write the document anew.
    pub only: Vec<String>,
}

/// Section names for [`SuiteConfig::only`], in document order.
pub const SECTIONS: [&str; 5] = ["figure8", "recon", "tradeoff", "stress", "scale"];

impl SuiteConfig {
    /// The command line that reproduces this run, as the document quotes it.
    pub fn command(&self) -> String {
        let mut c = format!("amr-bench suite --out {}", self.out.display());
        if self.quick {
            c.push_str(" --quick");
        }
        if self.skip_scale {
            c.push_str(" --skip-scale");
        }
        if self.scale_only {
            c.push_str(" --scale-only");
        }
        if let Some(n) = self.max_cells {
            c.push_str(&format!(" --max-cells {n:e}"));
        }
        if self.scratch.is_some() {
            c.push_str(" --scratch DIR");
        }
        for name in &self.only {
            c.push_str(" --only ");
            c.push_str(name);
        }
        c
    }
}

/// Context shared by every section.
pub struct Ctx {
    /// The configuration.
    pub cfg: SuiteConfig,
    /// The machine the numbers come from.
    pub machine: Machine,
    /// Where PNGs go.
    pub img: PathBuf,
    /// Scratch directory for datasets, removed at the end.
    pub scratch: PathBuf,
}

impl Ctx {
    /// The two lines every table is preceded by: command and machine.
    pub fn provenance(&self) -> String {
        format!(
            "Command: `{}` (release build). Machine: {}.\n",
            self.cfg.command(),
            self.machine
        )
    }
}

/// Runs every section and writes the document (or, with [`SuiteConfig::only`], runs those
/// sections and replaces them in the existing document); prints progress to stderr.
pub fn run_suite(cfg: SuiteConfig) -> anyhow::Result<PathBuf> {
    if let Some(bad) = cfg.only.iter().find(|n| !SECTIONS.contains(&n.as_str())) {
        anyhow::bail!(
            "--only {bad}: no such section (sections: {})",
            SECTIONS.join(", ")
        );
    }
    let path = cfg.out.join("benchmarks-suite.md");
    let existing = if cfg.only.is_empty() {
        None
    } else {
        Some(std::fs::read_to_string(&path).with_context(|| {
            format!(
                "--only replaces sections of {}, which cannot be read",
                path.display()
            )
        })?)
    };
    let img = cfg.out.join("img");
    std::fs::create_dir_all(&img).with_context(|| format!("cannot create {}", img.display()))?;
    let scratch = cfg
        .scratch
        .clone()
        .unwrap_or_else(std::env::temp_dir)
        .join(format!("amr-bench-suite-{}", std::process::id()));
    std::fs::create_dir_all(&scratch)
        .with_context(|| format!("cannot create {}", scratch.display()))?;
    let path = cfg.out.join("benchmarks-suite.md");
    let previous =
        if cfg.scale_only {
            Some(std::fs::read_to_string(&path).with_context(|| {
                format!("--scale-only updates {}: cannot read it", path.display())
            })?)
        } else {
            None
        };
    let ctx = Ctx {
        cfg,
        machine: Machine::read(),
        img,
        scratch,
    };
    let result = match (&previous, &existing) {
        (Some(doc), _) => run_scale_only(&ctx, doc),
        (None, Some(doc)) => replace_sections(&ctx, doc),
        (None, None) => run_sections(&ctx),
    };
    let _ = std::fs::remove_dir_all(&ctx.scratch);
    let body = result?;
    std::fs::write(&path, body).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(path)
}

type Section = fn(&Ctx) -> anyhow::Result<String>;

/// The section called `name` in [`SECTIONS`].
fn section(name: &str) -> (&'static str, Section) {
    match name {
        "figure8" => ("figure 8", figure8::run),
        "recon" => ("reconstruction error and leaks", recon::run),
        "tradeoff" => ("run time against error", tradeoff::run),
        "stress" => ("stability stress", stress::run),
        _ => ("scale", scale::run),
    }
}

fn run_one(ctx: &Ctx, name: &str) -> anyhow::Result<String> {
    let (title, f) = section(name);
    let t = Instant::now();
    eprintln!("bench suite: {title} ...");
    let s = f(ctx).with_context(|| format!("section '{title}' failed"))?;
    eprintln!(
        "bench suite: {title} done in {:.1} s",
        t.elapsed().as_secs_f64()
    );
    Ok(s)
}

/// `doc` with each section of `--only` replaced by a new run of it (a section spans from its
/// `## ` heading to the next one).
fn replace_sections(ctx: &Ctx, doc: &str) -> anyhow::Result<String> {
    let mut doc = doc.to_owned();
    for name in &ctx.cfg.only {
        let new = run_one(ctx, name)?;
        let heading = new.lines().next().unwrap_or_default().to_owned();
        let start = doc
            .find(&format!("{heading}\n"))
            .with_context(|| format!("the document has no section '{heading}' to replace"))?;
        let after = start + heading.len();
        let end = doc[after..]
            .find("\n## ")
            .map(|i| after + i + 1)
            .or_else(|| doc[after..].find("\n_Whole suite").map(|i| after + i + 1))
            .unwrap_or(doc.len());
        doc.replace_range(start..end, &format!("{new}\n"));
    }
    Ok(doc)
}

fn run_sections(ctx: &Ctx) -> anyhow::Result<String> {
    let start = Instant::now();
    let mut doc = String::new();
    writeln!(
        doc,
        "# Benchmark suite: accuracy, run time against error, stability, scale\n"
    )?;
    writeln!(
        doc,
        "Regenerated end to end by `{}`{}. Machine: {}. Every comparison below was measured side \
         by side in that one run; times are medians of the stated number of runs. Datasets, \
         hierarchies and cameras are seeded, so a rerun changes only the timings.\n",
        ctx.cfg.command(),
        if ctx.cfg.quick {
            " (the quick, smoke-test sizes: numbers are indicative only)"
        } else {
            ""
        },
        ctx.machine
    )?;
    let names = SECTIONS
        .iter()
        .filter(|&&n| n != "scale" || !ctx.cfg.skip_scale);
    for name in names {
        doc.push_str(&run_one(ctx, name)?);
        doc.push('\n');
    }
    writeln!(
        doc,
        "_Whole suite: {:.0} s._",
        start.elapsed().as_secs_f64()
    )?;
    Ok(doc)
}

/// Runs the scale section and puts it in place of the one in `doc`.
fn run_scale_only(ctx: &Ctx, doc: &str) -> anyhow::Result<String> {
    let (start, end) = scale_span(doc).context(
        "the existing benchmarks-suite.md has no '## Scale' section to replace; run the whole suite",
    )?;
    let t = Instant::now();
    eprintln!("bench suite: scale ...");
    let section = scale::run(ctx).context("section 'scale' failed")?;
    eprintln!(
        "bench suite: scale done in {:.1} s",
        t.elapsed().as_secs_f64()
    );
    Ok(format!("{}{}\n{}", &doc[..start], section, &doc[end..]))
}

/// Byte range of the `## Scale` section in `doc`: up to the next `## ` heading or the closing
/// `_Whole suite` line.
fn scale_span(doc: &str) -> Option<(usize, usize)> {
    let start = doc.find("## Scale\n")?;
    let rest = &doc[start + 1..];
    let end = [rest.find("\n## "), rest.find("\n_Whole suite")]
        .into_iter()
        .flatten()
        .min()
        .map_or(doc.len(), |e| start + 1 + e + 1);
    Some((start, end))
}

/// `path` relative to the document's directory, for image links.
pub fn img_link(ctx: &Ctx, name: &str) -> String {
    let _ = Path::new(&ctx.img);
    format!("img/{name}")
}

#[cfg(test)]
mod tests {
    use super::scale_span;

    #[test]
    fn the_scale_section_is_found_between_headings() {
        let doc = "# T\n\n## Stress\n\nx\n\n## Scale\n\nold\n\n_Whole suite: 1 s._\n";
        let (a, b) = scale_span(doc).unwrap();
        assert_eq!(&doc[a..b], "## Scale\n\nold\n\n");
        let doc = "## Scale\n\nold\n## Next\n";
        let (a, b) = scale_span(doc).unwrap();
        assert_eq!(&doc[a..b], "## Scale\n\nold\n");
        assert!(scale_span("## Stress\n").is_none());
    }
}
