//! Opening an `.amrk` file in place: every count and offset is checked once, at open, so that
//! every accessor afterwards is a bounds-safe slice of the caller's bytes.
//!
//! The metadata region is copied at open and only the copy is read afterwards: what `open`
//! validated cannot change under the reader when the file is rewritten while it is mapped.

use std::borrow::Cow;
use std::path::{Path, PathBuf};

use zerocopy::little_endian::{U32, U64};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout};

use crate::blocks::block_count;
use crate::compress::{decode_into, Encoding};
use crate::error::{FormatError, Result};
use crate::geometry::IBox;
use crate::hierarchy::{MAX_BRICK_CELLS, MAX_BRICK_EXTENT, MAX_FINEST_EXTENT, MAX_LEVELS};
use crate::kdtree::{KdNode, TreeView};
use crate::meta_copy::MetaCopy;
use crate::raw::{
    self, BlockRange, BrickData, BrickRecord, FieldRecord, Footer, Header, KdLeaf, LeafRange,
    LevelRecord, PartTable, Section,
};

/// One level of an open file.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelInfo {
    /// Physical cell size per axis.
    pub cell_size: [f64; 3],
    /// Physical position of the lower corner of cell (0, 0, 0).
    pub origin: [f64; 3],
    /// Refinement ratio to the next finer level (1 on the finest level).
    pub ratio_to_next: [u32; 3],
    /// The level's index domain.
    pub domain: IBox,
    /// Width of one cell of this level in finest-level cells.
    pub finest_scale: [i64; 3],
}

/// One field of an open file.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldInfo {
    /// The field's name.
    pub name: String,
    /// Smallest value over all bricks.
    pub min: f32,
    /// Largest value over all bricks.
    pub max: f32,
    /// The field's data region.
    pub data: (u64, u64),
    /// True when some brick of the field is compressed.
    pub compressed: bool,
}

/// One brick of an open file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BrickInfo {
    /// Refinement level.
    pub level: u32,
    /// Cells in the level's index space.
    pub cells: IBox,
}

/// Where one field's values of one brick are stored, and their range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrickLocation {
    /// Absolute byte offset in the file.
    pub offset: u64,
    /// Stored length in bytes.
    pub len: u64,
    /// How the values are stored.
    pub encoding: Encoding,
    /// Smallest value in the brick.
    pub min: f32,
    /// Largest value in the brick.
    pub max: f32,
    /// CRC-32 of the stored bytes.
    pub crc: u32,
}

/// One kd-tree leaf of an open file.
#[derive(Clone, Copy, Debug)]
pub struct LeafInfo<'a> {
    /// The leaf's cells, in finest-level cells relative to the domain's lower corner.
    pub bounds: IBox,
    /// The finest brick covering the leaf first, then the coarser bricks under it.
    pub bricks: &'a [U32],
}

impl<'a> LeafInfo<'a> {
    /// Leaf `l` of the table, its bricks in `brick_list` (in range: checked at open).
    fn of(l: &KdLeaf, brick_list: &'a [U32]) -> Self {
        let start = l.brick_start.get() as usize;
        LeafInfo {
            bounds: crate::kdtree::leaf_bounds(l),
            bricks: &brick_list[start..start + l.brick_count.get() as usize],
        }
    }
}

/// An open `.amrk` file over bytes `D` (a `Vec<u8>`, a memory map, ...).
pub struct AmrkFile<D> {
    data: D,
    /// A copy of the metadata region, read instead of `data` for every table.
    meta: MetaCopy,
    footer: Footer,
    levels: Vec<LevelInfo>,
    fields: Vec<FieldInfo>,
    finest_domain: IBox,
    tree_depth: u32,
    path: Option<PathBuf>,
    /// Version 2: cells per axis of a block, and each field's block range table's offset.
    block_tables: Option<(u32, Vec<u64>)>,
    /// Per brick: its first entry in a field's block range table (empty without tables).
    block_starts: Vec<u64>,
    /// Version 3: the file stores tight leaf ranges ([`Footer::tight_ranges`]).
    tight: bool,
    /// Version 4: the part bounds, when stored ([`Footer::part_table`]).
    parts: Option<PartTable>,
}

impl<D: AsRef<[u8]>> AmrkFile<D> {
    /// Opens a file: checks the header, the footer, the metadata checksum and every count,
    /// offset and index in the tables, and everything the tables' users index by: the kd-tree is
    /// a tree whose split planes lie inside their node's region and whose leaf boxes are the
    /// regions the walk reaches them with, and each leaf's first brick covers the leaf. Reads no
    /// brick data; costs O(metadata).
    pub fn open(data: D) -> Result<Self> {
        let bytes = data.as_ref();
        let len = bytes.len() as u64;
        let min_len = (size_of::<Header>() + size_of::<Footer>()) as u64;
        if len < min_len {
            if len >= 8 && bytes[..8] != raw::MAGIC {
                return Err(FormatError::BadMagic { at: "header" });
            }
            return Err(FormatError::Truncated(format!(
                "{len} bytes, less than the {min_len} of a header and footer"
            )));
        }
        let header = Header::read_from_prefix(bytes)
            .map_err(|_| FormatError::Truncated("no header".into()))?
            .0;
        if header.magic != raw::MAGIC {
            return Err(FormatError::BadMagic { at: "header" });
        }
        check_version(header.layout_version.get())?;
        check_size("header", header.header_size.get(), size_of::<Header>())?;
        let footer_bytes = &bytes[bytes.len() - size_of::<Footer>()..];
        let footer = Footer::read_from_bytes(footer_bytes)
            .map_err(|_| FormatError::Truncated("no footer".into()))?;
        if footer.magic != raw::MAGIC {
            return Err(FormatError::Truncated(
                "no footer at the end of the file (the file was cut short or never finished)"
                    .into(),
            ));
        }
        check_version(footer.layout_version.get())?;
        check_size("footer", footer.footer_size.get(), size_of::<Footer>())?;
        let crc = crc32fast::hash(&footer_bytes[..footer_bytes.len() - 4]);
        if crc != footer.footer_crc.get() {
            return Err(FormatError::Checksum {
                what: "footer".into(),
                stored: footer.footer_crc.get(),
                computed: crc,
            });
        }
        let footer_at = len - size_of::<Footer>() as u64;
        let meta = footer.metadata;
        let meta_end = end_of(&meta, "metadata")?;
        if meta.offset.get() < size_of::<Header>() as u64 || meta_end != footer_at {
            return Err(FormatError::Corrupt(format!(
                "metadata region {}..{} does not end at the footer ({footer_at})",
                meta.offset.get(),
                meta_end
            )));
        }
        // The checksum is of the copy, so that the bytes checked are the bytes read afterwards.
        let (meta_bytes, crc) = MetaCopy::of(&bytes[meta.offset.get() as usize..meta_end as usize]);
        if crc != footer.metadata_crc.get() {
            return Err(FormatError::Checksum {
                what: "metadata".into(),
                stored: footer.metadata_crc.get(),
                computed: crc,
            });
        }

        let mut file = Self {
            data,
            meta: meta_bytes,
            footer,
            levels: Vec::new(),
            fields: Vec::new(),
            finest_domain: IBox::default(),
            tree_depth: 0,
            path: None,
            block_tables: None,
            block_starts: Vec::new(),
            tight: false,
            parts: None,
        };
        file.check_sections()?;
        file.levels = file.read_levels()?;
        file.finest_domain = file.levels.last().map(|l| l.domain).unwrap_or_default();
        file.fields = file.read_fields()?;
        file.check_bricks()?;
        file.check_block_tables()?;
        file.check_tight_ranges()?;
        file.check_part_table()?;
        file.tree_depth = file.check_tree()?;
        file.check_leaves()?;
        Ok(file)
    }

    /// Names the file: errors from reading its bricks then name it (see [`FormatError::in_file`]).
    pub fn with_path(mut self, path: impl Into<PathBuf>) -> Self {
        self.path = Some(path.into());
        self
    }

    /// The file's name, when given with [`Self::with_path`].
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// Wraps `e` with the file's name, when it has one.
    fn named(&self, e: FormatError) -> FormatError {
        match &self.path {
            Some(p) => e.in_file(p),
            None => e,
        }
    }

    /// The underlying bytes.
    pub fn bytes(&self) -> &[u8] {
        self.data.as_ref()
    }

    /// The storage the file was opened from (a memory map, for instance).
    pub fn data(&self) -> &D {
        &self.data
    }

    /// The footer as stored.
    pub fn footer(&self) -> &Footer {
        &self.footer
    }

    /// The simulation time the data was written at, when the file records it.
    pub fn simulation_time(&self) -> Option<f64> {
        let s = &self.footer.simulation;
        let t = s.time.get();
        (s.flags.get() & crate::raw::STAMP_HAS_TIME != 0 && t.is_finite()).then_some(t)
    }

    /// The simulation step (cycle) the data was written at, when the file records it.
    pub fn simulation_step(&self) -> Option<i64> {
        let s = &self.footer.simulation;
        (s.flags.get() & crate::raw::STAMP_HAS_STEP != 0).then(|| s.step.get())
    }

    /// Levels, coarsest first.
    pub fn levels(&self) -> &[LevelInfo] {
        &self.levels
    }

    /// Fields, in file order.
    pub fn fields(&self) -> &[FieldInfo] {
        &self.fields
    }

    /// The index of the field called `name`.
    pub fn field_index(&self, name: &str) -> Option<usize> {
        self.fields.iter().position(|f| f.name == name)
    }

    /// Number of bricks.
    pub fn num_bricks(&self) -> usize {
        self.footer.num_bricks.get() as usize
    }

    /// Brick `i`. Panics if `i >= num_bricks()`.
    pub fn brick(&self, i: usize) -> BrickInfo {
        let r = &self.brick_records()[i];
        BrickInfo {
            level: r.level.get(),
            cells: IBox::new(r.lo.map(|v| v.get()), r.hi.map(|v| v.get())),
        }
    }

    /// Every brick, in order: [`Self::brick`] of each, in one pass over the table.
    pub fn bricks(&self) -> impl ExactSizeIterator<Item = BrickInfo> + '_ {
        self.brick_records().iter().map(|r| BrickInfo {
            level: r.level.get(),
            cells: IBox::new(r.lo.map(|v| v.get()), r.hi.map(|v| v.get())),
        })
    }

    /// Where field `field`'s values of brick `brick` are stored, and their range.
    pub fn brick_data(&self, field: usize, brick: usize) -> BrickLocation {
        location(&self.field_brick_records(field)[brick])
    }

    /// Where field `field`'s values of every brick are stored, in brick order:
    /// [`Self::brick_data`] of each, in one pass over the table.
    pub fn brick_locations(
        &self,
        field: usize,
    ) -> impl ExactSizeIterator<Item = BrickLocation> + '_ {
        self.field_brick_records(field).iter().map(location)
    }

    /// The values stored at `at` (a location of this file), borrowed in place: `None` unless
    /// they are stored raw, the host is little-endian and they are 4-byte aligned.
    pub fn raw_values(&self, at: &BrickLocation) -> Option<&[f32]> {
        if at.encoding != Encoding::Raw || !cfg!(target_endian = "little") {
            return None;
        }
        let start = at.offset as usize;
        // In range: brick locations are checked at open to lie in their field's data region.
        <[f32]>::ref_from_bytes(&self.bytes()[start..start + at.len as usize]).ok()
    }

    /// The value range of field `field` in brick `brick`.
    pub fn brick_range(&self, field: usize, brick: usize) -> (f32, f32) {
        let d = self.brick_data(field, brick);
        (d.min, d.max)
    }

    /// The stored bytes of one brick of one field (compressed or raw).
    pub fn brick_bytes(&self, field: usize, brick: usize) -> &[u8] {
        let d = self.brick_data(field, brick);
        let start = d.offset as usize;
        &self.bytes()[start..start + d.len as usize]
    }

    /// The values of one brick of one field, x fastest: borrowed from the bytes when stored raw
    /// on a little-endian host and 4-byte aligned, decoded otherwise.
    pub fn brick_values(&self, field: usize, brick: usize) -> Result<Cow<'_, [f32]>> {
        if let Some(values) = self.raw_values(&self.brick_data(field, brick)) {
            return Ok(Cow::Borrowed(values));
        }
        let mut out = Vec::new();
        self.brick_values_into(field, brick, &mut out)?;
        Ok(Cow::Owned(out))
    }

    /// Decodes one brick of one field into `out` (replacing its contents), after checking its
    /// stored bytes against their checksum: a brick decoded is read whole anyway, and the check
    /// costs a few per cent of a zstd decode, so damaged data gives an error naming the brick
    /// instead of wrong values. (Raw bricks read in place, [`Self::raw_values`], are not
    /// checked: that would read every page of every brick the renderer touches; `verify` does.)
    pub fn brick_values_into(&self, field: usize, brick: usize, out: &mut Vec<f32>) -> Result<()> {
        let d = self.brick_data(field, brick);
        let cells = self.brick(brick).cells.num_cells().unwrap_or(0) as usize;
        let bytes = self.brick_bytes(field, brick);
        let crc = crc32fast::hash(bytes);
        if crc != d.crc {
            return Err(self.named(FormatError::Checksum {
                what: format!("field '{}', brick {brick}", self.fields[field].name),
                stored: d.crc,
                computed: crc,
            }));
        }
        decode_into(d.encoding.raw(), bytes, cells, out).map_err(|e| {
            self.named(match e {
                FormatError::Corrupt(m) => FormatError::Corrupt(format!(
                    "field '{}', brick {brick}: {m}",
                    self.fields[field].name
                )),
                e => e,
            })
        })
    }

    /// The kd-tree, ready to walk.
    pub fn tree(&self) -> TreeView<'_> {
        TreeView {
            nodes: self.slice(&self.footer.nodes),
            leaves: self.slice(&self.footer.leaves),
            domain: IBox::new([0; 3], self.finest_domain.extent()),
        }
    }

    /// Depth of the deepest kd-tree leaf (the root is depth 0).
    pub fn tree_depth(&self) -> u32 {
        self.tree_depth
    }

    /// Number of kd-tree leaves.
    pub fn num_leaves(&self) -> usize {
        self.footer.num_leaves.get() as usize
    }

    /// Leaf `leaf`: its box and its bricks. Panics if out of range.
    pub fn leaf(&self, leaf: u32) -> LeafInfo<'_> {
        let l: &KdLeaf = &self.slice::<KdLeaf>(&self.footer.leaves)[leaf as usize];
        LeafInfo::of(l, self.slice(&self.footer.brick_list))
    }

    /// The bricks of each of `leaves`, in that order: [`Self::leaf`]'s bricks of each, with the
    /// tables looked up once.
    pub fn bricks_of_leaves<'s>(
        &'s self,
        leaves: &'s [u32],
    ) -> impl Iterator<Item = &'s [U32]> + 's {
        let table = self.slice::<KdLeaf>(&self.footer.leaves);
        let list: &[U32] = self.slice(&self.footer.brick_list);
        leaves
            .iter()
            .map(move |&l| LeafInfo::of(&table[l as usize], list).bricks)
    }

    /// Every kd-tree leaf, in order: [`Self::leaf`] of each, in one pass over the table.
    pub fn leaves(&self) -> impl ExactSizeIterator<Item = LeafInfo<'_>> + '_ {
        let list: &[U32] = self.slice(&self.footer.brick_list);
        self.slice::<KdLeaf>(&self.footer.leaves)
            .iter()
            .map(move |l| LeafInfo::of(l, list))
    }

    /// The conservative value range of field `field` inside leaf `leaf` (`(+inf, -inf)` for a
    /// leaf without bricks).
    pub fn leaf_range(&self, field: usize, leaf: u32) -> (f32, f32) {
        let r: &LeafRange =
            &self.slice::<LeafRange>(&self.fields_raw()[field].leaf_ranges)[leaf as usize];
        (r.min.get(), r.max.get())
    }

    /// True when the file stores tight leaf ranges (layout version 3, written with them).
    pub fn has_tight_ranges(&self) -> bool {
        self.tight
    }

    /// The stored tight range of `leaf` for field `field`: every value the octant
    /// reconstruction gives on the voxels the leaf owns lies inside it (`(+inf, -inf)` for a
    /// leaf without data); `None` when the file stores none ([`Self::has_tight_ranges`]).
    pub fn tight_range(&self, field: usize, leaf: u32) -> Option<(f32, f32)> {
        if !self.tight {
            return None;
        }
        let i = field * self.num_leaves() + leaf as usize;
        let r: &LeafRange = &self.slice::<LeafRange>(&self.footer.tight_ranges)[i];
        Some((r.min.get(), r.max.get()))
    }

    /// [`Self::tight_range`] of every leaf for field `field`, in leaf order, in one pass over
    /// the table; `None` when the file stores none.
    pub fn tight_ranges(
        &self,
        field: usize,
    ) -> Option<impl ExactSizeIterator<Item = (f32, f32)> + '_> {
        if !self.tight {
            return None;
        }
        let n = self.num_leaves();
        let all: &[LeafRange] = self.slice(&self.footer.tight_ranges);
        Some(
            all[field * n..(field + 1) * n]
                .iter()
                .map(|r| (r.min.get(), r.max.get())),
        )
    }

    /// [`Self::tight_range`] of every leaf for field `field`, in leaf order, as the stored table
    /// itself (no copy); `None` when the file stores none.
    pub fn tight_range_table(&self, field: usize) -> Option<&[LeafRange]> {
        if !self.tight {
            return None;
        }
        let n = self.num_leaves();
        let all: &[LeafRange] = self.slice(&self.footer.tight_ranges);
        Some(&all[field * n..(field + 1) * n])
    }

    /// Cells per axis of the parts whose bounds the file stores (layout version 4, written with
    /// them); `None` when it stores none.
    pub fn part_cells(&self) -> Option<u32> {
        self.parts.map(|p| p.part_cells.get())
    }

    /// The stored bounds of the parts of `leaf` for field `field`, in part order (see
    /// [`PartTable`]; empty for a leaf with no parts); `None` when the file stores none. Every
    /// entry is checked at open (no NaN, `min <= max` or the empty range).
    pub fn part_ranges(&self, field: usize, leaf: u32) -> Option<&[LeafRange]> {
        let p = self.parts.as_ref()?;
        let starts: &[U64] = self.slice(&p.starts);
        // In bounds and ordered: checked at open.
        let (start, end) = (starts[leaf as usize].get(), starts[leaf as usize + 1].get());
        let total = starts[self.num_leaves()].get();
        let all: &[LeafRange] = self.slice(&p.ranges);
        let first = field as u64 * total;
        Some(&all[(first + start) as usize..(first + end) as usize])
    }

    /// Per leaf, in order, the number of parts whose bounds the file stores (the length of
    /// [`Self::part_ranges`] for every field), in one pass over the table; `None` when it
    /// stores none.
    pub fn part_counts(&self) -> Option<impl ExactSizeIterator<Item = u64> + '_> {
        let p = self.parts.as_ref()?;
        let starts: &[U64] = self.slice(&p.starts);
        // Never negative: the starts are checked at open never to decrease.
        Some(starts.windows(2).map(|w| w[1].get() - w[0].get()))
    }

    /// The finest level's index domain (absolute finest-level cell indices).
    pub fn finest_domain(&self) -> IBox {
        self.finest_domain
    }

    /// Raw sections, for `info`: (name, bytes).
    pub fn section_sizes(&self) -> Vec<(String, u64)> {
        let f = &self.footer;
        let mut out = vec![("header".to_string(), size_of::<Header>() as u64)];
        for (field, raw) in self.fields.iter().zip(self.fields_raw()) {
            out.push((format!("data '{}'", field.name), raw.data.len.get()));
        }
        for (name, s) in [
            ("levels", &f.levels),
            ("fields", &f.fields),
            ("bricks", &f.bricks),
            ("kd nodes", &f.nodes),
            ("kd leaves", &f.leaves),
            ("brick list", &f.brick_list),
            ("names", &f.strings),
        ] {
            out.push((name.to_string(), s.len.get()));
        }
        let per_field: u64 = self
            .fields_raw()
            .iter()
            .map(|r| r.brick_data.len.get() + r.leaf_ranges.len.get())
            .sum();
        out.push(("per-field brick and leaf tables".to_string(), per_field));
        if self.block_tables.is_some() {
            let tables: &[Section] = self.slice(&f.block_tables);
            let bytes: u64 = tables.iter().map(|s| s.len.get()).sum();
            out.push(("block range tables".to_string(), bytes));
        }
        if self.tight {
            out.push(("tight leaf ranges".to_string(), f.tight_ranges.len.get()));
        }
        if let Some(p) = &self.parts {
            out.push((
                "part bounds".to_string(),
                size_of::<PartTable>() as u64 + p.starts.len.get() + p.ranges.len.get(),
            ));
        }
        out.push(("footer".to_string(), size_of::<Footer>() as u64));
        out
    }

    /// Cells per axis of the blocks of the file's block range tables; `None` for a file of
    /// layout version 1, which has none.
    pub fn block_cells(&self) -> Option<u32> {
        self.block_tables.as_ref().map(|(b, _)| *b)
    }

    /// The stored block range table of brick `brick` for field `field` (blocks of
    /// [`Self::block_cells`] cells, x fastest; see [`crate::blocks`]), read in place; `None` for
    /// a file of layout version 1. The entries' values are not checked at open (`verify` checks
    /// them against the data).
    pub fn block_ranges(&self, field: usize, brick: usize) -> Option<&[BlockRange]> {
        let (_, offsets) = self.block_tables.as_ref()?;
        let start = self.block_starts[brick];
        let end = self.block_starts[brick + 1];
        let size = size_of::<BlockRange>() as u64;
        // In bounds: every table's length was checked at open against the total.
        let bytes = &self.data.as_ref()[(offsets[field] + start * size) as usize..]
            [..((end - start) * size) as usize];
        Some(<[BlockRange]>::ref_from_bytes(bytes).expect("block ranges are unaligned records"))
    }

    fn brick_records(&self) -> &[BrickRecord] {
        self.slice(&self.footer.bricks)
    }

    pub(crate) fn field_brick_records(&self, field: usize) -> &[BrickData] {
        self.slice(&self.fields_raw()[field].brick_data)
    }

    pub(crate) fn fields_raw(&self) -> &[FieldRecord] {
        self.slice(&self.footer.fields)
    }

    /// A typed view of a metadata section checked at open, read from the private copy.
    fn slice<T: FromBytes + KnownLayout + Immutable>(&self, s: &Section) -> &[T] {
        let start = (s.offset.get() - self.footer.metadata.offset.get()) as usize;
        let bytes = &self.meta[start..start + s.len.get() as usize];
        <[T]>::ref_from_bytes(bytes).expect("section sizes are checked at open")
    }

    fn check_sections(&self) -> Result<()> {
        let f = &self.footer;
        let nl = f.num_levels.get() as usize;
        if nl == 0 || nl > MAX_LEVELS {
            return Err(FormatError::Corrupt(format!(
                "{nl} levels (1 to {MAX_LEVELS} allowed)"
            )));
        }
        if f.num_fields.get() == 0 {
            return Err(FormatError::Corrupt("no fields".into()));
        }
        let meta = &f.metadata;
        for (name, s, count, size) in [
            (
                "levels",
                &f.levels,
                f.num_levels.get(),
                size_of::<LevelRecord>(),
            ),
            (
                "fields",
                &f.fields,
                f.num_fields.get(),
                size_of::<FieldRecord>(),
            ),
            (
                "bricks",
                &f.bricks,
                f.num_bricks.get(),
                size_of::<BrickRecord>(),
            ),
            (
                "kd nodes",
                &f.nodes,
                f.num_nodes.get(),
                size_of::<raw::KdNode>(),
            ),
            (
                "kd leaves",
                &f.leaves,
                f.num_leaves.get(),
                size_of::<KdLeaf>(),
            ),
            ("brick list", &f.brick_list, f.brick_list_len.get(), 4),
        ] {
            check_table(name, s, meta, count, size)?;
        }
        check_within("names", &f.strings, meta)?;
        if f.num_nodes.get() == 0 || f.num_leaves.get() == 0 {
            return Err(FormatError::Corrupt("the kd-tree is empty".into()));
        }
        Ok(())
    }

    fn read_levels(&self) -> Result<Vec<LevelInfo>> {
        let recs: &[LevelRecord] = self.slice(&self.footer.levels);
        let nl = recs.len();
        let mut levels: Vec<LevelInfo> = Vec::with_capacity(nl);
        for (l, r) in recs.iter().enumerate() {
            let bad = |m: String| Err(FormatError::Corrupt(format!("level {l}: {m}")));
            let level = LevelInfo {
                cell_size: r.cell_size.map(|v| v.get()),
                origin: r.origin.map(|v| v.get()),
                ratio_to_next: r.ratio_to_next.map(|v| v.get()),
                domain: IBox::new(r.domain_lo.map(|v| v.get()), r.domain_hi.map(|v| v.get())),
                finest_scale: [1; 3],
            };
            if level.cell_size.iter().any(|&d| !(d.is_finite() && d > 0.0))
                || level.origin.iter().any(|o| !o.is_finite())
            {
                return bad(format!(
                    "cell size {:?} / origin {:?} invalid",
                    level.cell_size, level.origin
                ));
            }
            if level.domain.is_empty() {
                return bad(format!("empty domain {:?}", level.domain));
            }
            let last = l + 1 == nl;
            if level.ratio_to_next.iter().any(|&q| {
                if last {
                    q != 1
                } else {
                    !(2..=1 << 16).contains(&q)
                }
            }) {
                return bad(format!("refinement ratio {:?}", level.ratio_to_next));
            }
            if let Some(prev) = levels.last() {
                let r = prev.ratio_to_next.map(i64::from);
                if prev.domain.refine(r) != Some(level.domain) {
                    return bad(format!(
                        "domain {:?} is not the previous domain refined by {r:?}",
                        level.domain
                    ));
                }
            }
            levels.push(level);
        }
        let ext = levels[nl - 1].domain.extent();
        if ext.iter().any(|&e| e > MAX_FINEST_EXTENT) {
            return Err(FormatError::Corrupt(format!(
                "finest domain extent {ext:?} exceeds {MAX_FINEST_EXTENT}"
            )));
        }
        for l in (0..nl.saturating_sub(1)).rev() {
            let r = levels[l].ratio_to_next;
            let s = levels[l + 1].finest_scale;
            // Cannot overflow: the product is at most the finest extent, checked above.
            levels[l].finest_scale = [0, 1, 2].map(|a| s[a] * i64::from(r[a]));
        }
        Ok(levels)
    }

    fn read_fields(&self) -> Result<Vec<FieldInfo>> {
        let f = &self.footer;
        let strings: &[u8] = self.slice(&f.strings);
        let data_limit = f.metadata.offset.get();
        let nb = f.num_bricks.get();
        let nleaves = f.num_leaves.get();
        let mut out: Vec<FieldInfo> = Vec::new();
        let mut regions: Vec<(u64, u64)> = Vec::new();
        for (i, r) in self.fields_raw().iter().enumerate() {
            let bad = |m: String| Err(FormatError::Corrupt(format!("field {i}: {m}")));
            let (no, nlen) = (r.name_offset.get() as usize, r.name_len.get() as usize);
            let Some(name_bytes) = no.checked_add(nlen).and_then(|end| strings.get(no..end)) else {
                return bad("name lies outside the names section".into());
            };
            let Ok(name) = std::str::from_utf8(name_bytes) else {
                return bad("name is not UTF-8".into());
            };
            let data_end = end_of(&r.data, "field data")?;
            if r.data.offset.get() < size_of::<Header>() as u64 || data_end > data_limit {
                return bad(format!(
                    "data region {}..{data_end} outside the data area",
                    r.data.offset.get()
                ));
            }
            check_table(
                "per-field brick table",
                &r.brick_data,
                &f.metadata,
                nb,
                size_of::<BrickData>(),
            )?;
            check_table(
                "per-field leaf ranges",
                &r.leaf_ranges,
                &f.metadata,
                nleaves,
                size_of::<LeafRange>(),
            )?;
            let (min, max) = (r.min.get(), r.max.get());
            if !(min <= max) {
                return bad(format!("range {min}..{max}"));
            }
            regions.push((r.data.offset.get(), data_end));
            out.push(FieldInfo {
                name: name.to_string(),
                min,
                max,
                data: (r.data.offset.get(), r.data.len.get()),
                compressed: false,
            });
        }
        regions.sort_unstable();
        if regions.windows(2).any(|w| w[0].1 > w[1].0) {
            return Err(FormatError::Corrupt(
                "two fields' data regions overlap".into(),
            ));
        }
        Ok(out)
    }

    fn check_bricks(&mut self) -> Result<()> {
        let nl = self.levels.len();
        for (i, b) in self.brick_records().iter().enumerate() {
            let level = b.level.get() as usize;
            let cells = IBox::new(b.lo.map(|v| v.get()), b.hi.map(|v| v.get()));
            let bad = |m: String| Err(FormatError::Corrupt(format!("brick {i}: {m}")));
            if level >= nl {
                return bad(format!("level {level} but the file has {nl} levels"));
            }
            if cells.is_empty() || !self.levels[level].domain.contains_box(&cells) {
                return bad(format!(
                    "cells {cells:?} empty or outside level {level}'s domain"
                ));
            }
            if cells.extent().iter().any(|&e| e > MAX_BRICK_EXTENT)
                || cells.num_cells().is_none_or(|n| n > MAX_BRICK_CELLS)
            {
                return bad(format!("cells {cells:?} exceed the brick size limits"));
            }
        }
        let mut compressed_fields = vec![false; self.fields.len()];
        for field in 0..self.fields.len() {
            let (start, len) = self.fields[field].data;
            // Cannot overflow: the region's end was checked in `read_fields`.
            let end = start + len;
            let mut compressed = false;
            let data = self.field_brick_records(field);
            for (i, (d, b)) in data.iter().zip(self.bricks()).enumerate() {
                let cells = b.cells.num_cells().unwrap_or(0);
                let bad = |m: String| {
                    Err(FormatError::Corrupt(format!(
                        "field '{}', brick {i}: {m}",
                        self.fields[field].name
                    )))
                };
                let (off, n) = (d.offset.get(), d.len.get());
                if off < start || off.checked_add(n).is_none_or(|e| e > end) {
                    return bad(format!(
                        "data {off}+{n} outside the field's region {start}..{end}"
                    ));
                }
                match d.encoding.get() {
                    raw::ENCODING_RAW if n != cells * 4 => {
                        return bad(format!("raw length {n} for {cells} cells"))
                    }
                    raw::ENCODING_RAW => {}
                    raw::ENCODING_ZSTD_SHUFFLED => compressed = true,
                    e => return bad(format!("unknown encoding {e}")),
                }
                let (lo, hi) = (d.min.get(), d.max.get());
                if !(lo <= hi) || !lo.is_finite() || !hi.is_finite() {
                    return bad(format!("value range {lo}..{hi}"));
                }
            }
            compressed_fields[field] = compressed;
        }
        for (f, compressed) in self.fields.iter_mut().zip(compressed_fields) {
            f.compressed = compressed;
        }
        Ok(())
    }

    /// Layout version 2: the block size, and each field's block range table lies in the data area
    /// with exactly the bricks' block count of entries, overlapping no field's data region nor
    /// another table.
    fn check_block_tables(&mut self) -> Result<()> {
        let f = self.footer;
        if f.layout_version.get() < 2 {
            return Ok(());
        }
        let block = f.block_cells.get();
        if !(1..=MAX_BRICK_EXTENT as u32).contains(&block) {
            return Err(FormatError::Corrupt(format!(
                "block range tables of {block} cells per axis"
            )));
        }
        check_table(
            "block tables",
            &f.block_tables,
            &f.metadata,
            f.num_fields.get(),
            size_of::<Section>(),
        )?;
        let mut starts = Vec::with_capacity(self.num_bricks() + 1);
        let mut total = 0u64;
        for b in self.bricks() {
            starts.push(total);
            // Cannot overflow: bricks hold at most MAX_BRICK_CELLS cells, checked above.
            total += block_count(&b.cells, i64::from(block)).unwrap_or(0);
        }
        starts.push(total);
        let want = total
            .checked_mul(size_of::<BlockRange>() as u64)
            .ok_or_else(|| FormatError::Corrupt("block tables overflow".into()))?;
        let sections: Vec<Section> = self.slice::<Section>(&f.block_tables).to_vec();
        let mut regions: Vec<(u64, u64)> = self
            .fields
            .iter()
            .map(|fi| (fi.data.0, fi.data.0 + fi.data.1))
            .collect();
        let mut offsets = Vec::with_capacity(sections.len());
        for (i, s) in sections.iter().enumerate() {
            let end = end_of(s, "block table")?;
            if s.offset.get() < size_of::<Header>() as u64 || end > f.metadata.offset.get() {
                return Err(FormatError::Corrupt(format!(
                    "field {i}: block table {}..{end} outside the data area",
                    s.offset.get()
                )));
            }
            if s.len.get() != want {
                return Err(FormatError::Corrupt(format!(
                    "field {i}: block table holds {} bytes, {total} blocks need {want}",
                    s.len.get()
                )));
            }
            regions.push((s.offset.get(), end));
            offsets.push(s.offset.get());
        }
        regions.retain(|r| r.0 < r.1);
        regions.sort_unstable();
        if regions.windows(2).any(|w| w[0].1 > w[1].0) {
            return Err(FormatError::Corrupt(
                "a block table overlaps brick data or another block table".into(),
            ));
        }
        self.block_starts = starts;
        self.block_tables = Some((block, offsets));
        Ok(())
    }

    /// Layout version 3: the tight leaf ranges, when stored, lie in the metadata with one entry
    /// per leaf and field, none of them NaN or reversed (but for the empty range).
    fn check_tight_ranges(&mut self) -> Result<()> {
        let f = self.footer;
        let s = f.tight_ranges;
        if f.layout_version.get() < 3 || (s.offset.get() == 0 && s.len.get() == 0) {
            return Ok(());
        }
        let entries = f.num_leaves.get().checked_mul(f.num_fields.get());
        let Some(entries) = entries else {
            return Err(FormatError::Corrupt("tight leaf ranges overflow".into()));
        };
        check_table(
            "tight leaf ranges",
            &s,
            &f.metadata,
            entries,
            size_of::<LeafRange>(),
        )?;
        let nl = self.num_leaves();
        for (i, r) in self.slice::<LeafRange>(&s).iter().enumerate() {
            let (lo, hi) = (r.min.get(), r.max.get());
            if !crate::value_range::valid_tight_range(lo, hi) {
                return Err(FormatError::Corrupt(format!(
                    "field {}, leaf {}: tight range {lo}..{hi}",
                    i / nl.max(1),
                    i % nl.max(1)
                )));
            }
        }
        self.tight = true;
        Ok(())
    }

    /// Layout version 4: the part table, when stored, lies in the metadata; its leaf starts
    /// (one per leaf and one past the last) begin at zero and never decrease; its ranges hold
    /// one entry per part and field, none of them NaN or reversed (but for the empty range).
    fn check_part_table(&mut self) -> Result<()> {
        let f = self.footer;
        let at = f.part_table.get();
        if f.layout_version.get() < 4 || at == 0 {
            return Ok(());
        }
        let bad = |m: String| Err(FormatError::Corrupt(m));
        let record = Section {
            offset: at.into(),
            len: (size_of::<PartTable>() as u64).into(),
        };
        check_within("part table", &record, &f.metadata)?;
        let table = *self
            .slice::<PartTable>(&record)
            .first()
            .expect("one record, checked to lie in the metadata");
        if table.part_cells.get() == 0 {
            return bad("parts of 0 cells".into());
        }
        let leaves = f
            .num_leaves
            .get()
            .checked_add(1)
            .ok_or_else(|| FormatError::Corrupt("part starts overflow".into()))?;
        check_table(
            "part starts",
            &table.starts,
            &f.metadata,
            leaves,
            size_of::<U64>(),
        )?;
        let starts: &[U64] = self.slice(&table.starts);
        if starts[0].get() != 0 {
            return bad(format!(
                "the first leaf's parts start at {}",
                starts[0].get()
            ));
        }
        if let Some(l) = starts.windows(2).position(|w| w[1].get() < w[0].get()) {
            return bad(format!("leaf {l}: its parts end before they start"));
        }
        let total = starts[starts.len() - 1].get();
        let want = total
            .checked_mul(u64::from(f.num_fields.get()))
            .and_then(|n| n.checked_mul(size_of::<LeafRange>() as u64))
            .ok_or_else(|| FormatError::Corrupt("part bounds overflow".into()))?;
        check_within("part bounds", &table.ranges, &f.metadata)?;
        if table.ranges.len.get() != want {
            return bad(format!(
                "part bounds section holds {} bytes, {total} parts x {} fields need {want}",
                table.ranges.len.get(),
                f.num_fields.get()
            ));
        }
        for (i, r) in self.slice::<LeafRange>(&table.ranges).iter().enumerate() {
            let (lo, hi) = (r.min.get(), r.max.get());
            if !crate::value_range::valid_tight_range(lo, hi) {
                let total = total.max(1) as usize;
                return bad(format!(
                    "field {}, part {}: bound {lo}..{hi}",
                    i / total,
                    i % total
                ));
            }
        }
        self.parts = Some(table);
        Ok(())
    }

    /// Walks the tree from the root, each node once: returns the depth of the deepest leaf.
    ///
    /// Checks that the nodes are stored depth first, a split's first child right after it and
    /// its second child right after the first child's subtree, so that the walk meets node `i`
    /// `i`-th: then every node is reached exactly once (no cycle, no shared child, nothing
    /// unreachable). Checks too that every split plane lies strictly inside its node's region,
    /// and that every leaf is reached once with the region it stores. Leaf boxes then tile the
    /// domain, which is what point location and the renderer rely on. One pass over the node
    /// array, in order.
    fn check_tree(&self) -> Result<u32> {
        let tree = self.tree();
        let (nodes, leaves) = (tree.nodes, tree.leaves);
        let (n, nleaves) = (nodes.len(), leaves.len());
        let bad = |m: String| Err(FormatError::Corrupt(m));
        let mut leaf_seen = vec![false; nleaves];
        let mut depth_max = 0u32;
        // The second children still to walk, with their regions and depths.
        let mut pending: Vec<(usize, IBox, u32)> = Vec::new();
        let (mut i, mut region, mut depth) = (0usize, tree.domain, 0u32);
        // Node `i` is the `i`-th the walk meets: the nodes before it were each met once.
        for (at, node) in nodes.iter().enumerate() {
            if i != at {
                return bad(if i < at {
                    format!("kd node {i} is reached twice (not a tree)")
                } else if i == n {
                    format!("kd node {at} is not reachable from the root")
                } else {
                    format!("kd nodes are not stored depth first: node {i} stands where {at} is")
                });
            }
            match KdNode::decode(i, node) {
                KdNode::Leaf { leaf: a } => {
                    let Some(seen) = leaf_seen.get_mut(a as usize) else {
                        return bad(format!("kd node {i} names leaf {a} of {nleaves}"));
                    };
                    if std::mem::replace(seen, true) {
                        return bad(format!("kd leaf {a} is reached twice"));
                    }
                    let stored = tree.leaf_box(a);
                    if stored != region {
                        return bad(format!(
                            "kd leaf {a} stores {stored:?} but the tree gives it {region:?}"
                        ));
                    }
                    depth_max = depth_max.max(depth);
                    // `n` once the walk is over: every node it names is below `n`.
                    match pending.pop() {
                        Some(next) => (i, region, depth) = next,
                        None => i = n,
                    }
                }
                KdNode::Split {
                    axis, pos, high, ..
                } => {
                    if pos <= region.lo[axis] || pos >= region.hi[axis] {
                        return bad(format!(
                            "kd node {i} splits {region:?} at {pos} on axis {axis}, not inside it"
                        ));
                    }
                    if high <= i + 1 || high >= n {
                        return bad(format!(
                            "kd node {i} has children {} and {high} of {n}",
                            i + 1
                        ));
                    }
                    let mut upper = region;
                    upper.lo[axis] = pos;
                    pending.push((high, upper, depth + 1));
                    region.hi[axis] = pos;
                    (i, depth) = (i + 1, depth + 1);
                }
            }
        }
        if i != n {
            // A second child still to walk, and every node already met once.
            return bad(format!("kd node {i} is reached twice (not a tree)"));
        }
        if let Some(l) = leaf_seen.iter().position(|s| !s) {
            return bad(format!("kd leaf {l} is not reachable from the root"));
        }
        Ok(depth_max)
    }

    /// Checks each leaf's brick list and value ranges: the list lies inside the brick-list
    /// table, names existing bricks, and its first brick (the one the renderer reads the leaf's
    /// values from) covers the leaf.
    fn check_leaves(&self) -> Result<()> {
        let leaves: &[KdLeaf] = self.slice(&self.footer.leaves);
        let list: &[U32] = self.slice(&self.footer.brick_list);
        let nb = self.num_bricks() as u32;
        if let Some(bad) = list.iter().position(|b| b.get() >= nb) {
            return Err(FormatError::Corrupt(format!(
                "brick list entry {bad} names a brick past {nb}"
            )));
        }
        let origin = self.finest_domain.lo;
        let records = self.brick_records();
        let scales: Vec<[i64; 3]> = self.levels.iter().map(|l| l.finest_scale).collect();
        for (i, l) in leaves.iter().enumerate() {
            let (start, count) = (l.brick_start.get() as usize, l.brick_count.get() as usize);
            let Some(bricks) = start
                .checked_add(count)
                .and_then(|end| list.get(start..end))
            else {
                return Err(FormatError::Corrupt(format!(
                    "kd leaf {i}: brick list {start}+{count} past {}",
                    list.len()
                )));
            };
            let Some(first) = bricks.first() else {
                continue;
            };
            // In range: list entries and brick levels are checked above.
            let b = &records[first.get() as usize];
            let s = scales[b.level.get() as usize];
            // Cannot overflow: brick boxes lie inside their level's domain, which refines into
            // the finest domain.
            let covers = (0..3).all(|a| {
                b.lo[a].get() * s[a] - origin[a] <= i64::from(l.lo[a].get())
                    && i64::from(l.hi[a].get()) <= b.hi[a].get() * s[a] - origin[a]
            });
            if !covers {
                return Err(FormatError::Corrupt(format!(
                    "kd leaf {i}: its first brick {} does not cover it",
                    first.get()
                )));
            }
        }
        for (field, r) in self.fields_raw().iter().enumerate() {
            let ranges: &[LeafRange] = self.slice(&r.leaf_ranges);
            for (i, (range, leaf)) in ranges.iter().zip(leaves).enumerate() {
                let (lo, hi) = (range.min.get(), range.max.get());
                if leaf.brick_count.get() > 0 && !(lo <= hi) {
                    return Err(FormatError::Corrupt(format!(
                        "field '{}', kd leaf {i}: value range {lo}..{hi}",
                        self.fields[field].name
                    )));
                }
            }
        }
        Ok(())
    }

    /// Brick `b`'s cells in finest-level cells relative to `origin` (the finest domain's lower
    /// corner).
    pub fn brick_finest_bounds(&self, b: usize, origin: [i64; 3]) -> IBox {
        let info = self.brick(b);
        let s = self.levels()[info.level as usize].finest_scale;
        // Cannot overflow: brick boxes lie inside their level's domain (checked at open), which
        // refines into the finest domain.
        let f = info
            .cells
            .refine(s)
            .expect("brick boxes lie inside the checked domain");
        IBox::new(
            [0, 1, 2].map(|a| f.lo[a] - origin[a]),
            [0, 1, 2].map(|a| f.hi[a] - origin[a]),
        )
    }
}

/// A brick's stored location as read from its record.
fn location(d: &BrickData) -> BrickLocation {
    BrickLocation {
        offset: d.offset.get(),
        len: d.len.get(),
        encoding: Encoding::from_raw(d.encoding.get())
            .expect("encodings are checked at open and the tables are a private copy"),
        min: d.min.get(),
        max: d.max.get(),
        crc: d.crc.get(),
    }
}

fn check_version(got: u32) -> Result<()> {
    if !(raw::OLDEST_LAYOUT_VERSION..=raw::LAYOUT_VERSION).contains(&got) {
        return Err(FormatError::Version {
            expected: raw::LAYOUT_VERSION,
            got,
        });
    }
    Ok(())
}

fn end_of(s: &Section, what: &str) -> Result<u64> {
    s.offset
        .get()
        .checked_add(s.len.get())
        .ok_or_else(|| FormatError::Corrupt(format!("{what} section offset overflows")))
}

fn check_size(what: &str, stored: u32, size: usize) -> Result<()> {
    if stored as usize != size {
        return Err(FormatError::Corrupt(format!(
            "the {what} says it is {stored} bytes, this layout's {what} is {size}"
        )));
    }
    Ok(())
}

fn check_within(name: &str, s: &Section, meta: &Section) -> Result<()> {
    let end = end_of(s, name)?;
    if s.offset.get() < meta.offset.get() || end > meta.offset.get() + meta.len.get() {
        return Err(FormatError::Corrupt(format!(
            "{name} section {}..{end} lies outside the metadata",
            s.offset.get()
        )));
    }
    Ok(())
}

fn check_table(name: &str, s: &Section, meta: &Section, count: u32, size: usize) -> Result<()> {
    check_within(name, s, meta)?;
    let want = u64::from(count) * size as u64;
    if s.len.get() != want {
        return Err(FormatError::Corrupt(format!(
            "{name} section holds {} bytes, {count} entries need {want}",
            s.len.get()
        )));
    }
    Ok(())
}

/// Recomputes the metadata and footer checksums of the file in `bytes` after its metadata or
/// footer was rewritten (by tests and tools that damage files on purpose, so that structural
/// checks rather than checksums must catch the damage). Returns false, changing nothing, when
/// the footer does not locate a metadata region inside `bytes`.
pub fn recompute_checksums(bytes: &mut [u8]) -> bool {
    let Some(at) = bytes.len().checked_sub(size_of::<Footer>()) else {
        return false;
    };
    let Ok(mut footer) = Footer::read_from_bytes(&bytes[at..]) else {
        return false;
    };
    let (start, len) = (footer.metadata.offset.get(), footer.metadata.len.get());
    let Some(meta) = start
        .checked_add(len)
        .filter(|&end| end <= at as u64)
        .map(|end| &bytes[start as usize..end as usize])
    else {
        return false;
    };
    footer.metadata_crc = crc32fast::hash(meta).into();
    let fb = footer.as_bytes();
    footer.footer_crc = crc32fast::hash(&fb[..fb.len() - 4]).into();
    bytes[at..].copy_from_slice(footer.as_bytes());
    true
}

/// Raw-struct byte view, used by tests that corrupt files on purpose.
pub fn footer_bytes(footer: &Footer) -> &[u8] {
    footer.as_bytes()
}
