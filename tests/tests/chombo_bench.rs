//! Writes a large GRChombo-like plotfile for `docs/benchmarks-chombo.md` (ignored by default):
//!
//! `CHOMBO_BENCH_FILE=/path/big.3d.hdf5 cargo test --release -p amr-tests --test tests chombo_bench -- --ignored`
//!
//! Three levels (ratio 2 then 4), 32³ boxes with 3 ghost layers (GRChombo's default), four
//! float64 components: 930 MB; `CHOMBO_BENCH_COMPS=5` adds a fifth component for 1.16 GB.
//! Written box by box so the generator's memory stays small.

use crate::support::chombo::writer::{attr, attr_str, int_vect, padded_box_type, raw_box, RawBox};
use hdf5_metno::File;

/// 32³ boxes tiling the cube `[lo, lo + n)` of one level.
fn tile(lo: [i32; 3], n: i32) -> Vec<[i32; 6]> {
    let mut out = Vec::new();
    for z in (lo[2]..lo[2] + n).step_by(32) {
        for y in (lo[1]..lo[1] + n).step_by(32) {
            for x in (lo[0]..lo[0] + n).step_by(32) {
                out.push([x, y, z, x + 31, y + 31, z + 31]);
            }
        }
    }
    out
}

#[test]
#[ignore = "writes about 1 GB; run by hand for the benchmark"]
fn write_benchmark_file() -> hdf5_metno::Result<()> {
    let Some(path) = std::env::var_os("CHOMBO_BENCH_FILE") else {
        eprintln!("set CHOMBO_BENCH_FILE to the file to write");
        return Ok(());
    };
    let ncomps: usize = std::env::var("CHOMBO_BENCH_COMPS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(4)
        .clamp(1, 6);
    let comps = &["chi", "phi", "Ham", "lapse", "K", "shift1"][..ncomps];
    let ghost = 3i64;
    // Level 0: 128³, all 64 boxes. Level 1 (x2): a 192³ region around the centre (216 boxes).
    // Level 2 (x4 from level 1): two 160³ regions around two punctures (250 boxes).
    let mut l2 = tile([300, 420, 430], 160);
    l2.extend(tile([560, 420, 430], 160));
    let levels: Vec<(f64, i32, i32, Vec<[i32; 6]>)> = vec![
        (1.0, 2, 128, tile([0, 0, 0], 128)),
        (0.5, 4, 256, tile([32, 32, 32], 192)),
        (0.125, 1, 1024, l2),
    ];
    let file = File::create(&path)?;
    attr(&file, "num_levels", &3i32)?;
    attr(&file, "num_components", &(comps.len() as i32))?;
    attr(&file, "max_level", &2i32)?;
    attr(&file, "iteration", &100i32)?;
    attr(&file, "time", &12.5f64)?;
    for (c, n) in comps.iter().enumerate() {
        attr_str(&file, &format!("component_{c}"), n)?;
    }
    let global = file.create_group("Chombo_global")?;
    attr(&global, "SpaceDim", &3i32)?;
    attr(&global, "testReal", &0.0f64)?;
    for (l, (dx, ratio, n, boxes)) in levels.iter().enumerate() {
        let grp = file.create_group(&format!("level_{l}"))?;
        attr(&grp, "dx", dx)?;
        attr(&grp, "dt", &(dx * 0.25))?;
        attr(&grp, "time", &12.5f64)?;
        attr(&grp, "ref_ratio", ratio)?;
        let dom = raw_box([0, 0, 0, n - 1, n - 1, n - 1]);
        grp.new_attr_builder()
            .empty_as(padded_box_type())
            .create("prob_domain")?
            .write_scalar(&dom)?;
        let raw: Vec<RawBox> = boxes.iter().map(|&b| raw_box(b)).collect();
        grp.new_dataset_builder()
            .empty_as(padded_box_type())
            .shape(raw.len())
            .create("boxes")?
            .write_raw(&raw)?;
        let da = grp.create_group("data_attributes")?;
        let gv = int_vect([3; 3]);
        attr(&da, "outputGhost", &gv)?;
        attr(&da, "ghost", &gv)?;
        attr(&da, "comps", &(comps.len() as i32))?;
        attr_str(&da, "objectType", "FArrayBox")?;
        let per_box = (32 + 2 * ghost as usize).pow(3) * comps.len();
        let offsets: Vec<i64> = (0..=boxes.len()).map(|i| (i * per_box) as i64).collect();
        grp.new_dataset_builder()
            .with_data(&offsets)
            .create("data:offsets=0")?;
        let data = grp
            .new_dataset::<f64>()
            .shape(boxes.len() * per_box)
            .create("data:datatype=0")?;
        let mut buf = Vec::with_capacity(per_box);
        for (i, b) in boxes.iter().enumerate() {
            buf.clear();
            for c in 0..comps.len() {
                for z in b[2] as i64 - ghost..=b[5] as i64 + ghost {
                    for y in b[1] as i64 - ghost..=b[4] as i64 + ghost {
                        for x in b[0] as i64 - ghost..=b[3] as i64 + ghost {
                            let p = [x, y, z].map(|v| (v as f64 + 0.5) * dx);
                            let r2 = (p[0] - 64.0).powi(2)
                                + (p[1] - 64.0).powi(2)
                                + (p[2] - 64.0).powi(2);
                            buf.push((c as f64 + 1.0) / (1.0 + r2).sqrt() + 1e-9 * x as f64);
                        }
                    }
                }
            }
            data.write_slice(&buf[..], i * per_box..(i + 1) * per_box)?;
        }
    }
    file.close()?;
    Ok(())
}
