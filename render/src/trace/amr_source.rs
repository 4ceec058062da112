//! The `.amrk` file as a voxel source: active voxels from the extraction (issue 4), decoded from
//! their 32:32 refs, and point samples of the chosen reconstruction. Grid coordinates are the
//! extraction's doubled finest-level coordinates.

use std::cell::RefCell;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

use amr_format::progress::NoProgress;
use amr_synth::{write_synth, AnalyticField, Case, SynthParams};
use amr_format::{AmrkFile, WriterOptions};
use anyhow::Context;

use crate::extract::Extractor;
use crate::mapping::{mapped_resident_bytes, open_mapped, PageRelease};
use crate::reconstruct::{Method as Recon, VertexMemo};
use crate::render_cmd::{
    header_meta, progress_bar, render_source, stats_rows, write_outputs, ActiveSource, Method,
    Reconstruction, RenderArgs, RenderConfig,
};
use crate::shade::IsoSpec;
use crate::trace::recon_source::ReconSource;
use crate::trace::source::{GridFrame, Voxel, VoxelSource};

/// Bytes of decompressed bricks the extraction may cache.
const CACHE_BYTES: usize = 256 << 20;

/// Slots of each thread's cache of decoded voxels (a power of two).
const VOXEL_CACHE_SLOTS: usize = 4096;

/// Bytes of one thread's voxel cache: the decoded voxels with their keys, plus the vertex memo
/// (bounded by [`VertexMemo`]'s own capacity, not counted here).
pub const VOXEL_CACHE_BYTES: usize = VOXEL_CACHE_SLOTS * std::mem::size_of::<(u64, u64, Voxel)>();

/// Source ids, so that a thread's cache never answers for another source.
static NEXT_SOURCE: AtomicU64 = AtomicU64::new(1);

/// Threads that have allocated a voxel cache (for the memory statistics).
static CACHE_THREADS: AtomicU64 = AtomicU64::new(0);

/// One thread's decoded voxels: direct-mapped by ref, tagged with the source id.
struct VoxelCache {
    source: u64,
    slots: Vec<(u64, u64, Voxel)>,
    memo: VertexMemo,
}

thread_local! {
    static VOXELS: RefCell<VoxelCache> = RefCell::new(VoxelCache {
        source: 0,
        slots: Vec::new(),
        memo: VertexMemo::default(),
    });
}

/// Bytes held by the per-thread voxel caches of this process.
pub fn voxel_cache_bytes() -> u64 {
    CACHE_THREADS.load(Ordering::Relaxed) * VOXEL_CACHE_BYTES as u64
}

/// One field of an open file as a [`VoxelSource`].
pub struct AmrSource<'f, D> {
    ext: Extractor<'f, D>,
    method: Recon,
    frame: GridFrame,
    id: u64,
}

impl<'f, D: AsRef<[u8]> + Sync> AmrSource<'f, D> {
    /// The source for field `field` of `file`, sampled with `reconstruction`.
    pub fn new(
        file: &'f AmrkFile<D>,
        field: usize,
        reconstruction: Reconstruction,
    ) -> anyhow::Result<Self> {
        let ext = Extractor::new(file, field, CACHE_BYTES)?;
        let grid = ext.sampler().grid();
        let origin = grid.to_world([0.0; 3]);
        let unit = [0, 1, 2].map(|a| {
            let mut e = [0.0; 3];
            e[a] = 1.0;
            grid.to_world(e)[a] - origin[a]
        });
        let extent = grid.extent().map(|e| 2.0 * e as f64);
        let method = match reconstruction {
            Reconstruction::Octant => Recon::Octant,
            Reconstruction::Current => Recon::Current,
            Reconstruction::Nearest => Recon::Nearest,
        };
        Ok(AmrSource {
            ext,
            id: NEXT_SOURCE.fetch_add(1, Ordering::Relaxed),
            method,
            frame: GridFrame {
                origin,
                unit,
                extent,
            },
        })
    }
}

impl<'f, D: AsRef<[u8]> + Sync> AmrSource<'f, D> {
    /// The extractor underneath.
    pub fn extractor(&self) -> &Extractor<'f, D> {
        &self.ext
    }

    /// Releases `pages` (the map of this source's file) after each chunk of the extraction and
    /// between the stages of a render.
    pub fn set_page_release(&mut self, pages: &'f PageRelease<'f>) {
        self.ext.set_page_release(pages);
    }
}

impl<D: AsRef<[u8]> + Sync> AmrSource<'_, D> {
    /// The voxel `r` names, from this thread's cache when it holds it.
    fn cached_voxel(&self, r: u64) -> Voxel {
        VOXELS.with(|cell| {
            let mut guard = cell.borrow_mut();
            let cache = &mut *guard;
            if cache.slots.is_empty() {
                CACHE_THREADS.fetch_add(1, Ordering::Relaxed);
                let empty = (0, u64::MAX, self.decode_ref(r, &mut cache.memo));
                cache.slots = vec![empty; VOXEL_CACHE_SLOTS];
            }
            if cache.source != self.id {
                cache.source = self.id;
                cache.memo.clear();
                for s in &mut cache.slots {
                    s.0 = 0;
                }
            }
            // Fibonacci hashing of the ref: neighbouring refs land in different slots.
            let slot = (r.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 52) as usize % VOXEL_CACHE_SLOTS;
            let e = cache.slots[slot];
            if e.0 == self.id && e.1 == r {
                return e.2;
            }
            let v = self.decode_ref(r, &mut cache.memo);
            cache.slots[slot] = (self.id, r, v);
            v
        })
    }
}

impl<D: AsRef<[u8]> + Sync> AmrSource<'_, D> {
    /// Decodes `r` (a NaN voxel when it names none).
    fn decode_ref(&self, r: u64, memo: &mut VertexMemo) -> Voxel {
        match self.ext.decode_memo(r, memo) {
            Ok(v) => Voxel {
                lo: v.lo_doubled.map(|x| x as f64),
                hi: v.hi_doubled.map(|x| x as f64),
                values: v.values,
                level: v.level,
            },
            Err(_) => Voxel {
                lo: [0.0; 3],
                hi: [0.0; 3],
                values: [f32::NAN; 8],
                level: 0,
            },
        }
    }
}

impl<D: AsRef<[u8]> + Sync> VoxelSource for AmrSource<'_, D> {
    fn frame(&self) -> GridFrame {
        self.frame
    }

    fn voxel(&self, r: u64) -> Voxel {
        self.cached_voxel(r)
    }

    fn voxel_box(&self, r: u64) -> ([f64; 3], [f64; 3]) {
        // A reference that names no voxel gets the empty box `decode_ref` gives it.
        self.ext
            .voxel_box(r)
            .map_or(([0.0; 3], [0.0; 3]), |(lo, hi)| {
                (lo.map(|x| x as f64), hi.map(|x| x as f64))
            })
    }

    fn sample(&self, p: [f64; 3]) -> Option<(f32, u32)> {
        let s = self.ext.sampler();
        let v = s.sample(p, self.method).ok().flatten()?;
        let ext = s.grid().extent();
        let finest = [0, 1, 2].map(|a| ((p[a] * 0.5).floor() as i64).clamp(0, ext[a] - 1));
        let level = s.locate(finest).ok().flatten().map_or(0, |c| c.level);
        Some((v, level))
    }

    fn release_pages(&self) {
        self.ext.release_pages();
    }
}

impl<D: AsRef<[u8]> + Sync> ActiveSource for AmrSource<'_, D> {
    fn extract(&self, iso: f32) -> anyhow::Result<Vec<u64>> {
        Ok(self.ext.extract(iso)?.refs)
    }
}

/// The index of the field `args` names (the first by default), and the middle of its range as the
/// isovalue when `cfg` has none.
pub fn resolve_field<D: AsRef<[u8]>>(
    file: &AmrkFile<D>,
    args: &RenderArgs,
    cfg: &mut RenderConfig,
) -> anyhow::Result<usize> {
    let field = match &args.field {
        Some(name) => file.field_index(name).with_context(|| {
            let names: Vec<&str> = file.fields().iter().map(|f| f.name.as_str()).collect();
            format!(
                "{}: no field '{name}' (fields: {})",
                args.file.display(),
                names.join(", ")
            )
        })?,
        None => 0,
    };
    if cfg.isos.is_empty() {
        let f = &file.fields()[field];
        cfg.isos.push(IsoSpec {
            value: 0.5 * (f.min + f.max),
            color: None,
            opacity: 1.0,
        });
    }
    Ok(field)
}

/// Renders the file named in `args` with the validated `cfg`.
pub fn render_file(args: &RenderArgs, mut cfg: RenderConfig) -> anyhow::Result<()> {
    let file = open_mapped(&args.file)?;
    let field = resolve_field(&file, args, &mut cfg)?;
    let pages = PageRelease::new(&file);
    let (bar, progress) = progress_bar(u64::from(cfg.size.1));
    let report = match args.reconstruction {
        Reconstruction::Octant => {
            let mut src = AmrSource::new(&file, field, args.reconstruction)?;
            src.set_page_release(&pages);
            render_source(&src, &cfg, &progress)?
        }
        other => {
            // A piecewise-constant field has no smooth normals: nearest shades with face normals.
            cfg.smooth_normals &= other != Reconstruction::Nearest;
            let src = ReconSource::new(&file, field, other)?;
            render_source(&src, &cfg, &progress)?
        }
    };
    bar.finish_and_clear();
    let extra = [
        ("field", format!("\"{}\"", file.fields()[field].name)),
        ("file_bytes", file.bytes().len().to_string()),
        ("voxel_cache_bytes", voxel_cache_bytes().to_string()),
        (
            "mapped_resident_bytes",
            mapped_resident_bytes(file.bytes()).map_or("null".into(), |b| b.to_string()),
        ),
        ("mapped_resident_peak_bytes", pages.peak_bytes().to_string()),
    ];
    let meta = header_meta(&cfg, &report, &[("file", args.file.display().to_string())]);
    let rows = stats_rows(&report, &extra);
    write_outputs(
        &report,
        &meta,
        &args.output,
        args.preview.as_deref(),
        &rows,
        args.stats,
        args.stats_json.as_deref(),
    )
}

/// Synthesizes the two-blob dataset (3 levels, ratio 2), converts it to a temporary `.amrk`
/// file and renders it to `out`, with a PNG preview beside it.
pub fn demo(out: &Path) -> anyhow::Result<()> {
    let dir = tempfile_dir()?;
    let path = dir.join("demo.amrk");
    let params = SynthParams {
        levels: 3,
        ratio: 2,
        base: 32,
        brick: 16,
        origin: [0.0; 3],
        size: 1.0,
    };
    write_synth(
        &path,
        Case::Blobs,
        &params,
        WriterOptions::default(),
        &NoProgress,
    )
    .with_context(|| format!("cannot write {}", path.display()))?;
    let iso = Case::Blobs.default_iso() as f32;
    let args = RenderArgs {
        file: path.clone(),
        field: None,
        iso: vec![
            IsoSpec {
                value: iso,
                color: Some([0.85, 0.62, 0.35]),
                opacity: 1.0,
            },
            IsoSpec {
                value: 0.6 * iso,
                color: Some([0.35, 0.55, 0.85]),
                opacity: 0.3,
            },
        ],
        output: out.to_path_buf(),
        size: (800, 600),
        camera_pos: None,
        look_at: None,
        up: None,
        fov: 35.0,
        reconstruction: Reconstruction::Octant,
        method: Method::Hybrid,
        step: None,
        spp: 1,
        threads: None,
        preview: Some(out.with_extension("png")),
        stats: true,
        stats_json: None,
        ao: 4,
        no_shadows: false,
        flat_normals: false,
        mpi_mode: None,
    };
    let result = crate::render_cmd::run_render(&args);
    let _ = std::fs::remove_dir_all(&dir);
    result?;
    eprintln!(
        "wrote {} and {}",
        out.display(),
        out.with_extension("png").display()
    );
    Ok(())
}

fn tempfile_dir() -> anyhow::Result<std::path::PathBuf> {
    let d = std::env::temp_dir().join(format!("amr-render-demo-{}", std::process::id()));
    std::fs::create_dir_all(&d).with_context(|| format!("cannot create {}", d.display()))?;
    Ok(d)
}
