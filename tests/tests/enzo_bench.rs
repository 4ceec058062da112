//! Writes a large Enzo dataset for `docs/benchmarks-convert.md` (ignored by default):
//!
//! `ENZO_BENCH_DIR=/path/DD0001 cargo test --release -p amr-tests --test tests enzo_bench -- --ignored`
//!
//! Packed HDF5 in Enzo's layout (`tests/tests/support/enzo/writer.rs`): a 256³ root split into
//! eight 128³ grids, each refined (`RefineBy` 2) over its central 64³ cells by one 128³ grid;
//! four float64 fields, active cells only; 33.6 M cells, 1.07 GB of cell data.

use crate::support::enzo::writer::{write, Desc, GridDesc};

#[test]
#[ignore = "writes about 1.1 GB; run by hand for the benchmark"]
fn write_benchmark_dataset() {
    let Some(dir) = std::env::var_os("ENZO_BENCH_DIR") else {
        eprintln!("set ENZO_BENCH_DIR to the directory to write");
        return;
    };
    let mut roots = Vec::new();
    for i in 0..8i64 {
        let lo = [(i % 2) * 128, ((i / 2) % 2) * 128, (i / 4) * 128];
        let child_lo = lo.map(|v| 2 * v + 64);
        roots.push(GridDesc {
            lo,
            hi: lo.map(|v| v + 128),
            children: vec![GridDesc {
                lo: child_lo,
                hi: child_lo.map(|v| v + 128),
                children: vec![],
            }],
        });
    }
    let d = Desc {
        top: [256; 3],
        left: [0.0; 3],
        right: [1.0; 3],
        fields: vec![
            "Density".into(),
            "Temperature".into(),
            "TotalEnergy".into(),
            "x-velocity".into(),
        ],
        write_ghosts: false,
        roots,
        ..Desc::three_levels()
    };
    let params = write(std::path::Path::new(&dir), "DD0001", &d);
    eprintln!("wrote {}", params.display());
}
