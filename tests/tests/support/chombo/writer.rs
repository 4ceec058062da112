//! Writes a [`Desc`] as an HDF5 file in Chombo's layout: the root and level attributes of
//! `WriteAMRHierarchyHDF5` (AMRIO.cpp) or of `AMR::writeCheckpointFile` (AMR.cpp) with an
//! `AMRLevel::writeCheckpointLevel`, and each `LevelData` as `CH_HDF5`'s
//! `write(handle, LevelData, NAME, outputGhost)` stores it: `NAME:datatype=0`,
//! `NAME:offsets=0` and `NAME_attributes` (`comps`, `objectType`, `ghost`, `outputGhost`).

use std::path::Path;

use hdf5_metno::types::{
    CompoundField, CompoundType, FixedAscii, IntSize, TypeDescriptor, VarLenUnicode,
};
use hdf5_metno::{File, Group, H5Type, Location};

use super::{ghost_value, value, Desc};

/// A box as Chombo's writer has it in memory.
#[derive(H5Type, Clone, Copy, Debug)]
#[repr(C)]
pub struct RawBox {
    lo_i: i32,
    lo_j: i32,
    lo_k: i32,
    hi_i: i32,
    hi_j: i32,
    hi_k: i32,
}

/// A 2D box, for the 2D fixture.
#[derive(H5Type, Clone, Copy, Debug)]
#[repr(C)]
struct RawBox2 {
    lo_i: i32,
    lo_j: i32,
    hi_i: i32,
    hi_j: i32,
}

#[derive(H5Type, Clone, Copy, Debug)]
#[repr(C)]
pub struct RawIntVect {
    intvecti: i32,
    intvectj: i32,
    intvectk: i32,
}

/// Chombo's IntVect compound for `v`.
pub fn int_vect(v: [i32; 3]) -> RawIntVect {
    RawIntVect {
        intvecti: v[0],
        intvectj: v[1],
        intvectk: v[2],
    }
}

/// Chombo's box compound for inclusive corners `[lo_i, lo_j, lo_k, hi_i, hi_j, hi_k]`.
pub fn raw_box(b: [i32; 6]) -> RawBox {
    RawBox {
        lo_i: b[0],
        lo_j: b[1],
        lo_k: b[2],
        hi_i: b[3],
        hi_j: b[4],
        hi_k: b[5],
    }
}

/// Chombo's on-disk box compound: the six members, then 8 bytes of padding (the index type).
pub fn padded_box_type() -> TypeDescriptor {
    let names = ["lo_i", "lo_j", "lo_k", "hi_i", "hi_j", "hi_k"];
    TypeDescriptor::Compound(CompoundType {
        fields: names
            .iter()
            .enumerate()
            .map(|(i, n)| CompoundField {
                name: n.to_string(),
                ty: TypeDescriptor::Integer(IntSize::U4),
                offset: 4 * i,
                index: i,
            })
            .collect(),
        size: 32,
    })
}

pub fn attr<T: H5Type>(loc: &Location, name: &str, v: &T) -> hdf5_metno::Result<()> {
    loc.new_attr::<T>().create(name)?.write_scalar(v)
}

/// A fixed-length string attribute sized to its text, as Chombo writes them.
pub fn attr_str(loc: &Location, name: &str, v: &str) -> hdf5_metno::Result<()> {
    let a = loc
        .new_attr_builder()
        .empty_as(TypeDescriptor::FixedAscii(v.len()))
        .create(name)?;
    a.write_scalar(&FixedAscii::<256>::from_ascii(v).map_err(|e| e.to_string())?)
}

/// Writes `d` to `path`.
pub fn write(path: &Path, d: &Desc) -> hdf5_metno::Result<()> {
    let file = File::create(path)?;
    let root: &Group = &file;
    let root_attrs = [
        ("num_levels", d.levels.len() as i32),
        ("num_components", d.comps.len() as i32),
        ("iteration", 7),
        ("max_level", d.levels.len() as i32 - 1),
    ];
    for (name, v) in root_attrs {
        let skip = d.omit_root.iter().any(|o| o == name) || (d.boxes_only && name == "num_levels");
        if !skip {
            attr(root, name, &v)?;
        }
    }
    attr(root, "time", &1.25f64)?;
    if d.checkpoint_marker {
        for l in 0..d.levels.len() {
            attr(root, &format!("regrid_interval_{l}"), &2i32)?;
            attr(root, &format!("steps_since_regrid_{l}"), &1i32)?;
        }
    }
    attr_str(root, "filetype", "VanillaAMRFileType")?;
    for (c, name) in d.comps.iter().enumerate() {
        let key = format!("component_{c}");
        if d.omit_root.contains(&key) {
            continue;
        }
        if c == 1 {
            // One variable-length UTF-8 string, as h5py writes a Python str.
            let v: VarLenUnicode = name
                .parse()
                .map_err(|e: hdf5_metno::types::StringError| e.to_string())?;
            attr(root, &key, &v)?;
        } else {
            attr_str(root, &key, name)?;
        }
    }
    let global = root.create_group("Chombo_global")?;
    attr(&global, "SpaceDim", &d.space_dim)?;
    attr(&global, "testReal", &0.0f64)?;

    let nc = d.comps.len();
    for (l, lev) in d.levels.iter().enumerate() {
        let grp = root.create_group(&format!("level_{l}"))?;
        let omit = |n: &str| d.omit_level.iter().any(|(ol, on)| *ol == l && on == n);
        if !omit("dx") {
            attr(&grp, "dx", &lev.dx)?;
        }
        attr(&grp, "dt", &0.01f64)?;
        attr(&grp, "time", &1.25f64)?;
        if !omit("ref_ratio") {
            attr(&grp, "ref_ratio", &lev.ref_ratio)?;
        }
        if !omit("prob_domain") {
            if d.space_dim == 2 {
                let b = lev.domain;
                attr(
                    &grp,
                    "prob_domain",
                    &RawBox2 {
                        lo_i: b[0],
                        lo_j: b[1],
                        hi_i: b[3],
                        hi_j: b[4],
                    },
                )?;
            } else {
                let a = grp
                    .new_attr_builder()
                    .empty_as(padded_box_type())
                    .create("prob_domain")?;
                a.write_scalar(&raw_box(lev.domain))?;
            }
        }
        let boxes: Vec<RawBox> = lev.boxes.iter().map(|&b| raw_box(b)).collect();
        if d.huge_boxes == Some(l) {
            grp.new_dataset_builder()
                .empty_as(padded_box_type())
                .shape(1usize << 33)
                .create("boxes")?;
        } else if !omit("boxes") {
            let ds = grp
                .new_dataset_builder()
                .empty_as(padded_box_type())
                .shape(boxes.len())
                .create("boxes")?;
            ds.write_raw(&boxes)?;
        }
        if d.boxes_only {
            continue;
        }
        let vars = if d.per_variable.is_empty() {
            vec![("data".to_string(), nc)]
        } else {
            d.per_variable.clone()
        };
        let mut first = 0;
        for (var, n) in vars {
            write_var(&grp, d, l, &var, first..first + n, &omit)?;
            first += n;
        }
    }
    file.close()?;
    Ok(())
}

/// Writes components `comps` of level `l` as the `LevelData` `name`: box after box, component
/// after component, x fastest, ghost layers included.
fn write_var(
    grp: &Group,
    d: &Desc,
    l: usize,
    name: &str,
    comps: std::ops::Range<usize>,
    omit: &dyn Fn(&str) -> bool,
) -> hdf5_metno::Result<()> {
    let lev = &d.levels[l];
    let g = d.ghost.map(i64::from);
    let da = grp.create_group(&format!("{name}_attributes"))?;
    if !omit("outputGhost") {
        attr(&da, "outputGhost", &int_vect(d.ghost))?;
    }
    attr(&da, "ghost", &int_vect(d.ghost))?;
    attr(&da, "comps", &(comps.len() as i32))?;
    attr_str(&da, "objectType", "FArrayBox")?;

    let mut data: Vec<f64> = Vec::new();
    let mut offsets: Vec<i64> = vec![0];
    for (bi, b) in lev.boxes.iter().enumerate() {
        let lo = [b[0], b[1], b[2]].map(i64::from);
        let hi = [b[3], b[4], b[5]].map(i64::from);
        for c in comps.clone() {
            for z in lo[2] - g[2]..=hi[2] + g[2] {
                for y in lo[1] - g[1]..=hi[1] + g[1] {
                    for x in lo[0] - g[0]..=hi[0] + g[0] {
                        let p = [x, y, z];
                        let inside = (0..3).all(|a| lo[a] <= p[a] && p[a] <= hi[a]);
                        let mut v = if inside {
                            value(l, c, p)
                        } else {
                            ghost_value(l, c, p)
                        };
                        if let Some((pl, pb, pc, pp, pv)) = d.poison {
                            if (pl, pb, pc, pp) == (l, bi, c, p) {
                                v = pv;
                            }
                        }
                        data.push(v);
                    }
                }
            }
        }
        offsets.push(data.len() as i64);
    }
    if let Some((tl, n)) = d.truncate_data {
        if tl == l {
            data.truncate(data.len().saturating_sub(n));
        }
    }
    let (data_name, offsets_name) = (format!("{name}:datatype=0"), format!("{name}:offsets=0"));
    if !omit(&offsets_name) {
        grp.new_dataset_builder()
            .with_data(&offsets)
            .create(offsets_name.as_str())?;
    }
    if d.unwritten_data == Some(l) {
        grp.new_dataset::<f64>()
            .shape(data.len())
            .create(data_name.as_str())?;
    } else if !omit(&data_name) {
        if d.f64 {
            grp.new_dataset_builder()
                .with_data(&data)
                .create(data_name.as_str())?;
        } else {
            let f: Vec<f32> = data.iter().map(|&v| v as f32).collect();
            grp.new_dataset_builder()
                .with_data(&f)
                .create(data_name.as_str())?;
        }
    }
    Ok(())
}
