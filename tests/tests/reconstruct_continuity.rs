//! The octant reconstruction is continuous across level boundaries, bit-identical at shared
//! octant vertices, and interpolating at cell centres; every failure names its seed.

use std::collections::{HashMap, HashSet};

use crate::support::hierarchy::{build, standard_cases, Case, Rng};
use amr_format::AmrkFile;
use amr_render::reconstruct::{Octant, Reconstruction, Sampler, VertexMemo};

/// Every leaf cell of the file, once, with its value.
fn leaf_cells(s: &Sampler<'_, Vec<u8>>) -> Vec<(u32, [i64; 3], f32)> {
    let file = s.file();
    let mut seen = HashSet::new();
    let mut out = Vec::new();
    for leaf in 0..file.num_leaves() as u32 {
        let Some((_, level)) = s.leaf_top(leaf) else {
            continue;
        };
        let cells = s.grid().level_box(level, &file.tree().leaf_box(leaf));
        for z in cells.lo[2]..cells.hi[2] {
            for y in cells.lo[1]..cells.hi[1] {
                for x in cells.lo[0]..cells.hi[0] {
                    if seen.insert((level, [x, y, z])) {
                        let at = s.grid().finest_cell(s.grid().centre(level, [x, y, z]), 7);
                        let c = s.locate(at).unwrap().unwrap();
                        out.push((level, [x, y, z], c.value));
                    }
                }
            }
        }
    }
    out
}

fn sampler<'a>(case: &Case, file: &'a AmrkFile<Vec<u8>>, field: usize) -> Sampler<'a, Vec<u8>> {
    Sampler::new(file, field, 64 << 20).unwrap_or_else(|e| panic!("{case:?}: {e}"))
}

#[test]
fn shared_vertices_are_bit_identical() {
    let mut shared_across_levels = 0u64;
    for case in standard_cases(3) {
        let (_, file) = build(&case);
        for field in 0..2 {
            let s = sampler(&case, &file, field);
            let mut memo = VertexMemo::default();
            let mut seen: HashMap<[i64; 3], (f32, u32, Octant)> = HashMap::new();
            for (level, cell, _) in leaf_cells(&s) {
                for octant in 0..8u8 {
                    let o = Octant {
                        level,
                        cell,
                        octant,
                    };
                    let v = s
                        .octant_values_memo(&o, &mut memo)
                        .unwrap()
                        .expect("level 0 covers the domain");
                    let (lo, hi) = s.octant_box(&o);
                    for (n, &value) in v.iter().enumerate() {
                        let p = [0, 1, 2].map(|a| if n >> a & 1 == 1 { hi[a] } else { lo[a] });
                        match seen.get(&p) {
                            None => {
                                seen.insert(p, (value, level, o));
                            }
                            Some(&(first, first_level, first_o)) => {
                                assert!(
                                    first == value,
                                    "seed {} ({case:?}) field {field}: vertex {p:?} is {first} in {first_o:?} \
                                     but {value} in {o:?}",
                                    case.seed
                                );
                                if first_level != level {
                                    shared_across_levels += 1;
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    assert!(
        shared_across_levels > 1000,
        "only {shared_across_levels} vertices shared across levels"
    );
    eprintln!("{shared_across_levels} vertex values shared across levels, all bit-identical");
}

#[test]
fn continuous_across_level_boundary_faces_edges_and_corners() {
    let delta = (-20f64).exp2();
    let mut worst = 0f64;
    let mut points = 0u64;
    for case in standard_cases(3) {
        let (_, file) = build(&case);
        let mut rng = Rng(case.seed ^ 0xC0FFEE);
        for field in 0..2 {
            let s = sampler(&case, &file, field);
            let mut faces = Vec::new();
            for (level, cell, _) in leaf_cells(&s) {
                let centre = s.grid().centre(level, cell);
                for octant in 0..8u8 {
                    for a in 0..3 {
                        let up = octant >> a & 1 == 1;
                        let (lo, hi) = s.octant_box(&Octant {
                            level,
                            cell,
                            octant,
                        });
                        let face = if up { hi[a] } else { lo[a] };
                        let mut across = centre;
                        across[a] = face;
                        let dir = if up { 7 } else { 7 & !(1 << a) };
                        let f = s.grid().finest_cell(across, dir as u8);
                        let Some(n) = s.locate(f).unwrap() else {
                            continue;
                        };
                        if n.level != level && s.grid().contains_point(across) {
                            faces.push((level, cell, octant, a, face));
                        }
                    }
                }
            }
            for _ in 0..faces.len().min(150) {
                let (level, cell, octant, a, face) = faces[rng.below(faces.len() as u64) as usize];
                let sc = s.grid().scale(level);
                let (lo, hi) = s.octant_box(&Octant {
                    level,
                    cell,
                    octant,
                });
                let mut p = [0f64; 3];
                for b in 0..3 {
                    p[b] = if b == a {
                        face as f64
                    } else {
                        match rng.below(3) {
                            0 => lo[b] as f64,
                            1 => hi[b] as f64,
                            _ => lo[b] as f64 + rng.f64() * sc[b] as f64,
                        }
                    };
                }
                let mut vals = Vec::new();
                for d in 0..8 {
                    let q = [0, 1, 2].map(|b| p[b] + if d >> b & 1 == 1 { delta } else { -delta });
                    if let Some(v) = s.sample(q, Reconstruction::Octant).unwrap() {
                        vals.push(v as f64);
                    }
                }
                let (mn, mx) = vals
                    .iter()
                    .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
                let diff = mx - mn;
                points += 1;
                worst = worst.max(diff);
                assert!(
                    diff <= 2e-5,
                    "seed {} ({case:?}) field {field}: values {vals:?} around {p:?} differ by {diff}",
                    case.seed
                );
            }
        }
    }
    assert!(points > 1000, "only {points} boundary points");
    eprintln!(
        "{points} points on level boundaries: largest difference a tiny step either side {worst:e}"
    );
}

#[test]
fn octant_interpolates_at_cell_centres_away_from_boundaries() {
    let mut checked = 0u64;
    for case in standard_cases(2) {
        let (_, file) = build(&case);
        let s = sampler(&case, &file, 1);
        for (level, cell, value) in leaf_cells(&s) {
            let inner = (0..27).all(|k| {
                let d = [k % 3 - 1, k / 3 % 3 - 1, k / 9 - 1];
                let c = [0, 1, 2].map(|a| cell[a] + d[a]);
                if !s.grid().domain(level).contains_cell(c) {
                    return false;
                }
                let at = s.grid().finest_cell(s.grid().centre(level, c), 7);
                s.locate(at).unwrap().is_some_and(|n| n.level == level)
            });
            if !inner {
                continue;
            }
            let p = s.grid().centre(level, cell).map(|v| v as f64);
            for m in [
                Reconstruction::Octant,
                Reconstruction::Nearest,
                Reconstruction::Current,
            ] {
                let got = s.sample(p, m).unwrap().unwrap();
                assert_eq!(
                    got, value,
                    "seed {} ({case:?}): {m:?} at the centre of {cell:?}",
                    case.seed
                );
            }
            checked += 1;
        }
    }
    assert!(checked > 100, "only {checked} interior cells");
}

#[test]
fn world_coordinates_round_trip_far_from_the_origin() {
    for case in standard_cases(2).into_iter().filter(|c| c.far) {
        let (_, file) = build(&case);
        let s = sampler(&case, &file, 0);
        let mut rng = Rng(case.seed);
        let ext = s.grid().extent();
        for _ in 0..200 {
            let p = [0, 1, 2].map(|a| rng.f64() * 2.0 * ext[a] as f64);
            let back = s.grid().to_doubled(s.grid().to_world(p));
            let err = (0..3).map(|a| (back[a] - p[a]).abs()).fold(0.0, f64::max);
            assert!(
                err < 1e-3,
                "seed {} ({case:?}): {p:?} comes back as {back:?}",
                case.seed
            );
            let a = s
                .sample_world(s.grid().to_world(p), Reconstruction::Octant)
                .unwrap();
            assert!(a.is_some() || (0..3).any(|a| back[a] < 0.0 || back[a] > 2.0 * ext[a] as f64));
        }
    }
}
