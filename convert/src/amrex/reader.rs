//! Streams a plotfile's cell data: every data file is opened once and read front to back,
//! boxes in offset order, handing out one z-slab of one component of one box at a time.
//!
//! A reading thread reads and decodes while the caller's thread consumes slabs; memory is a
//! few slabs (a box's x-y extent times `slab_z` planes each) plus the metadata.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{channel, sync_channel, Receiver, SyncSender};

use amr_format::IBox;

use super::error::{AmrexError, Result};
use super::fab::{why_not_f32, FabHeader, RealFormat, MAX_FAB_HEADER};
use super::plotfile::{show, Plotfile};
use crate::hierarchy_to_amrk::Slab;
use amr_format::progress::Progress;

/// Read buffer per data file.
const READ_BUFFER: usize = 4 << 20;
/// Decoded slabs queued between the reading thread and the consumer.
const IN_FLIGHT: usize = 4;

/// What [`stream`] read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamStats {
    /// Bytes actually read from data files (skipped bytes are not counted).
    pub bytes_read: u64,
    /// Bytes of data files traversed, read or skipped.
    pub bytes_covered: u64,
}

/// One box to read: where it is and what it is.
struct Job {
    level: usize,
    index: usize,
    offset: u64,
}

/// Every box's FAB, grouped by data file (files in path order), each file's FABs in offset
/// order: the order [`stream`] reads them in.
fn jobs_by_file(pf: &Plotfile) -> Vec<(PathBuf, Vec<Job>)> {
    let mut files: BTreeMap<PathBuf, Vec<Job>> = BTreeMap::new();
    for (level, pl) in pf.levels.iter().enumerate() {
        for (index, fod) in pl.cells.fabs.iter().enumerate() {
            files.entry(pl.dir.join(&fod.file)).or_default().push(Job {
                level,
                index,
                offset: fod.offset,
            });
        }
    }
    let mut files: Vec<_> = files.into_iter().collect();
    for (_, jobs) in &mut files {
        jobs.sort_by_key(|j| j.offset);
    }
    files
}

/// `(level, index)` of every box in the order [`stream`] hands out their slabs.
pub fn stream_order(pf: &Plotfile) -> Vec<(usize, usize)> {
    jobs_by_file(pf)
        .into_iter()
        .flat_map(|(_, jobs)| jobs.into_iter().map(|j| (j.level, j.index)))
        .collect()
}

/// Streams the components `comps` (indices into the plotfile's fields) of every box of every
/// level to `sink`, in slabs of at most `slab_z` planes aligned to each box's lower z corner.
/// Progress counts data-file bytes.
pub fn stream(
    pf: &Plotfile,
    comps: &[usize],
    slab_z: i64,
    progress: &dyn Progress,
    mut sink: impl FnMut(Slab) -> Result<()>,
) -> Result<StreamStats> {
    let nfields = pf.header.fields.len();
    let mut selected: Vec<Option<usize>> = vec![None; nfields];
    for (p, &c) in comps.iter().enumerate() {
        selected[c] = Some(p);
    }
    let files = jobs_by_file(pf);
    let mut sizes = Vec::with_capacity(files.len());
    for (path, _) in &files {
        let meta = std::fs::metadata(path)
            .map_err(|e| AmrexError::io(path, "cannot open data file", e))?;
        sizes.push(meta.len());
    }
    progress.set_total(sizes.iter().sum());
    let advanced = AtomicU64::new(0);
    let (tx, rx) = sync_channel::<OwnedSlab>(IN_FLIGHT);
    let (back_tx, back_rx) = channel::<Vec<f32>>();
    let files: Vec<(PathBuf, Vec<Job>, u64)> = files
        .into_iter()
        .zip(sizes)
        .map(|((p, j), n)| (p, j, n))
        .collect();
    std::thread::scope(|scope| {
        let reader = scope.spawn(|| {
            let mut st = FileStreamer {
                pf,
                selected: &selected,
                slab_z: slab_z.max(1),
                raw: Vec::new(),
                tx,
                spare: back_rx,
            };
            st.read_files(files, &advanced)
        });
        let mut reported = 0;
        let mut consumed = Ok(());
        for slab in rx.iter() {
            let now = advanced.load(Ordering::Relaxed);
            progress.advance(now - reported);
            reported = now;
            consumed = sink(slab.borrow());
            if consumed.is_err() {
                break;
            }
            let _ = back_tx.send(slab.values);
        }
        drop(rx);
        let read = reader
            .join()
            .unwrap_or_else(|_| Err(AmrexError::invalid(&pf.dir, "the reading thread panicked")));
        consumed?;
        let stats = read?;
        progress.advance(advanced.load(Ordering::Relaxed) - reported);
        Ok(stats)
    })
}

/// A [`Slab`] that owns its values, on its way from the reading thread to the consumer.
struct OwnedSlab {
    level: usize,
    index: usize,
    valid: IBox,
    field: usize,
    cells: IBox,
    values: Vec<f32>,
}

impl OwnedSlab {
    fn borrow(&self) -> Slab<'_> {
        Slab {
            level: self.level,
            index: self.index,
            valid: self.valid,
            field: self.field,
            cells: self.cells,
            values: &self.values,
        }
    }
}

/// One data file being read front to back.
struct DataFile<'a> {
    r: BufReader<File>,
    path: &'a Path,
    pos: u64,
    len: u64,
    read: u64,
    advanced: &'a AtomicU64,
}

impl DataFile<'_> {
    fn skip(&mut self, n: u64) -> Result<()> {
        if n == 0 {
            return Ok(());
        }
        let d = i64::try_from(n)
            .map_err(|_| AmrexError::invalid(self.path, format!("skip of {n} bytes")))?;
        self.r.seek_relative(d).map_err(|e| {
            AmrexError::io(self.path, format!("seeking to byte {}", self.pos + n), e)
        })?;
        self.pos += n;
        self.advanced.fetch_add(n, Ordering::Relaxed);
        Ok(())
    }

    fn read_exact(&mut self, buf: &mut [u8], what: &dyn Fn() -> String) -> Result<()> {
        self.r.read_exact(buf).map_err(|e| {
            if e.kind() == std::io::ErrorKind::UnexpectedEof {
                AmrexError::Truncated {
                    path: self.path.to_path_buf(),
                    msg: format!("the file ends inside {}", what()),
                }
            } else {
                AmrexError::io(
                    self.path,
                    format!("reading {} at byte {}", what(), self.pos),
                    e,
                )
            }
        })?;
        self.pos += buf.len() as u64;
        self.read += buf.len() as u64;
        self.advanced.fetch_add(buf.len() as u64, Ordering::Relaxed);
        Ok(())
    }

    fn read_line(&mut self, what: &dyn Fn() -> String) -> Result<String> {
        let mut line = Vec::new();
        let n = (&mut self.r)
            .take(MAX_FAB_HEADER as u64)
            .read_until(b'\n', &mut line)
            .map_err(|e| AmrexError::io(self.path, format!("reading {}", what()), e))?;
        if line.last() != Some(&b'\n') {
            let why = if n < MAX_FAB_HEADER {
                "the file ends inside"
            } else {
                "no end of line within 4 KiB in"
            };
            return Err(AmrexError::Truncated {
                path: self.path.to_path_buf(),
                msg: format!("{why} {}", what()),
            });
        }
        self.pos += n as u64;
        self.read += n as u64;
        self.advanced.fetch_add(n as u64, Ordering::Relaxed);
        line.pop();
        String::from_utf8(line)
            .map_err(|_| AmrexError::invalid(self.path, format!("{} is not text", what())))
    }
}

/// The reading thread's state: the selection, the reused read buffer, and the channels.
struct FileStreamer<'a> {
    pf: &'a Plotfile,
    selected: &'a [Option<usize>],
    slab_z: i64,
    raw: Vec<u8>,
    tx: SyncSender<OwnedSlab>,
    spare: Receiver<Vec<f32>>,
}

/// The consumer stopped (after an error of its own): the reading thread ends quietly.
struct Stopped;

impl FileStreamer<'_> {
    fn read_files(
        &mut self,
        files: Vec<(PathBuf, Vec<Job>, u64)>,
        advanced: &AtomicU64,
    ) -> Result<StreamStats> {
        let mut stats = StreamStats::default();
        for (path, jobs, len) in files {
            let file =
                File::open(&path).map_err(|e| AmrexError::io(&path, "cannot open data file", e))?;
            let mut f = DataFile {
                r: BufReader::with_capacity(READ_BUFFER, file),
                path: &path,
                pos: 0,
                len,
                read: 0,
                advanced,
            };
            for job in &jobs {
                match self.read_box(&mut f, job) {
                    Ok(Ok(())) => {}
                    Ok(Err(Stopped)) => return Ok(stats),
                    Err(e) => return Err(e),
                }
            }
            advanced.fetch_add(len.saturating_sub(f.pos), Ordering::Relaxed);
            stats.bytes_read += f.read;
            stats.bytes_covered += len;
        }
        Ok(stats)
    }

    fn read_box(&mut self, f: &mut DataFile, job: &Job) -> Result<Result<(), Stopped>> {
        let pl = &self.pf.levels[job.level];
        let valid = pl.cells.boxes[job.index];
        let (l, i) = (job.level, job.index);
        let what = || format!("the FAB of level {l}, box {i} {}", show(&valid));
        if job.offset < f.pos {
            return Err(AmrexError::invalid(
                &pl.cell_h,
                format!(
                    "box {i} starts at byte {} of {}, inside the data of the box before it",
                    job.offset,
                    f.path.display()
                ),
            ));
        }
        if job.offset > f.len {
            return Err(AmrexError::Truncated {
                path: f.path.to_path_buf(),
                msg: format!(
                    "{} bytes long, but {} starts at byte {}",
                    f.len,
                    what(),
                    job.offset
                ),
            });
        }
        f.skip(job.offset - f.pos)?;
        let expected_box = valid.grow(pl.cells.nghost);
        let (format, data_box) = match pl.cells.real_format {
            Some(fmt) => (fmt, expected_box),
            None => {
                let line = f.read_line(&what)?;
                let h = match FabHeader::parse(&line) {
                    Ok(Ok(h)) => h,
                    Ok(Err(e)) => {
                        return Err(AmrexError::unsupported(f.path, format!("{}: {e}", what())))
                    }
                    Err(e) => {
                        return Err(AmrexError::invalid(
                            f.path,
                            format!("bad header of {}: {e}: '{line}'", what()),
                        ))
                    }
                };
                if h.ncomp != pl.cells.ncomp {
                    return Err(AmrexError::invalid(
                        f.path,
                        format!(
                            "{} has {} components, but {} says {}",
                            what(),
                            h.ncomp,
                            pl.cell_h.display(),
                            pl.cells.ncomp
                        ),
                    ));
                }
                if h.data_box != expected_box {
                    let ghost = match pl.cells.nghost {
                        [0, 0, 0] => String::new(),
                        g => format!(" grown by {g:?} ghost cells: {}", show(&expected_box)),
                    };
                    return Err(AmrexError::invalid(
                        f.path,
                        format!(
                            "the FAB at byte {} covers {}, but {} gives box {i} of level {l} as {}{ghost}",
                            job.offset,
                            show(&h.data_box),
                            pl.cell_h.display(),
                            show(&valid),
                        ),
                    ));
                }
                (h.format, h.data_box)
            }
        };
        let size = format.size() as u64;
        let too_big = || AmrexError::invalid(f.path, format!("{} is too large", what()));
        let cells = data_box.num_cells().ok_or_else(too_big)?;
        let comp_bytes = cells.checked_mul(size).ok_or_else(too_big)?;
        let total = comp_bytes
            .checked_mul(pl.cells.ncomp as u64)
            .ok_or_else(too_big)?;
        let end = f.pos.checked_add(total).ok_or_else(too_big)?;
        if end > f.len {
            return Err(AmrexError::Truncated {
                path: f.path.to_path_buf(),
                msg: format!(
                    "{} bytes long, but {} needs bytes {}..{}",
                    f.len,
                    what(),
                    f.pos,
                    end
                ),
            });
        }
        for c in 0..pl.cells.ncomp {
            match self.selected[c] {
                Some(p) => {
                    if let Err(Stopped) = self.read_component(f, job, format, &data_box, p, c)? {
                        return Ok(Err(Stopped));
                    }
                }
                None => f.skip(comp_bytes)?,
            }
        }
        Ok(Ok(()))
    }

    /// Reads one component of one box in slabs and sends each to the consumer.
    fn read_component(
        &mut self,
        f: &mut DataFile,
        job: &Job,
        format: RealFormat,
        data: &IBox,
        field: usize,
        comp: usize,
    ) -> Result<Result<(), Stopped>> {
        let valid = self.pf.levels[job.level].cells.boxes[job.index];
        let de = data.extent();
        let ve = valid.extent();
        let size = format.size();
        let plane_bytes = (de[0] as u64) * (de[1] as u64) * size as u64;
        f.skip((valid.lo[2] - data.lo[2]) as u64 * plane_bytes)?;
        let (x0, y0) = (
            (valid.lo[0] - data.lo[0]) as usize,
            (valid.lo[1] - data.lo[1]) as usize,
        );
        let trimmed_xy = de[0] != ve[0] || de[1] != ve[1];
        let mut z0 = valid.lo[2];
        while z0 < valid.hi[2] {
            let z1 = (z0 + self.slab_z).min(valid.hi[2]);
            let nz = (z1 - z0) as usize;
            let nbytes = usize::try_from(plane_bytes * nz as u64).map_err(|_| {
                AmrexError::invalid(f.path, "a slab of a box does not fit in memory")
            })?;
            self.raw.resize(nbytes, 0);
            let l = job.level;
            let i = job.index;
            f.read_exact(&mut self.raw, &|| {
                format!("level {l}, box {i}, component {comp}")
            })?;
            let ncells = ve[0] as usize * ve[1] as usize * nz;
            let mut vals = self.spare.try_recv().unwrap_or_default();
            vals.resize(ncells, 0.0);
            let result = if trimmed_xy {
                let mut r = Ok(());
                let row = ve[0] as usize;
                for (k, out_row) in vals.chunks_exact_mut(row).enumerate() {
                    let (y, z) = (k % ve[1] as usize, k / ve[1] as usize);
                    let start = ((z * de[1] as usize + y + y0) * de[0] as usize + x0) * size;
                    r = format
                        .decode(&self.raw[start..start + row * size], out_row)
                        .map_err(|(_, v)| v);
                    if r.is_err() {
                        break;
                    }
                }
                r
            } else {
                format.decode(&self.raw, &mut vals).map_err(|(_, v)| v)
            };
            if let Err(value) = result {
                return Err(AmrexError::BadValue {
                    path: f.path.to_path_buf(),
                    level: job.level,
                    index: job.index,
                    cells: show(&valid),
                    field: self.pf.header.fields[comp].clone(),
                    value,
                    why: why_not_f32(value),
                });
            }
            let cells = IBox::new(
                [valid.lo[0], valid.lo[1], z0],
                [valid.hi[0], valid.hi[1], z1],
            );
            let slab = OwnedSlab {
                level: job.level,
                index: job.index,
                valid,
                field,
                cells,
                values: vals,
            };
            if self.tx.send(slab).is_err() {
                return Ok(Err(Stopped));
            }
            z0 = z1;
        }
        f.skip((data.hi[2] - valid.hi[2]) as u64 * plane_bytes)?;
        Ok(Ok(()))
    }
}
