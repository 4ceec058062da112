//! The BVH and its frames do not depend on the thread count: surfaces built and rendered on 1, 2
//! and 3 threads, in small chunks (a two-level BVH) and in one BVH, give the same pixels bit for
//! bit, and each build puts the refs in the same order.

use crate::support::render::{frame_bits, on_threads, sphere_grid};
use amr_render::bvh::BvhBuilder;
use amr_render::render::render_surfaces;
use amr_render::shade::IsoSpec;
use amr_render::trace::Surface;
use amr_render::{CameraPlacement, View};

fn isos() -> Vec<IsoSpec> {
    vec![
        "0:gold".parse::<IsoSpec>().unwrap(),
        "0.45:#4080ff:0.35".parse::<IsoSpec>().unwrap(),
    ]
}

/// The refs of each surface and the frame's bits (colour, alpha, depth, normal), built and
/// rendered on `threads` threads with chunks of `chunk_refs` refs.
fn build_and_render(threads: usize, chunk_refs: usize) -> (Vec<Vec<u64>>, Vec<u32>) {
    let grid = sphere_grid(7, 3, 2, 1.3, [0.0; 3], 1.0);
    on_threads(threads, || {
        let mut b = BvhBuilder::new();
        b.chunk_refs = chunk_refs;
        let surfaces: Vec<Surface> = isos()
            .iter()
            .map(|s| Surface::build_owned(&grid, s.value, grid.active(s.value), &mut b))
            .collect();
        let view = View {
            camera: Some(CameraPlacement {
                pos: [9.0, -5.0, 6.5],
                look_at: Some([2.0, 2.0, 2.0]),
                up: None,
            }),
            size: (96, 72),
            shadows: true,
            ao_rays: 2,
            ..View::default()
        };
        let f = render_surfaces(&grid, &surfaces, &isos(), &view, &|_| {})
            .unwrap()
            .frame;
        let refs = surfaces.iter().map(|s| s.bvh.refs().to_vec()).collect();
        (refs, frame_bits(&f))
    })
}

#[test]
fn frames_and_bvhs_are_the_same_on_any_thread_count() {
    for chunk_refs in [32, usize::MAX] {
        let (refs, frame) = build_and_render(1, chunk_refs);
        let n: Vec<usize> = refs.iter().map(Vec::len).collect();
        assert!(
            n.iter().all(|&n| n > 200),
            "chunks of {chunk_refs}: too few refs: {n:?}"
        );
        for threads in [2, 3] {
            let (r, f) = build_and_render(threads, chunk_refs);
            assert!(
                r == refs,
                "chunks of {chunk_refs}, {threads} threads: other ref order"
            );
            assert!(
                f == frame,
                "chunks of {chunk_refs}, {threads} threads: other pixels"
            );
        }
    }
}
