//! Smoke test of `amr-bench suite --quick`: run as a user runs it (the scale section renders in
//! child processes), it writes the document and its plots into a temporary directory, every
//! section is there, and every PNG it links is a PNG of a sensible size.

use std::process::Command;

/// Width and height from a PNG's signature and IHDR chunk.
fn png_size(bytes: &[u8]) -> Option<(u32, u32)> {
    if bytes.len() < 24 || &bytes[..8] != b"\x89PNG\r\n\x1a\n" || &bytes[12..16] != b"IHDR" {
        return None;
    }
    let be = |i: usize| u32::from_be_bytes(bytes[i..i + 4].try_into().unwrap());
    Some((be(16), be(20)))
}

#[test]
fn quick_suite_writes_markdown_and_pngs() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_amr-bench"))
        .args(["suite", "--quick", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "amr-bench suite failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let md = std::fs::read_to_string(dir.path().join("benchmarks-suite.md")).unwrap();
    for heading in [
        "## Figure 8",
        "## Reconstruction error",
        "## Run time against error",
        "## Stability stress",
        "## Scale",
    ] {
        assert!(md.contains(heading), "missing section {heading}");
    }
    assert!(md.contains("Machine: "), "no machine line");
    assert!(
        md.contains("by a child `amr-bench render-stats"),
        "the scale section did not render in a child process"
    );
    let links: Vec<&str> = md
        .split("](img/")
        .skip(1)
        .map(|s| s.split(')').next().unwrap())
        .collect();
    assert!(links.len() >= 4, "too few plots: {links:?}");
    for name in links {
        let bytes = std::fs::read(dir.path().join("img").join(name)).unwrap();
        let (w, h) = png_size(&bytes).unwrap_or_else(|| panic!("{name} is not a PNG"));
        assert!(w > 100 && h > 100, "{name} is {w}x{h}");
    }
}
