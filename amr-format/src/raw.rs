//! The on-disk structures of an `.amrk` file, byte for byte, and nothing else.
//!
//! Every struct is `#[repr(C)]`, little-endian, made only of byte-order-aware zerocopy
//! integers (alignment 1), so it can be read in place from any byte buffer. Sizes are
//! pinned by compile-time assertions. The layout is described in `docs/format.md`.

use zerocopy::little_endian::{F32, F64, I64, U32, U64};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

/// First eight bytes of the file and of the footer.
pub const MAGIC: [u8; 8] = *b"\x89AMRK\r\n\x1a";
/// Layout version: changes only when the byte layout changes. Version 2 added the block range
/// tables ([`Footer::block_tables`]), version 3 the tight leaf ranges ([`Footer::tight_ranges`]),
/// version 4 the part bounds ([`Footer::part_table`]).
pub const LAYOUT_VERSION: u32 = 4;
/// The oldest layout version readers still open (version 1: no block range tables).
pub const OLDEST_LAYOUT_VERSION: u32 = 1;
/// Cells per axis of the blocks the writer's block range tables cover.
pub const BLOCK_CELLS: u32 = 4;
/// Alignment of every section and of every brick's data.
pub const ALIGN: u64 = 64;

/// Brick data stored as raw little-endian f32, x fastest.
pub const ENCODING_RAW: u32 = 0;
/// Brick data stored as one zstd frame of the f32 bytes shuffled into four byte planes.
pub const ENCODING_ZSTD_SHUFFLED: u32 = 1;

/// Kind tag of a [`KdNode`] that is a leaf (kinds 0, 1, 2 are inner nodes split on x, y, z).
pub const KD_LEAF: u32 = 3;

/// Bit of [`SimulationStamp::flags`]: `time` holds the simulation time.
pub const STAMP_HAS_TIME: u32 = 1;
/// Bit of [`SimulationStamp::flags`]: `step` holds the simulation step.
pub const STAMP_HAS_STEP: u32 = 2;

/// When in a simulation a file's data was written (24 bytes, in the footer). All zero (no flag)
/// in files that do not say, such as every file written before it existed: the bytes were
/// reserved and zero, so the layout version did not change.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
pub struct SimulationStamp {
    /// Simulation time, finite, when [`STAMP_HAS_TIME`] is set.
    pub time: F64,
    /// Simulation step (cycle), when [`STAMP_HAS_STEP`] is set.
    pub step: I64,
    /// [`STAMP_HAS_TIME`] | [`STAMP_HAS_STEP`].
    pub flags: U32,
    /// Zero.
    pub reserved: U32,
}

/// File header at offset 0 (64 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
pub struct Header {
    /// [`MAGIC`].
    pub magic: [u8; 8],
    /// [`LAYOUT_VERSION`] of the writer.
    pub layout_version: U32,
    /// Size of this header in bytes (64).
    pub header_size: U32,
    /// Zero.
    pub reserved: [u8; 48],
}

/// An (offset, length) pair locating a section in the file, in bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
pub struct Section {
    /// Absolute byte offset from the start of the file.
    pub offset: U64,
    /// Length in bytes.
    pub len: U64,
}

/// File footer, the last 256 bytes of the file; written last.
#[repr(C)]
#[derive(Clone, Copy, Debug, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
pub struct Footer {
    /// [`MAGIC`].
    pub magic: [u8; 8],
    /// [`LAYOUT_VERSION`] of the writer.
    pub layout_version: U32,
    /// Size of this footer in bytes (256).
    pub footer_size: U32,
    /// Number of levels.
    pub num_levels: U32,
    /// Number of fields.
    pub num_fields: U32,
    /// Number of bricks.
    pub num_bricks: U32,
    /// Number of kd-tree nodes.
    pub num_nodes: U32,
    /// Number of kd-tree leaves.
    pub num_leaves: U32,
    /// Number of entries of the leaves' brick list.
    pub brick_list_len: U32,
    /// Zero.
    pub reserved0: [u8; 8],
    /// The metadata region: every section below, and the checksummed bytes.
    pub metadata: Section,
    /// [`LevelRecord`] × num_levels.
    pub levels: Section,
    /// [`FieldRecord`] × num_fields.
    pub fields: Section,
    /// [`BrickRecord`] × num_bricks.
    pub bricks: Section,
    /// [`KdNode`] × num_nodes, depth first (a node's first child follows it).
    pub nodes: Section,
    /// [`KdLeaf`] × num_leaves.
    pub leaves: Section,
    /// u32 brick indices × brick_list_len.
    pub brick_list: Section,
    /// UTF-8 field names.
    pub strings: Section,
    /// Version 2: [`Section`] × num_fields, inside the metadata: where each field's
    /// [`BlockRange`] table lies in the data area. Zero (reserved) in version 1.
    pub block_tables: Section,
    /// Version 2: cells per axis of a block of the block range tables. Zero in version 1.
    pub block_cells: U32,
    /// Version 3: [`LeafRange`] × num_leaves × num_fields (field after field), inside the
    /// metadata: each leaf's tight range, every value the octant reconstruction can give on the
    /// voxels the leaf owns. Empty when the writer was not given the computation, zero (reserved)
    /// before version 3.
    pub tight_ranges: Section,
    /// Version 4: offset of the [`PartTable`] record inside the metadata; zero when the file
    /// stores no part bounds (and before version 4).
    pub part_table: U64,
    /// Zero.
    pub reserved1: [u8; 4],
    /// When in the simulation the data was written, where the input said.
    pub simulation: SimulationStamp,
    /// CRC-32 of the metadata region.
    pub metadata_crc: U32,
    /// CRC-32 of the footer's bytes before this field.
    pub footer_crc: U32,
}

/// One refinement level (128 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
pub struct LevelRecord {
    /// Physical cell size per axis.
    pub cell_size: [F64; 3],
    /// Physical position of the lower corner of cell (0, 0, 0).
    pub origin: [F64; 3],
    /// Index domain, lower corner (inclusive).
    pub domain_lo: [I64; 3],
    /// Index domain, upper corner (exclusive).
    pub domain_hi: [I64; 3],
    /// Refinement ratio to the next finer level per axis (1 on the finest level).
    pub ratio_to_next: [U32; 3],
    /// Zero.
    pub reserved: [u8; 20],
}

/// One field (64 bytes): its name, global range and where its per-field sections are.
#[repr(C)]
#[derive(Clone, Copy, Debug, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
pub struct FieldRecord {
    /// Offset of the name in the strings section.
    pub name_offset: U32,
    /// Length of the name in bytes.
    pub name_len: U32,
    /// Smallest value of the field over all bricks.
    pub min: F32,
    /// Largest value of the field over all bricks.
    pub max: F32,
    /// The field's brick data region (no other field's bytes inside).
    pub data: Section,
    /// [`BrickData`] × num_bricks for this field, inside the metadata region.
    pub brick_data: Section,
    /// [`LeafRange`] × num_leaves for this field, inside the metadata region.
    pub leaf_ranges: Section,
}

/// One brick (56 bytes): a box of cells of one level.
#[repr(C)]
#[derive(Clone, Copy, Debug, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
pub struct BrickRecord {
    /// Lower cell corner in the level's index space (inclusive).
    pub lo: [I64; 3],
    /// Upper cell corner (exclusive).
    pub hi: [I64; 3],
    /// Refinement level.
    pub level: U32,
    /// Zero.
    pub reserved: U32,
}

/// Where one field's values of one brick are stored (32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
pub struct BrickData {
    /// Absolute file offset, a multiple of [`ALIGN`], inside the field's data region.
    pub offset: U64,
    /// Stored length in bytes (cells × 4 when raw).
    pub len: U64,
    /// Smallest value in the brick.
    pub min: F32,
    /// Largest value in the brick.
    pub max: F32,
    /// CRC-32 of the stored bytes.
    pub crc: U32,
    /// [`ENCODING_RAW`] or [`ENCODING_ZSTD_SHUFFLED`].
    pub encoding: U32,
}

/// A kd-tree node (8 bytes).
///
/// Inner node: `a` is the split plane in finest-level cells relative to the domain's lower
/// corner; `b & 3` is the axis (0, 1, 2) and `b >> 2` the index of the second child (the first
/// child is the next node). Leaf: `b & 3 == KD_LEAF` and `a` is the leaf index.
#[repr(C)]
#[derive(Clone, Copy, Debug, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
pub struct KdNode {
    /// Split position, or leaf index.
    pub a: U32,
    /// Kind in the low two bits, second child index above them.
    pub b: U32,
}

/// A kd-tree leaf (32 bytes): its cells and the bricks under it.
#[repr(C)]
#[derive(Clone, Copy, Debug, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
pub struct KdLeaf {
    /// Lower corner in finest-level cells relative to the domain's lower corner.
    pub lo: [U32; 3],
    /// Upper corner (exclusive), same coordinates.
    pub hi: [U32; 3],
    /// First entry in the brick list: the finest brick covering the leaf, then coarser ones.
    pub brick_start: U32,
    /// Number of brick-list entries (0 for a leaf no brick covers).
    pub brick_count: U32,
}

/// A leaf's conservative value range for one field (8 bytes); in the tight leaf ranges (version
/// 3) of a leaf without data, `min` is +inf and `max` is -inf.
#[repr(C)]
#[derive(Clone, Copy, Debug, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
pub struct LeafRange {
    /// No reconstruction value inside the leaf is below this.
    pub min: F32,
    /// No reconstruction value inside the leaf is above this.
    pub max: F32,
}

/// Where the part bounds lie (64 bytes, version 4, inside the metadata): a range for each part
/// of each leaf the renderer extracts part by part.
///
/// A leaf's parts are the boxes of `part_cells`^3 cells of its level, aligned to the lower
/// corner of the leaf's first brick, that overlap the leaf, x fastest; a leaf the renderer
/// extracts whole has none. Each part's range holds every corner value of every voxel whose
/// lower corner lies in the part (`(+inf, -inf)` when none does).
#[repr(C)]
#[derive(Clone, Copy, Debug, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
pub struct PartTable {
    /// Cells per axis of a part (of the leaf's level).
    pub part_cells: U32,
    /// Zero.
    pub reserved0: U32,
    /// U64 × (num_leaves + 1), inside the metadata: leaf `l`'s parts are entries
    /// `starts[l]..starts[l + 1]` of each field's ranges.
    pub starts: Section,
    /// [`LeafRange`] × `starts[num_leaves]` × num_fields, inside the metadata, field after field.
    pub ranges: Section,
    /// Zero.
    pub reserved1: [u8; 24],
}

/// The value range of one block of a brick's cells, for one field (8 bytes, version 2).
///
/// A field's table holds, brick after brick in brick order, the blocks of each brick's cells
/// (`block_cells` per axis, the last block along an axis cut short by the brick's end), x
/// fastest; a brick's entries start after those of every brick before it.
#[repr(C)]
#[derive(Clone, Copy, Debug, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
pub struct BlockRange {
    /// Smallest value of the block's cells.
    pub min: F32,
    /// Largest value of the block's cells.
    pub max: F32,
}

const _: () = assert!(size_of::<Header>() == 64);
const _: () = assert!(size_of::<Section>() == 16);
const _: () = assert!(size_of::<Footer>() == 256);
const _: () = assert!(size_of::<SimulationStamp>() == 24);
const _: () = assert!(size_of::<LevelRecord>() == 128);
const _: () = assert!(size_of::<FieldRecord>() == 64);
const _: () = assert!(size_of::<BrickRecord>() == 56);
const _: () = assert!(size_of::<BrickData>() == 32);
const _: () = assert!(size_of::<KdNode>() == 8);
const _: () = assert!(size_of::<KdLeaf>() == 32);
const _: () = assert!(size_of::<LeafRange>() == 8);
const _: () = assert!(size_of::<BlockRange>() == 8);
const _: () = assert!(size_of::<PartTable>() == 64);

/// Rounds `x` up to the next multiple of [`ALIGN`].
pub const fn align_up(x: u64) -> u64 {
    x.div_ceil(ALIGN) * ALIGN
}
