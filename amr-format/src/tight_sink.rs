//! What a tight-range computation ([`crate::writer::TightFn`]) hands the writer: each leaf's
//! tight range and the bounds of its parts, leaf after leaf, field after field. The part bounds
//! are streamed into the metadata as they come, so that the writer never holds them whole; the
//! tight ranges and each leaf's first part (8 bytes per leaf each) are held until the end.

use zerocopy::little_endian::U64;
use zerocopy::IntoBytes;

use crate::error::{FormatError, Result};
use crate::raw::{LeafRange, PartTable, Section};
use crate::value_range::valid_tight_range;
use crate::writer::MetaWriter;

/// Bytes of part bounds gathered before they are written, at most.
const BUFFER_BYTES: usize = 64 << 10;

/// Receives the tables a [`crate::writer::TightFn`] computes; see the module documentation.
pub struct TightSink<'a, 'f> {
    meta: &'a mut MetaWriter<'f>,
    fields: usize,
    leaves: usize,
    /// The field and leaf the next [`Self::push`] is for.
    next: (usize, usize),
    tight: Vec<LeafRange>,
    /// Each leaf's first part, and one past the last leaf's, as field 0 gave them.
    starts: Vec<U64>,
    part_cells: Option<u32>,
    /// Where the part bounds start in the file, once the first one is written.
    ranges_at: Option<u64>,
    /// Part bounds written or buffered so far, over all fields.
    parts: u64,
    buffer: Vec<u8>,
}

impl<'a, 'f> TightSink<'a, 'f> {
    /// A sink for `fields` fields of `leaves` leaves, writing through `meta`.
    pub(crate) fn new(meta: &'a mut MetaWriter<'f>, fields: usize, leaves: usize) -> Self {
        Self {
            meta,
            fields,
            leaves,
            next: (0, 0),
            tight: Vec::with_capacity(fields.saturating_mul(leaves)),
            starts: vec![0.into()],
            part_cells: None,
            ranges_at: None,
            parts: 0,
            buffer: Vec::with_capacity(BUFFER_BYTES),
        }
    }

    /// Declares that the leaves' part bounds follow, for parts of `cells` cells per axis (see
    /// [`PartTable`]); before the first [`Self::push`]. Without it the file stores none.
    pub fn set_part_cells(&mut self, cells: u32) -> std::result::Result<(), String> {
        if self.next != (0, 0) {
            return Err("the part size was given after the first leaf".into());
        }
        if cells == 0 {
            return Err("parts of 0 cells".into());
        }
        self.part_cells = Some(cells);
        Ok(())
    }

    /// The next leaf's tight range and the bounds of its parts, in part order: leaves in order,
    /// field after field; every field gives each leaf as many parts as field 0 did. Ranges
    /// hold no NaN and have `lo <= hi` or are the empty range `(+inf, -inf)`.
    pub fn push(
        &mut self,
        tight: (f32, f32),
        parts: &[(f32, f32)],
    ) -> std::result::Result<(), String> {
        let (field, leaf) = self.next;
        if field >= self.fields {
            return Err(format!(
                "more leaves given than the file's {} fields x {} leaves",
                self.fields, self.leaves
            ));
        }
        if !valid_tight_range(tight.0, tight.1) {
            return Err(format!(
                "field {field}, leaf {leaf}: range {}..{}",
                tight.0, tight.1
            ));
        }
        if self.part_cells.is_none() && !parts.is_empty() {
            return Err(format!(
                "field {field}, leaf {leaf}: part bounds given without a part size"
            ));
        }
        if field == 0 {
            let last = self.starts[self.starts.len() - 1].get();
            self.starts.push((last + parts.len() as u64).into());
        } else {
            let want = self.starts[leaf + 1].get() - self.starts[leaf].get();
            if parts.len() as u64 != want {
                return Err(format!(
                    "field {field}, leaf {leaf}: {} parts given, field 0 gave {want}",
                    parts.len()
                ));
            }
        }
        if let Some(p) = parts
            .iter()
            .position(|&(lo, hi)| !valid_tight_range(lo, hi))
        {
            let (lo, hi) = parts[p];
            return Err(format!(
                "field {field}, leaf {leaf}, part {p}: bound {lo}..{hi}"
            ));
        }
        self.tight.push(LeafRange {
            min: tight.0.into(),
            max: tight.1.into(),
        });
        for &(lo, hi) in parts {
            if self.buffer.len() + size_of::<LeafRange>() > BUFFER_BYTES {
                self.flush().map_err(|e| e.to_string())?;
            }
            let r = LeafRange {
                min: lo.into(),
                max: hi.into(),
            };
            self.buffer.extend_from_slice(r.as_bytes());
        }
        self.parts += parts.len() as u64;
        self.next = if leaf + 1 == self.leaves {
            (field + 1, 0)
        } else {
            (field, leaf + 1)
        };
        Ok(())
    }

    /// Writes the buffered part bounds.
    fn flush(&mut self) -> Result<()> {
        if self.ranges_at.is_none() {
            self.ranges_at = Some(self.meta.begin()?);
        }
        self.meta.write(&self.buffer)?;
        self.buffer.clear();
        Ok(())
    }

    /// Checks that every leaf of every field was given, writes what is left: the tight range
    /// table's section and, when part bounds were given, where the [`PartTable`] record lies.
    pub(crate) fn finish(mut self) -> Result<(Section, u64)> {
        if self.next != (self.fields, 0) && self.leaves > 0 {
            return Err(FormatError::TightRanges(format!(
                "{} leaves given, the file has {} fields x {} leaves",
                self.tight.len(),
                self.fields,
                self.leaves
            )));
        }
        let Some(part_cells) = self.part_cells else {
            return Ok((self.meta.push(self.tight.as_bytes())?, 0));
        };
        self.flush()?;
        let at = self.ranges_at.expect("set by the flush");
        let ranges = Section {
            offset: at.into(),
            len: (self.parts * size_of::<LeafRange>() as u64).into(),
        };
        let starts = self.meta.push(self.starts.as_bytes())?;
        let tight = self.meta.push(self.tight.as_bytes())?;
        let record = PartTable {
            part_cells: part_cells.into(),
            reserved0: 0.into(),
            starts,
            ranges,
            reserved1: [0; 24],
        };
        let table = self.meta.push(record.as_bytes())?;
        Ok((tight, table.offset.get()))
    }
}
