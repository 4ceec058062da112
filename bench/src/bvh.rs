//! BVH in chunks against one BVH over all refs, side by side on one file and one isovalue:
//! build time, build scratch, resident bytes and frame time, and whether the frames agree.

use std::time::{Duration, Instant};

use anyhow::Context;

use amr_render::bvh::{BoxRun, BuildMethod, BvhBuilder};
use amr_render::camera::Camera;
use amr_render::mapping::{open_mapped, PageRelease};
use amr_render::shade::{render_frame, Lighting, RenderSettings};
use amr_render::trace::{FieldSource, HybridTracer, Surface, VoxelSource};
use amr_render::Reconstruction;
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::BvhBuildParams;

/// What `amr-bench bvh` measures.
#[derive(Clone, Debug)]
pub struct BvhBenchConfig {
    /// Refs per chunk of each variant; `usize::MAX` is one BVH over all refs.
    pub chunks: Vec<usize>,
    /// Build methods; every chunk size is built with each.
    pub methods: Vec<BuildMethod>,
    /// Frames rendered per variant (the variants take turns, so each run is side by side).
    pub runs: usize,
    /// Image width and height.
    pub size: (u32, u32),
    /// Shadow rays (any-hit queries).
    pub shadows: bool,
    /// Ambient-occlusion rays per hit (any-hit queries).
    pub ao: u32,
}

/// One variant's measurements.
#[derive(Clone, Debug)]
pub struct BvhVariant {
    /// Refs per chunk (`usize::MAX`: one BVH).
    pub chunk_refs: usize,
    /// How the BVHs were built.
    pub method: BuildMethod,
    /// Chunks built.
    pub chunks: usize,
    /// Build time (boxes decoded from the file, PLOC, CWBVH conversion).
    pub build: Duration,
    /// Build scratch held at the end of the build.
    pub scratch_bytes: usize,
    /// Resident bytes of the BVH nodes.
    pub bvh_bytes: usize,
    /// Median frame time.
    pub frame: Duration,
    /// Time of the variant's first frame, which starts with the map's pages released, as in a
    /// render (the frame faults the pages it reads back in from the page cache).
    pub first_frame: Duration,
    /// Pixels whose colour, alpha or depth differ from the first variant's frame.
    pub differing_pixels: usize,
}

/// What `amr-bench bvh` measured.
#[derive(Clone, Debug)]
pub struct BvhComparison {
    /// Active voxels.
    pub active: usize,
    /// Time to decode the boxes of all active voxels from their refs (in parallel).
    pub decode: Duration,
    /// The renderer's builds.
    pub variants: Vec<BvhVariant>,
    /// obvhs's own builds over the decoded boxes.
    pub raw: Vec<RawBuild>,
}

/// obvhs's own build of one CWBVH over the same boxes, for comparison with the renderer's.
#[derive(Clone, Debug)]
pub struct RawBuild {
    /// The obvhs preset's name.
    pub preset: &'static str,
    /// Build time (boxes given).
    pub build: Duration,
}

/// The boxes of the voxels `refs` of `src` as the renderer's BVH gets them (grown by its pad);
/// the time taken is the second value.
fn voxel_boxes(src: &impl VoxelSource, refs: &[u64]) -> (Vec<Aabb>, Duration) {
    use rayon::prelude::*;
    let grid = amr_render::trace::traverse::bvh_grid(&src.frame());
    let t = Instant::now();
    let mut boxes = vec![Aabb::empty(); refs.len()];
    let mut codes = vec![0; refs.len()];
    boxes
        .par_chunks_mut(4096)
        .zip(codes.par_chunks_mut(4096))
        .zip(refs.par_chunks(4096))
        .for_each(|((out, codes), refs)| {
            src.voxel_boxes(refs, &mut BoxRun::new(out, codes, grid));
        });
    (boxes, t.elapsed())
}

/// The obvhs presets timed over all boxes at once: its fastest, and the one the renderer uses.
const RAW_PRESETS: [(&str, BvhBuildParams); 2] = [
    ("obvhs fastest_build", BvhBuildParams::fastest_build()),
    ("obvhs fast_build", BvhBuildParams::fast_build()),
];

/// The time of one obvhs build of a CWBVH over `boxes` with `params`.
fn raw_build(boxes: &[Aabb], params: BvhBuildParams) -> Duration {
    let t = Instant::now();
    let mut core = Duration::ZERO;
    std::hint::black_box(build_cwbvh(boxes, params, &mut core));
    t.elapsed()
}

/// Extracts `iso` from `path` once, builds one BVH per variant and renders each `runs` times
/// (the median is over all runs, the first included), and times obvhs's own builds over the same
/// boxes (the variants' builds and the raw builds take turns, `runs` times).
pub fn compare(
    path: &std::path::Path,
    iso: f32,
    cfg: &BvhBenchConfig,
) -> anyhow::Result<BvhComparison> {
    let file = open_mapped(path)?;
    let mut src = FieldSource::new(&file, 0, Reconstruction::Octant)?;
    src.set_page_release(PageRelease::new(&file));
    let refs = src
        .extract(iso)
        .with_context(|| format!("extracting iso {iso} from {}", path.display()))?
        .refs;
    let (boxes, decode) = voxel_boxes(&src, &refs);
    let mut raw_times: Vec<Vec<Duration>> = vec![Vec::new(); RAW_PRESETS.len()];
    let variants: Vec<(usize, BuildMethod)> = cfg
        .chunks
        .iter()
        .flat_map(|&c| cfg.methods.iter().map(move |&m| (c, m)))
        .collect();
    let mut build_times: Vec<Vec<Duration>> = vec![Vec::new(); variants.len()];
    for _ in 0..cfg.runs.max(1) {
        for (k, (_, params)) in RAW_PRESETS.iter().enumerate() {
            raw_times[k].push(raw_build(&boxes, *params));
        }
        for (k, &(chunk_refs, method)) in variants.iter().enumerate() {
            let mut builder = BvhBuilder::new();
            builder.chunk_refs = chunk_refs;
            builder.method = method;
            let t = Instant::now();
            std::hint::black_box(Surface::build(&src, iso, &refs, &mut builder));
            build_times[k].push(t.elapsed());
        }
    }
    let raw = RAW_PRESETS
        .iter()
        .zip(&mut raw_times)
        .map(|(&(preset, _), t)| RawBuild {
            preset,
            build: crate::median(t),
        })
        .collect();
    drop(boxes);
    let mut surfaces = Vec::new();
    let mut out = Vec::new();
    for (k, &(chunk_refs, method)) in variants.iter().enumerate() {
        let mut builder = BvhBuilder::new();
        builder.chunk_refs = chunk_refs;
        builder.method = method;
        let s = Surface::build(&src, iso, &refs, &mut builder);
        let build = crate::median(&mut build_times[k]);
        out.push(BvhVariant {
            chunk_refs,
            method,
            chunks: s.bvh.num_chunks(),
            build,
            scratch_bytes: builder.last_scratch_bytes,
            bvh_bytes: s.bvh.bvh_bytes(),
            frame: Duration::ZERO,
            first_frame: Duration::ZERO,
            differing_pixels: 0,
        });
        surfaces.push([s]);
    }
    let (lo, hi) = src.frame().world_bounds();
    let (w, h) = cfg.size;
    let camera = Camera::framing(lo, hi, 40.0, f64::from(w) / f64::from(h))?;
    let diag = (0..3).map(|a| (hi[a] - lo[a]).powi(2)).sum::<f64>().sqrt();
    let mut light = Lighting::for_camera(&camera, vec![[0.8, 0.8, 0.8]], vec![1.0], 0.08 * diag);
    light.shadows = cfg.shadows;
    light.ao_rays = cfg.ao;
    let settings = RenderSettings {
        width: w,
        height: h,
        spp: 1,
    };
    let mut times = vec![Vec::new(); surfaces.len()];
    let mut first = None;
    for run in 0..cfg.runs.max(1) {
        for (i, surface) in surfaces.iter().enumerate() {
            if run == 0 {
                src.release_pages();
            }
            let tracer = HybridTracer {
                src: &src,
                surfaces: surface,
                sources: &[],
                smooth_normals: true,
            };
            let t = Instant::now();
            let (fb, _) = render_frame(&tracer, &camera, &light, settings, &|_| {});
            times[i].push(t.elapsed());
            if run == 0 {
                out[i].first_frame = t.elapsed();
            }
            let reference = first.get_or_insert_with(|| fb.clone());
            let differ = (0..fb.len())
                .filter(|&p| {
                    (0..3).any(|c| fb.rgb[c][p].to_bits() != reference.rgb[c][p].to_bits())
                        || fb.alpha[p].to_bits() != reference.alpha[p].to_bits()
                        || fb.z[p].to_bits() != reference.z[p].to_bits()
                })
                .count();
            out[i].differing_pixels = out[i].differing_pixels.max(differ);
        }
    }
    for (v, t) in out.iter_mut().zip(&mut times) {
        v.frame = crate::median(t);
    }
    Ok(BvhComparison {
        active: refs.len(),
        decode,
        variants: out,
        raw,
    })
}

/// The comparison as a Markdown table, the raw obvhs builds below it.
pub fn table(c: &BvhComparison) -> String {
    let (active, variants) = (c.active, &c.variants);
    let mut s = format!(
        "{active} active voxels on {} threads; decoding their boxes from the refs took {:.3} s.\n\n\
         | BVH | chunks | build s | build scratch bytes | BVH bytes | \
         first frame s | frame s (median) | pixels differing from the first row |\n\
         |---|---|---|---|---|---|---|---|\n",
        rayon::current_num_threads(),
        c.decode.as_secs_f64()
    );
    for v in variants {
        let method = match v.method {
            BuildMethod::Morton => "Morton",
            BuildMethod::Ploc => "PLOC",
        };
        let name = if v.chunk_refs == usize::MAX {
            format!("{method}, one BVH over all refs")
        } else {
            format!("{method}, chunks of {} refs", v.chunk_refs)
        };
        s.push_str(&format!(
            "| {name} | {} | {:.3} | {} | {} | {:.4} | {:.4} | {} |\n",
            v.chunks,
            v.build.as_secs_f64(),
            v.scratch_bytes,
            v.bvh_bytes,
            v.first_frame.as_secs_f64(),
            v.frame.as_secs_f64(),
            v.differing_pixels
        ));
    }
    s.push_str("\n| obvhs's own build of one CWBVH over the same boxes (boxes given) | build s | M boxes/s |\n|---|---|---|\n");
    for r in &c.raw {
        let secs = r.build.as_secs_f64();
        s.push_str(&format!(
            "| {} | {secs:.3} | {:.2} |\n",
            r.preset,
            active as f64 / secs / 1e6
        ));
    }
    s
}
