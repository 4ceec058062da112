//! The streaming writer: bricks go to disk as they arrive; tables, tree and footer go last.
//!
//! Memory held is O(bricks × fields) of small records, never brick data. Raw bricks are written
//! in place at offsets fixed when the writer is created (every brick's size is known from its
//! box), so each field's data sits in its own region whatever order the bricks arrive in.
//! Compressed bricks have unknown sizes: each field's frames are appended to a spill file in
//! the target directory and copied into the field's region at [`AmrkWriter::finish`]. Everything
//! goes to a temporary file beside the target, renamed into place only when complete; the
//! temporaries of writers that died first are removed (see [`crate::output`]).

use std::fs::File;
use std::io::{Seek, SeekFrom, Write};
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

use tempfile::NamedTempFile;
use zerocopy::IntoBytes;

use crate::blocks::{block_count, block_ranges};
use crate::compress::encode_zstd_shuffled;
use crate::error::{FormatError, Result};
use crate::geometry::IBox;
use crate::hierarchy::HierarchySpec;
use crate::kdtree::{self, KdTree, TreeBrick, TreeView};
use crate::output;
use crate::raw::{
    self, align_up, BlockRange, BrickData, BrickRecord, FieldRecord, Footer, Header, LeafRange,
    LevelRecord, Section,
};
use crate::tight_sink::TightSink;
use crate::value_range::finite_range;

/// How brick data is stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Compression {
    /// Raw little-endian f32.
    #[default]
    None,
    /// One zstd frame per brick over byte-shuffled f32, or raw where that is not smaller.
    Zstd {
        /// zstd level (1 to 22; 3 is a good default).
        level: i32,
    },
}

/// Computes the tight leaf ranges of a finished file, given its path (a complete file of the
/// current layout without them), and the bounds of the parts of its leaves when it can: hands
/// them to the sink, leaf after leaf, field after field ([`TightSink`]). `amr-render` has one;
/// this crate cannot compute them (it does not reconstruct).
pub type TightFn = fn(&Path, &mut TightSink<'_, '_>) -> std::result::Result<(), String>;

/// Options of [`AmrkWriter::create`].
#[derive(Clone, Copy, Debug, Default)]
pub struct WriterOptions {
    /// How brick data is stored.
    pub compression: Compression,
    /// Stores the tight leaf ranges (and part bounds) this computes over the finished file,
    /// before it is renamed into place; without it the file has none (readers then compute them
    /// as they go).
    pub tight: Option<TightFn>,
}

/// What a finished write produced.
#[derive(Clone, Debug)]
pub struct WriteSummary {
    /// Final file size in bytes.
    pub file_bytes: u64,
    /// Bytes of brick data (all fields).
    pub data_bytes: u64,
    /// Bytes brick data would take raw.
    pub raw_data_bytes: u64,
    /// Number of bricks.
    pub bricks: usize,
    /// Number of kd-tree leaves.
    pub leaves: usize,
    /// Number of kd-tree nodes.
    pub nodes: usize,
    /// Total cells.
    pub cells: u64,
}

/// Streams one `.amrk` file. See the module documentation.
pub struct AmrkWriter {
    target: PathBuf,
    file: NamedTempFile,
    spec: HierarchySpec,
    written: Vec<Vec<Option<BrickData>>>,
    spill: Option<Vec<Spill>>,
    compression: Compression,
    tight: Option<TightFn>,
    data_end: u64,
    tree: KdTree,
    simulation: raw::SimulationStamp,
    /// Per field: where its block range table starts in the file.
    block_tables: Vec<Section>,
    /// Per brick: its first entry in a field's block range table.
    block_starts: Vec<u64>,
}

struct Spill {
    file: NamedTempFile,
    len: u64,
}

impl AmrkWriter {
    /// Starts a file at `path` for the hierarchy `spec`; nothing appears at `path` until
    /// [`finish`](Self::finish) succeeds.
    pub fn create(path: &Path, spec: HierarchySpec, opts: WriterOptions) -> Result<Self> {
        spec.validate()?;
        let tree = build_tree(&spec)?;
        output::remove_stale_temporaries(path);
        let temp = |suffix: &str| output::temporary_for(path, suffix);
        let file = temp(".tmp")?;
        let header = Header {
            magic: raw::MAGIC,
            layout_version: raw::LAYOUT_VERSION.into(),
            header_size: (size_of::<Header>() as u32).into(),
            reserved: [0; 48],
        };
        file.as_file()
            .write_all_at(header.as_bytes(), 0)
            .map_err(|e| FormatError::io("writing the header", e))?;
        let nb = spec.bricks.len();
        let mut written = vec![vec![None; nb]; spec.fields.len()];
        let mut data_end = align_up(size_of::<Header>() as u64);
        // The block range tables come first, at places fixed now, so that each brick's entries
        // are written with its data (sizes follow from the brick boxes alone).
        let block = i64::from(raw::BLOCK_CELLS);
        let mut block_starts = Vec::with_capacity(nb);
        let mut blocks = 0u64;
        for b in &spec.bricks {
            block_starts.push(blocks);
            blocks += block_count(&b.cells, block).unwrap_or(0);
        }
        let table_len = blocks * size_of::<BlockRange>() as u64;
        let block_tables: Vec<Section> = (0..spec.fields.len())
            .map(|_| {
                let s = Section {
                    offset: data_end.into(),
                    len: table_len.into(),
                };
                data_end = align_up(data_end + table_len);
                s
            })
            .collect();
        let spill = match opts.compression {
            Compression::None => {
                // Fix every raw brick's place now: field after field, bricks in table order.
                for slots in written.iter_mut() {
                    for (slot, b) in slots.iter_mut().zip(&spec.bricks) {
                        let len = 4 * b.cells.num_cells().unwrap_or(0);
                        *slot = Some(BrickData {
                            offset: data_end.into(),
                            len: len.into(),
                            min: 0.0.into(),
                            max: 0.0.into(),
                            crc: 0.into(),
                            encoding: u32::MAX.into(),
                        });
                        data_end = align_up(data_end + len);
                    }
                }
                None
            }
            Compression::Zstd { .. } => {
                let spills = (0..spec.fields.len())
                    .map(|_| {
                        Ok(Spill {
                            file: temp(".spill")?,
                            len: 0,
                        })
                    })
                    .collect::<Result<Vec<_>>>()?;
                Some(spills)
            }
        };
        if spill.is_none() {
            // The raw data's end is known: a file system without that much room refuses it now
            // rather than when a write fails part way (compressed sizes are not known yet).
            output::check_room(path, data_end)?;
        }
        Ok(Self {
            target: path.to_path_buf(),
            file,
            spec,
            written,
            spill,
            compression: opts.compression,
            tight: opts.tight,
            data_end,
            tree,
            simulation: raw::SimulationStamp::default(),
            block_tables,
            block_starts,
        })
    }

    /// Records when in the simulation the data was written (`None`: not known), for frames to
    /// be labelled and ordered. A time must be finite.
    pub fn set_simulation(&mut self, time: Option<f64>, step: Option<i64>) -> Result<()> {
        let mut stamp = raw::SimulationStamp::default();
        if let Some(t) = time {
            if !t.is_finite() {
                return Err(FormatError::Usage(format!(
                    "simulation time {t} is not finite"
                )));
            }
            stamp.time = t.into();
            stamp.flags = (stamp.flags.get() | raw::STAMP_HAS_TIME).into();
        }
        if let Some(n) = step {
            stamp.step = n.into();
            stamp.flags = (stamp.flags.get() | raw::STAMP_HAS_STEP).into();
        }
        self.simulation = stamp;
        Ok(())
    }

    /// The hierarchy this writer was created with.
    pub fn spec(&self) -> &HierarchySpec {
        &self.spec
    }

    /// Writes one field's values of one brick, x fastest; each (brick, field) exactly once.
    pub fn write_brick(&mut self, brick: usize, field: usize, values: &[f32]) -> Result<()> {
        let spec = self.spec.bricks.get(brick).ok_or_else(|| {
            FormatError::Usage(format!(
                "brick {brick} does not exist ({} bricks)",
                self.spec.bricks.len()
            ))
        })?;
        let field_name = self
            .spec
            .fields
            .get(field)
            .ok_or_else(|| FormatError::Usage(format!("field {field} does not exist")))?;
        let cells = spec.cells.num_cells().unwrap_or(0) as usize;
        if values.len() != cells {
            return Err(FormatError::Usage(format!(
                "brick {brick} has {cells} cells but {} values were given",
                values.len()
            )));
        }
        let Some((min, max)) = finite_range(values) else {
            let value = values
                .iter()
                .find(|v| !v.is_finite())
                .copied()
                .unwrap_or(f32::NAN);
            return Err(FormatError::NonFinite {
                field: field_name.clone(),
                level: spec.level,
                brick,
                lo: spec.cells.lo,
                hi: spec.cells.hi,
                value: value as f64,
            });
        };
        let slot = &mut self.written[field][brick];
        let already = match slot {
            Some(d) => d.encoding.get() != u32::MAX,
            None => false,
        };
        if already {
            return Err(FormatError::Usage(format!(
                "brick {brick} of field '{field_name}' was written twice"
            )));
        }
        let table: Vec<BlockRange> = block_ranges(values, &spec.cells, i64::from(raw::BLOCK_CELLS))
            .into_iter()
            .map(|(lo, hi)| BlockRange {
                min: lo.into(),
                max: hi.into(),
            })
            .collect();
        let at = self.block_tables[field].offset.get()
            + self.block_starts[brick] * size_of::<BlockRange>() as u64;
        self.file
            .as_file()
            .write_all_at(table.as_bytes(), at)
            .map_err(|e| FormatError::io("writing a block range table", e))?;
        let raw_bytes = values.as_bytes();
        let record = match (&mut self.spill, self.compression) {
            (Some(spills), Compression::Zstd { level }) => {
                let s = &mut spills[field];
                let (bytes, encoding) = match encode_zstd_shuffled(values, level) {
                    Some(packed) => (std::borrow::Cow::Owned(packed), raw::ENCODING_ZSTD_SHUFFLED),
                    None => (le_bytes(values, raw_bytes), raw::ENCODING_RAW),
                };
                let offset = s.len;
                s.file
                    .as_file()
                    .write_all_at(&bytes, offset)
                    .map_err(|e| FormatError::io("writing a spill file", e))?;
                s.len = align_up(offset + bytes.len() as u64);
                BrickData {
                    offset: offset.into(),
                    len: (bytes.len() as u64).into(),
                    min: min.into(),
                    max: max.into(),
                    crc: crc32fast::hash(&bytes).into(),
                    encoding: encoding.into(),
                }
            }
            _ => {
                let mut d = slot.expect("raw slots are laid out at create");
                let bytes = le_bytes(values, raw_bytes);
                self.file
                    .as_file()
                    .write_all_at(&bytes, d.offset.get())
                    .map_err(|e| FormatError::io("writing brick data", e))?;
                d.min = min.into();
                d.max = max.into();
                d.crc = crc32fast::hash(&bytes).into();
                d.encoding = raw::ENCODING_RAW.into();
                d
            }
        };
        *slot = Some(record);
        Ok(())
    }

    /// Builds the kd-tree, writes every table and the footer, syncs, and renames the file into
    /// place. On error nothing is left at the target path.
    pub fn finish(mut self) -> Result<WriteSummary> {
        for (f, slots) in self.written.iter().enumerate() {
            if let Some(b) = slots
                .iter()
                .position(|d| d.is_none_or(|d| d.encoding.get() == u32::MAX))
            {
                return Err(FormatError::Usage(format!(
                    "brick {b} of field '{}' was never written",
                    self.spec.fields[f]
                )));
            }
        }
        let records: Vec<Vec<BrickData>> = std::mem::take(&mut self.written)
            .into_iter()
            .map(|s| s.into_iter().map(|d| d.expect("checked above")).collect())
            .collect();
        let (records, data_sections) = self.place_data(records)?;
        let raw_data_bytes = 4 * self.spec.total_cells() * self.spec.fields.len() as u64;
        let data_bytes: u64 = records.iter().flatten().map(|d| d.len.get()).sum();

        let nl = self.spec.levels.len();
        let domain = self.spec.levels[nl - 1].domain;
        let rel_domain = IBox::new([0; 3], domain.extent());
        let scales: Vec<[i64; 3]> = (0..nl).map(|l| self.spec.finest_scale(l)).collect();
        let tree = std::mem::take(&mut self.tree);
        let view = TreeView {
            nodes: &tree.nodes,
            leaves: &tree.leaves,
            domain: rel_domain,
        };
        let leaf_level: Vec<Option<u32>> = tree
            .leaves
            .iter()
            .map(|l| {
                (l.brick_count.get() > 0).then(|| {
                    self.spec.bricks[tree.brick_list[l.brick_start.get() as usize] as usize].level
                })
            })
            .collect();
        let first_brick = |leaf: u32| {
            tree.brick_list[tree.leaves[leaf as usize].brick_start.get() as usize] as usize
        };

        // Metadata, streamed to the file section after section (64-byte aligned) with a running
        // checksum, so that it is never held in memory whole.
        let mut meta = MetaWriter::new(self.file.as_file(), self.data_end);
        let levels: Vec<LevelRecord> = self
            .spec
            .levels
            .iter()
            .enumerate()
            .map(|(l, lev)| LevelRecord {
                cell_size: lev.cell_size.map(Into::into),
                origin: lev.origin.map(Into::into),
                domain_lo: lev.domain.lo.map(Into::into),
                domain_hi: lev.domain.hi.map(Into::into),
                ratio_to_next: if l + 1 < nl {
                    lev.ratio_to_next.map(Into::into)
                } else {
                    [1u32.into(); 3]
                },
                reserved: [0; 20],
            })
            .collect();
        let levels_sec = meta.push(levels.as_bytes())?;
        let bricks: Vec<BrickRecord> = self
            .spec
            .bricks
            .iter()
            .map(|b| BrickRecord {
                lo: b.cells.lo.map(Into::into),
                hi: b.cells.hi.map(Into::into),
                level: b.level.into(),
                reserved: 0.into(),
            })
            .collect();
        let bricks_sec = meta.push(bricks.as_bytes())?;
        drop(bricks);
        let nodes_sec = meta.push(tree.nodes.as_bytes())?;
        let leaves_sec = meta.push(tree.leaves.as_bytes())?;
        let list_sec = meta.push(tree.brick_list.as_bytes())?;
        let mut strings = Vec::new();
        let mut fields = Vec::new();
        for (f, name) in self.spec.fields.iter().enumerate() {
            let recs = &records[f];
            let ranges = kdtree::leaf_ranges(
                &view,
                &leaf_level,
                |leaf| {
                    let d = &recs[first_brick(leaf)];
                    (d.min.get(), d.max.get())
                },
                &scales,
            );
            let ranges: Vec<LeafRange> = ranges
                .iter()
                .map(|&(lo, hi)| LeafRange {
                    min: lo.into(),
                    max: hi.into(),
                })
                .collect();
            let brick_data = meta.push(recs.as_bytes())?;
            let leaf_ranges = meta.push(ranges.as_bytes())?;
            let min = recs
                .iter()
                .map(|d| d.min.get())
                .fold(f32::INFINITY, f32::min);
            let max = recs
                .iter()
                .map(|d| d.max.get())
                .fold(f32::NEG_INFINITY, f32::max);
            fields.push(FieldRecord {
                name_offset: (strings.len() as u32).into(),
                name_len: (name.len() as u32).into(),
                min: min.into(),
                max: max.into(),
                data: data_sections[f],
                brick_data,
                leaf_ranges,
            });
            strings.extend_from_slice(name.as_bytes());
        }
        let fields_sec = meta.push(fields.as_bytes())?;
        let tables_sec = meta.push(self.block_tables.as_bytes())?;
        let strings_sec = meta.push(&strings)?;
        // What the footer needs of the tree; the tree itself is not held while the tight ranges
        // are computed.
        let (num_nodes, num_leaves, list_len) =
            (tree.nodes.len(), tree.leaves.len(), tree.brick_list.len());
        drop((records, leaf_level));
        drop(tree);
        let footer_of =
            |metadata: Section, metadata_crc: u32, (tight_ranges, part_table): (Section, u64)| {
                let mut footer = Footer {
                    magic: raw::MAGIC,
                    layout_version: raw::LAYOUT_VERSION.into(),
                    footer_size: (size_of::<Footer>() as u32).into(),
                    num_levels: (nl as u32).into(),
                    num_fields: (self.spec.fields.len() as u32).into(),
                    num_bricks: (self.spec.bricks.len() as u32).into(),
                    num_nodes: (num_nodes as u32).into(),
                    num_leaves: (num_leaves as u32).into(),
                    brick_list_len: (list_len as u32).into(),
                    reserved0: [0; 8],
                    metadata,
                    levels: levels_sec,
                    fields: fields_sec,
                    bricks: bricks_sec,
                    nodes: nodes_sec,
                    leaves: leaves_sec,
                    brick_list: list_sec,
                    strings: strings_sec,
                    block_tables: tables_sec,
                    block_cells: raw::BLOCK_CELLS.into(),
                    tight_ranges,
                    part_table: part_table.into(),
                    reserved1: [0; 4],
                    simulation: self.simulation,
                    metadata_crc: metadata_crc.into(),
                    footer_crc: 0.into(),
                };
                let fb = footer.as_bytes();
                footer.footer_crc = crc32fast::hash(&fb[..fb.len() - 4]).into();
                footer
            };
        let file_bytes = match self.tight {
            None => {
                let (metadata, crc) = meta.finish()?;
                write_footer(
                    self.file.as_file(),
                    &footer_of(metadata, crc, (Section::default(), 0)),
                )?
            }
            Some(tight) => {
                // A complete file without the tight ranges first, which `tight` reads; the
                // tables then go where its footer was, and a new footer after them.
                let (metadata, crc) = meta.snapshot()?;
                write_footer(
                    self.file.as_file(),
                    &footer_of(metadata, crc, (Section::default(), 0)),
                )?;
                let mut sink = TightSink::new(&mut meta, self.spec.fields.len(), num_leaves);
                tight(self.file.path(), &mut sink).map_err(FormatError::TightRanges)?;
                let tables = sink.finish()?;
                let (metadata, crc) = meta.finish()?;
                write_footer(self.file.as_file(), &footer_of(metadata, crc, tables))?
            }
        };
        let file = self.file.as_file();
        file.sync_all()
            .map_err(|e| FormatError::io("syncing the file", e))?;
        let target = self.target.clone();
        self.file.persist(&target).map_err(|e| {
            FormatError::io(
                format!("renaming the finished file to {}", target.display()),
                e.error,
            )
        })?;
        if let Some(dir) = target.parent().filter(|p| !p.as_os_str().is_empty()) {
            // Make the rename itself durable; a failure here loses nothing already written.
            let _ = File::open(dir).and_then(|d| d.sync_all());
        }
        Ok(WriteSummary {
            file_bytes,
            data_bytes,
            raw_data_bytes,
            bricks: self.spec.bricks.len(),
            leaves: num_leaves,
            nodes: num_nodes,
            cells: self.spec.total_cells(),
        })
    }

    /// Gives each field its data region: raw bricks are already in place; compressed ones are
    /// copied from their spill file now and their offsets made absolute.
    fn place_data(
        &mut self,
        mut records: Vec<Vec<BrickData>>,
    ) -> Result<(Vec<Vec<BrickData>>, Vec<Section>)> {
        let mut sections = Vec::with_capacity(records.len());
        match self.spill.take() {
            None => {
                for recs in &records {
                    let start = recs
                        .first()
                        .map(|d| d.offset.get())
                        .unwrap_or(self.data_end);
                    let end = recs
                        .last()
                        .map(|d| align_up(d.offset.get() + d.len.get()))
                        .unwrap_or(start);
                    sections.push(Section {
                        offset: start.into(),
                        len: (end - start).into(),
                    });
                }
            }
            Some(spills) => {
                let mut at = self.data_end;
                let out = self.file.as_file_mut();
                for (recs, mut spill) in records.iter_mut().zip(spills) {
                    out.seek(SeekFrom::Start(at))
                        .map_err(|e| FormatError::io("seeking the output", e))?;
                    let src = spill.file.as_file_mut();
                    src.seek(SeekFrom::Start(0))
                        .map_err(|e| FormatError::io("rewinding a spill file", e))?;
                    std::io::copy(&mut std::io::Read::take(src, spill.len), out)
                        .map_err(|e| FormatError::io("copying compressed bricks into place", e))?;
                    for d in recs.iter_mut() {
                        d.offset = (d.offset.get() + at).into();
                    }
                    sections.push(Section {
                        offset: at.into(),
                        len: spill.len.into(),
                    });
                    at = align_up(at + spill.len);
                }
                out.flush()
                    .map_err(|e| FormatError::io("flushing the output", e))?;
                self.data_end = at;
            }
        }
        Ok((records, sections))
    }
}

/// Builds the kd-tree from the brick boxes alone, before any data arrives, so that an
/// inconsistent hierarchy (overlapping bricks) fails before the input is read.
fn build_tree(spec: &HierarchySpec) -> Result<KdTree> {
    let nl = spec.levels.len();
    let domain = spec.levels[nl - 1].domain;
    let origin = domain.lo;
    let scales: Vec<[i64; 3]> = (0..nl).map(|l| spec.finest_scale(l)).collect();
    let tree_bricks: Vec<TreeBrick> = spec
        .bricks
        .iter()
        .map(|b| {
            let f = b
                .cells
                .refine(scales[b.level as usize])
                .expect("validated extents");
            TreeBrick {
                bounds: IBox::new(
                    [0, 1, 2].map(|a| f.lo[a] - origin[a]),
                    [0, 1, 2].map(|a| f.hi[a] - origin[a]),
                ),
                level: b.level,
            }
        })
        .collect();
    kdtree::build(&tree_bricks, IBox::new([0; 3], domain.extent()))
}

/// Writes `footer` right after its metadata region and ends the file there; returns the file's
/// length.
fn write_footer(file: &File, footer: &Footer) -> Result<u64> {
    let footer_at = footer.metadata.offset.get() + footer.metadata.len.get();
    file.write_all_at(footer.as_bytes(), footer_at)
        .map_err(|e| FormatError::io("writing the footer", e))?;
    let file_bytes = footer_at + size_of::<Footer>() as u64;
    file.set_len(file_bytes)
        .map_err(|e| FormatError::io("setting the file length", e))?;
    Ok(file_bytes)
}

/// The little-endian bytes of `values`: borrowed on little-endian hosts.
fn le_bytes<'a>(values: &[f32], native: &'a [u8]) -> std::borrow::Cow<'a, [u8]> {
    if cfg!(target_endian = "little") {
        std::borrow::Cow::Borrowed(native)
    } else {
        std::borrow::Cow::Owned(values.iter().flat_map(|v| v.to_le_bytes()).collect())
    }
}

/// Writes the metadata region: sections appended at 64-byte boundaries, zero padding between
/// them, every byte fed to the region's checksum in file order.
pub(crate) struct MetaWriter<'a> {
    file: &'a File,
    start: u64,
    pos: u64,
    crc: crc32fast::Hasher,
}

impl<'a> MetaWriter<'a> {
    fn new(file: &'a File, start: u64) -> Self {
        let start = align_up(start);
        Self {
            file,
            start,
            pos: start,
            crc: crc32fast::Hasher::new(),
        }
    }

    /// Appends `data` to the section being written.
    pub(crate) fn write(&mut self, data: &[u8]) -> Result<()> {
        self.file
            .write_all_at(data, self.pos)
            .map_err(|e| FormatError::io("writing metadata", e))?;
        self.crc.update(data);
        self.pos += data.len() as u64;
        Ok(())
    }

    fn pad(&mut self) -> Result<()> {
        let pad = (align_up(self.pos) - self.pos) as usize;
        self.write(&[0u8; raw::ALIGN as usize][..pad])
    }

    /// Starts a section written piece by piece ([`Self::write`]): pads, and returns its offset.
    pub(crate) fn begin(&mut self) -> Result<u64> {
        self.pad()?;
        Ok(self.pos)
    }

    /// Writes `data` as one section.
    pub(crate) fn push(&mut self, data: &[u8]) -> Result<Section> {
        self.pad()?;
        let at = self.pos;
        self.write(data)?;
        Ok(Section {
            offset: at.into(),
            len: (data.len() as u64).into(),
        })
    }

    /// The region written so far and its checksum, as [`Self::finish`] would give them; more
    /// sections may follow.
    fn snapshot(&mut self) -> Result<(Section, u32)> {
        self.pad()?;
        Ok((
            Section {
                offset: self.start.into(),
                len: (self.pos - self.start).into(),
            },
            self.crc.clone().finalize(),
        ))
    }

    fn finish(mut self) -> Result<(Section, u32)> {
        self.pad()?;
        let len = self.pos - self.start;
        Ok((
            Section {
                offset: self.start.into(),
                len: len.into(),
            },
            self.crc.finalize(),
        ))
    }
}
