//! The box of merged dual cells a decode frame keeps ([`DecodeFrame::duals`]) holds exactly the
//! lowest cells of the dual cells whose eight cells the finest cells place in the leaf: the test
//! a decode made per dual cell before the box was kept.

use amr_render::extract::leaf::LeafFrame;
use amr_render::extract::DecodeFrame;
use amr_render::reconstruct::Sampler;

use crate::support::hierarchy::{build, standard_cases};

#[test]
fn the_kept_box_holds_the_dual_cells_inside_the_leaf() {
    for case in standard_cases(2) {
        let (_, file) = build(&case);
        let s = Sampler::new(&file, 0, 64 << 20).unwrap();
        let grid = s.grid();
        let mut kept = 0;
        for leaf in 0..file.num_leaves() as u32 {
            let Some(frame) = LeafFrame::new(&s, leaf) else {
                continue;
            };
            let d = DecodeFrame::new(grid, frame).unwrap();
            let inside = |c: [i64; 3]| {
                let at = grid.finest_cell(grid.centre(frame.level, c), 7);
                frame.finest.contains_cell(at) && grid.cell_of(frame.level, at) == c
            };
            let b = frame.cells;
            for z in b.lo[2]..b.hi[2] {
                for y in b.lo[1]..b.hi[1] {
                    for x in b.lo[0]..b.hi[0] {
                        let c = [x, y, z];
                        let want = inside(c) && inside(c.map(|v| v + 1));
                        assert_eq!(
                            d.duals.contains_cell(c),
                            want,
                            "{case:?}: leaf {leaf} {c:?}"
                        );
                        kept += usize::from(want);
                    }
                }
            }
        }
        assert!(kept > 0, "{case:?}: no dual cell inside a leaf");
    }
}

/// A corner of the kept dual cells read from the leaf's brick ([`DecodeFrame::corner_value`])
/// is the cell, and the value, that locating its centre gives.
#[test]
fn a_corner_read_from_the_brick_is_the_located_cell() {
    for case in standard_cases(2) {
        let (_, file) = build(&case);
        let s = Sampler::new(&file, 0, 64 << 20).unwrap();
        let grid = s.grid();
        let mut read = 0;
        for leaf in 0..file.num_leaves() as u32 {
            let Some(frame) = LeafFrame::new(&s, leaf) else {
                continue;
            };
            let mut d = DecodeFrame::new(grid, frame).unwrap();
            d.index_duals_in(&s.brick_cells(frame.brick));
            let Some(values) = s.values_in_place(frame.brick) else {
                continue;
            };
            let b = frame.cells;
            for z in b.lo[2]..=b.hi[2] {
                for y in b.lo[1]..=b.hi[1] {
                    for x in b.lo[0]..=b.hi[0] {
                        let c = [x, y, z];
                        let Some(value) = d.corner_value(values, c) else {
                            continue;
                        };
                        let at = grid.finest_cell(grid.centre(frame.level, c), 7);
                        let cell = s.locate(at).unwrap().unwrap();
                        assert_eq!(
                            (cell.level, cell.cell, cell.value.to_bits()),
                            (frame.level, c, value.to_bits()),
                            "{case:?}: leaf {leaf} {c:?}"
                        );
                        read += 1;
                    }
                }
            }
        }
        assert!(read > 0, "{case:?}: no corner read from a brick");
    }
}
