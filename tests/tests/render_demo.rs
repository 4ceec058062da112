//! `amr-render demo`: synthesize, convert and render end to end through the `.amrk` pipeline.

use amr_render::output::exr_file::read_channel;
use amr_render::render_cmd::run_demo;

#[test]
fn demo_renders_a_frame_with_coverage() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo.exr");
    run_demo(&out).unwrap();
    let (w, h, a) = read_channel(&out, "A").unwrap();
    assert_eq!((w, h), (800, 600));
    let covered = a.iter().filter(|&&x| x > 0.0).count();
    assert!(covered > a.len() / 50, "only {covered} pixels covered");
    assert!(out.with_extension("png").exists());
}
