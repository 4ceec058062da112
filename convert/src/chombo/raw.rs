//! The on-disk compound types of a Chombo file and the names of its objects, nothing else.
//!
//! Chombo stores boxes and integer vectors as HDF5 compounds whose on-disk size may include
//! padding (a `Box` carries its index type). HDF5 converts compounds member by member, by
//! name, so these structs read any such layout as long as the named members exist;
//! [`crate::chombo::props`] checks that they do before reading.

use hdf5_metno::H5Type;

/// A 3D box as Chombo writes it (`prob_domain`, `boxes`): inclusive corners.
#[derive(H5Type, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(C)]
pub struct RawBox {
    /// Lower corner, x.
    pub lo_i: i32,
    /// Lower corner, y.
    pub lo_j: i32,
    /// Lower corner, z.
    pub lo_k: i32,
    /// Upper corner (inclusive), x.
    pub hi_i: i32,
    /// Upper corner (inclusive), y.
    pub hi_j: i32,
    /// Upper corner (inclusive), z.
    pub hi_k: i32,
}

/// The members of [`RawBox`], as they must appear in the file.
pub const BOX_MEMBERS: [&str; 6] = ["lo_i", "lo_j", "lo_k", "hi_i", "hi_j", "hi_k"];

/// A 3D integer vector as Chombo writes it (`outputGhost`, an anisotropic `ref_ratio`).
#[derive(H5Type, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(C)]
pub struct RawIntVect {
    /// x component.
    pub intvecti: i32,
    /// y component.
    pub intvectj: i32,
    /// z component.
    pub intvectk: i32,
}

/// The members of [`RawIntVect`].
pub const INTVECT_MEMBERS: [&str; 3] = ["intvecti", "intvectj", "intvectk"];

/// A 3D real vector as Chombo writes it (`vec_dx` of anisotropic files).
#[derive(H5Type, Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct RawRealVect {
    /// x component.
    pub x: f64,
    /// y component.
    pub y: f64,
    /// z component.
    pub z: f64,
}

/// The members of [`RawRealVect`].
pub const REALVECT_MEMBERS: [&str; 3] = ["x", "y", "z"];

/// Root attribute: number of levels.
pub const NUM_LEVELS: &str = "num_levels";
/// Root attribute: number of components (fields).
pub const NUM_COMPONENTS: &str = "num_components";
/// Group holding `SpaceDim`.
pub const GLOBAL_GROUP: &str = "Chombo_global";
/// Attribute of [`GLOBAL_GROUP`]: the dimension Chombo was built for.
pub const SPACE_DIM: &str = "SpaceDim";
/// Level attribute: cell size (isotropic).
pub const DX: &str = "dx";
/// Level attribute: cell size per axis (anisotropic files).
pub const VEC_DX: &str = "vec_dx";
/// Level attribute: refinement ratio to the next finer level.
pub const REF_RATIO: &str = "ref_ratio";
/// Level attribute: the level's problem domain.
pub const PROB_DOMAIN: &str = "prob_domain";
/// Level dataset: the boxes.
pub const BOXES: &str = "boxes";
/// The `LevelData` name plotfiles (and GRChombo's checkpoints) store every component under:
/// `data:datatype=0` holds all boxes' data, box after box, component after component.
pub const DATA_NAME: &str = "data";
/// Suffix of a `LevelData`'s offsets dataset (`NAME:offsets=0`, `nboxes + 1` entries).
pub const OFFSETS_SUFFIX: &str = ":offsets=0";
/// Suffix of the group holding a `LevelData`'s attributes (`NAME_attributes`).
pub const ATTRIBUTES_SUFFIX: &str = "_attributes";
/// Attribute of a `NAME_attributes` group: components per box.
pub const COMPS: &str = "comps";
/// Attribute of a `NAME_attributes` group: ghost layers stored around every box.
pub const OUTPUT_GHOST: &str = "outputGhost";
/// Suffix of every LevelData dataset (`NAME:datatype=0`).
pub const DATATYPE_SUFFIX: &str = ":datatype=0";

/// Root attribute AMReX's HDF5 plotfile writer sets to [`AMREX_PLOTFILE_TYPE`].
pub const PLOTFILE_TYPE: &str = "plotfile_type";
/// The [`PLOTFILE_TYPE`] of AMReX's `WriteMultiLevelPlotfileHDF5`.
pub const AMREX_PLOTFILE_TYPE: &str = "VanillaHDF5";
/// Root attribute of AMReX HDF5 plotfiles: 0 for Cartesian coordinates.
pub const COORDINATE_SYSTEM: &str = "coordinate_system";
/// Level attribute of AMReX HDF5 plotfiles: the cell size per axis, three reals.
pub const AMREX_VEC_DX: &str = "Vec_dx";
/// Level attribute of AMReX HDF5 plotfiles: the physical lower corner of the domain.
pub const PROB_LO: &str = "prob_lo";
/// Level attribute of AMReX HDF5 plotfiles: 1 on an axis where the domain is node-centred.
pub const DOMAIN_TYPE: &str = "domain_type";
/// Level attribute of AMReX HDF5 plotfiles: the level's step.
pub const STEPS: &str = "steps";

/// The name of component `i`'s root attribute.
pub fn component(i: usize) -> String {
    format!("component_{i}")
}

/// The name of level `l`'s group.
pub fn level(l: usize) -> String {
    format!("level_{l}")
}
