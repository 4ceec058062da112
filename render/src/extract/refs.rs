//! Active-voxel references: 64 bits, `leaf << 32 | id`, and what decoding one gives.
//!
//! Inside a leaf of level `L`, cells are numbered by their linear index (x fastest) in the box
//! of level-`L` cells overlapping the leaf; a brick holds at most 2^28 cells, so the index fits
//! 28 bits. Ids below [`DUAL_BASE`] are single octants, `cell * 8 + octant`; ids from
//! [`DUAL_BASE`] are merged dual cells, `DUAL_BASE + cell` naming the dual cell's lowest cell.

/// First id of a merged dual cell.
pub const DUAL_BASE: u32 = 1 << 31;

/// What an id inside a leaf names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LocalVoxel {
    /// Octant `octant` of local cell `cell`.
    Octant {
        /// Local cell index.
        cell: u32,
        /// Octant, 0 to 7 (bit `a` set: upper side of axis `a`).
        octant: u8,
    },
    /// The dual cell whose lowest corner is the centre of local cell `cell`.
    Dual {
        /// Local index of the dual cell's lowest cell.
        cell: u32,
    },
}

impl LocalVoxel {
    /// The 32-bit id.
    pub fn id(self) -> u32 {
        match self {
            LocalVoxel::Octant { cell, octant } => cell * 8 + u32::from(octant),
            LocalVoxel::Dual { cell } => DUAL_BASE + cell,
        }
    }

    /// The voxel an id names.
    pub fn from_id(id: u32) -> Self {
        if id >= DUAL_BASE {
            LocalVoxel::Dual {
                cell: id - DUAL_BASE,
            }
        } else {
            LocalVoxel::Octant {
                cell: id / 8,
                octant: (id % 8) as u8,
            }
        }
    }
}

/// A 64-bit reference from a leaf index and a local voxel.
pub fn make_ref(leaf: u32, v: LocalVoxel) -> u64 {
    u64::from(leaf) << 32 | u64::from(v.id())
}

/// The leaf index and local voxel of a reference.
pub fn split_ref(r: u64) -> (u32, LocalVoxel) {
    ((r >> 32) as u32, LocalVoxel::from_id(r as u32))
}
