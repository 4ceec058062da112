//! The paper's Figure 8: a two-level grid of cells valued 0 and 1 and the isocontours 0.25, 0.5
//! and 0.75 of the `nearest`, `current`, `finest` and `octant` reconstructions, side by side.
//!
//! The grid is a real `.amrk` file one coarse cell thick in z (values constant in z); the real
//! [`Sampler`] is evaluated at pixel centres in the mid-plane and the contours are drawn by
//! marching squares on that pixel grid, over colour bands of the same values.

use std::fmt::Write as _;
use std::path::Path;

use amr_format::{AmrkWriter, BrickSpec, HierarchySpec, IBox, LevelSpec, WriterOptions};
use amr_render::mapping::open_mapped;
use amr_render::reconstruct::Sampler;
use amr_render::Reconstruction;
use anyhow::anyhow;
use plotters::prelude::*;

use super::plot::fonts;
use super::{img_link, Ctx};

/// Coarse cells per axis.
const N0: i64 = 6;
/// The refined box, in fine cells (x, y).
const FINE: ([i64; 2], [i64; 2]) = ([4, 2], [10, 8]);
/// Coarse values, row `y = 5` first (as drawn).
const COARSE: [[u8; 6]; 6] = [
    [0, 0, 0, 0, 0, 0],
    [0, 1, 1, 0, 0, 0],
    [0, 1, 1, 1, 1, 0],
    [0, 0, 1, 1, 1, 0],
    [0, 0, 0, 1, 0, 0],
    [0, 0, 0, 0, 0, 0],
];
/// Pixels per panel side.
const PANEL: u32 = 420;
/// The isovalues drawn.
const ISOS: [f32; 3] = [0.25, 0.5, 0.75];

fn coarse_value(i: i64, j: i64) -> f32 {
    f32::from(COARSE[(N0 - 1 - j) as usize][i as usize])
}

/// Fine cells take the value of a disk that does not follow the coarse pattern, so the level
/// boundary carries jumps of both signs.
fn fine_value(i: i64, j: i64) -> f32 {
    let (x, y) = (i as f64 + 0.5 - 7.0, j as f64 + 0.5 - 5.2);
    if x * x + 0.6 * y * y < 2.6 * 2.6 {
        1.0
    } else {
        0.0
    }
}

fn write_grid(path: &Path) -> anyhow::Result<()> {
    let levels = vec![
        LevelSpec {
            cell_size: [1.0; 3],
            origin: [0.0; 3],
            ratio_to_next: [2; 3],
            domain: IBox::new([0; 3], [N0, N0, 1]),
        },
        LevelSpec {
            cell_size: [0.5; 3],
            origin: [0.0; 3],
            ratio_to_next: [1; 3],
            domain: IBox::new([0; 3], [2 * N0, 2 * N0, 2]),
        },
    ];
    let fine = IBox::new([FINE.0[0], FINE.0[1], 0], [FINE.1[0], FINE.1[1], 2]);
    let spec = HierarchySpec {
        levels,
        fields: vec!["f".into()],
        bricks: vec![
            BrickSpec {
                level: 0,
                cells: IBox::new([0; 3], [N0, N0, 1]),
            },
            BrickSpec {
                level: 1,
                cells: fine,
            },
        ],
    };
    let mut w = AmrkWriter::create(path, spec, WriterOptions::default())?;
    let mut v0 = Vec::new();
    for j in 0..N0 {
        for i in 0..N0 {
            v0.push(coarse_value(i, j));
        }
    }
    let mut v1 = Vec::new();
    for _k in 0..2 {
        for j in FINE.0[1]..FINE.1[1] {
            for i in FINE.0[0]..FINE.1[0] {
                v1.push(fine_value(i, j));
            }
        }
    }
    w.write_brick(0, 0, &v0)?;
    w.write_brick(1, 0, &v1)?;
    w.finish()?;
    Ok(())
}

fn in_fine(i: i64, j: i64) -> bool {
    i >= FINE.0[0] && i < FINE.1[0] && j >= FINE.0[1] && j < FINE.1[1]
}

/// Draws the figure to `img/figure8.png` and returns its section.
pub fn run(ctx: &Ctx) -> anyhow::Result<String> {
    let path = ctx.scratch.join("figure8.amrk");
    write_grid(&path)?;
    let file = open_mapped(&path)?;
    let sampler = Sampler::new(&file, 0, 16 << 20)?;
    let png = ctx.img.join("figure8.png");
    draw(&png, &sampler)?;
    let mut s = String::new();
    writeln!(s, "## Figure 8: isocontours of the four reconstructions\n")?;
    s.push_str(&ctx.provenance());
    writeln!(
        s,
        "\nA {N0}x{N0} coarse grid with a 6x6 refined patch (ratio 2), cells valued 0 (open dots) \
         and 1 (filled dots); contours at 0.25, 0.5 and 0.75 of the real sampler, evaluated at \
         {PANEL}x{PANEL} pixel centres per panel in the mid-plane of a one-cell-thick 3D file and \
         traced by marching squares. `nearest` is piecewise constant (its contours sit on cell \
         faces), `current` and `finest` break at the level boundary, `octant` is continuous.\n"
    )?;
    writeln!(s, "![Figure 8]({})\n", img_link(ctx, "figure8.png"))?;
    Ok(s)
}

fn band_colour(v: f32) -> RGBColor {
    let t = f64::from(v.clamp(0.0, 1.0));
    let lerp = |a: f64, b: f64| (a + (b - a) * t).round() as u8;
    RGBColor(lerp(250.0, 160.0), lerp(250.0, 200.0), lerp(245.0, 240.0))
}

fn draw<D: AsRef<[u8]>>(png: &Path, sampler: &Sampler<'_, D>) -> anyhow::Result<()> {
    fonts();
    let title_h = 40u32;
    let gap = 16u32;
    let w = 4 * PANEL + 5 * gap;
    let h = PANEL + title_h + 2 * gap + 24;
    let root = BitMapBackend::new(png, (w, h)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let extent = 2.0 * (2 * N0) as f64; // doubled finest units across the domain
    let px_per = PANEL as f64 / extent;
    let iso_colours = [
        RGBColor(0, 90, 200),
        RGBColor(200, 0, 0),
        RGBColor(0, 140, 0),
    ];
    for (k, method) in Reconstruction::ALL.into_iter().enumerate() {
        let ox = (gap + k as u32 * (PANEL + gap)) as i32;
        let oy = (title_h + gap) as i32;
        root.draw(&Text::new(
            method.name(),
            (ox + PANEL as i32 / 2 - 30, 12),
            ("sans-serif", 24).into_font(),
        ))
        .map_err(|e| anyhow!("{e}"))?;
        // Values at pixel centres; y up in the data, down in the image.
        let n = PANEL as usize;
        let mut vals = vec![f32::NAN; n * n];
        for py in 0..n {
            for px in 0..n {
                let x = (px as f64 + 0.5) / px_per;
                let y = extent - (py as f64 + 0.5) / px_per;
                let v = sampler.sample([x, y, 2.0], method)?;
                vals[py * n + px] = v.unwrap_or(f32::NAN);
            }
        }
        for py in 0..n {
            for px in 0..n {
                let v = vals[py * n + px];
                let c = if v.is_nan() {
                    RGBColor(255, 0, 255)
                } else {
                    band_colour(v)
                };
                root.draw_pixel((ox + px as i32, oy + py as i32), &c)
                    .map_err(|e| anyhow!("{e}"))?;
            }
        }
        // Cell grid: coarse cells outside the patch, fine cells inside.
        let to_px = |x: f64, y: f64| -> (i32, i32) {
            (
                ox + (x * px_per).round() as i32,
                oy + ((extent - y) * px_per).round() as i32,
            )
        };
        let grey = RGBColor(120, 120, 120);
        for j in 0..N0 {
            for i in 0..N0 {
                let (x0, y0) = (4.0 * i as f64, 4.0 * j as f64);
                let r = [to_px(x0, y0 + 4.0), to_px(x0 + 4.0, y0)];
                root.draw(&Rectangle::new(r, grey.stroke_width(1)))
                    .map_err(|e| anyhow!("{e}"))?;
            }
        }
        for j in FINE.0[1]..FINE.1[1] {
            for i in FINE.0[0]..FINE.1[0] {
                let (x0, y0) = (2.0 * i as f64, 2.0 * j as f64);
                let r = [to_px(x0, y0 + 2.0), to_px(x0 + 2.0, y0)];
                root.draw(&Rectangle::new(r, grey.stroke_width(1)))
                    .map_err(|e| anyhow!("{e}"))?;
            }
        }
        // Contours by marching squares between pixel centres.
        for (c, &iso) in ISOS.iter().enumerate() {
            let style = iso_colours[c].stroke_width(2);
            for py in 0..n - 1 {
                for px in 0..n - 1 {
                    let v = [
                        vals[py * n + px],
                        vals[py * n + px + 1],
                        vals[(py + 1) * n + px + 1],
                        vals[(py + 1) * n + px],
                    ];
                    for seg in march(v, iso) {
                        let p = seg.map(|(u, t)| {
                            (
                                ox + px as i32 + (u * 1.0).round() as i32,
                                oy + py as i32 + (t).round() as i32,
                            )
                        });
                        if p[0] != p[1] {
                            root.draw(&PathElement::new(vec![p[0], p[1]], style))
                                .map_err(|e| anyhow!("{e}"))?;
                        } else {
                            root.draw_pixel(p[0], &iso_colours[c])
                                .map_err(|e| anyhow!("{e}"))?;
                        }
                    }
                }
            }
        }
        // Cell-value dots at the leaf cells' centres.
        let dot = |x: f64, y: f64, v: f32, r: i32| -> anyhow::Result<()> {
            let p = to_px(x, y);
            if v > 0.5 {
                root.draw(&Circle::new(p, r, BLACK.filled()))
                    .map_err(|e| anyhow!("{e}"))?;
            } else {
                root.draw(&Circle::new(p, r, WHITE.filled()))
                    .map_err(|e| anyhow!("{e}"))?;
                root.draw(&Circle::new(p, r, BLACK.stroke_width(1)))
                    .map_err(|e| anyhow!("{e}"))?;
            }
            Ok(())
        };
        for j in 0..N0 {
            for i in 0..N0 {
                let covered = (0..2).all(|a| (0..2).all(|b| in_fine(2 * i + a, 2 * j + b)));
                if !covered {
                    dot(
                        4.0 * i as f64 + 2.0,
                        4.0 * j as f64 + 2.0,
                        coarse_value(i, j),
                        6,
                    )?;
                }
            }
        }
        for j in FINE.0[1]..FINE.1[1] {
            for i in FINE.0[0]..FINE.1[0] {
                dot(
                    2.0 * i as f64 + 1.0,
                    2.0 * j as f64 + 1.0,
                    fine_value(i, j),
                    4,
                )?;
            }
        }
    }
    let legend_y = (h - 14) as i32;
    for (c, iso) in ISOS.iter().enumerate() {
        let x = 20 + 140 * c as i32;
        root.draw(&PathElement::new(
            vec![(x, legend_y), (x + 24, legend_y)],
            iso_colours[c].stroke_width(3),
        ))
        .map_err(|e| anyhow!("{e}"))?;
        root.draw(&Text::new(
            format!("iso {iso}"),
            (x + 30, legend_y - 8),
            ("sans-serif", 15).into_font(),
        ))
        .map_err(|e| anyhow!("{e}"))?;
    }
    root.present().map_err(|e| anyhow!("{e}"))?;
    Ok(())
}

/// Marching squares on one cell with corners `v` (counter-clockwise from the upper left in image
/// space: (0,0), (1,0), (1,1), (0,1)); segments in cell-local pixel units.
fn march(v: [f32; 4], iso: f32) -> Vec<[(f64, f64); 2]> {
    if v.iter().any(|x| x.is_nan()) {
        return Vec::new();
    }
    let corners = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)];
    let mut pts = Vec::with_capacity(4);
    for e in 0..4 {
        let (a, b) = (e, (e + 1) % 4);
        let (fa, fb) = (v[a] - iso, v[b] - iso);
        if (fa < 0.0) != (fb < 0.0) {
            let t = f64::from(fa / (fa - fb));
            let (pa, pb) = (corners[a], corners[b]);
            pts.push((pa.0 + t * (pb.0 - pa.0), pa.1 + t * (pb.1 - pa.1)));
        }
    }
    match pts.len() {
        2 => vec![[pts[0], pts[1]]],
        4 => vec![[pts[0], pts[1]], [pts[2], pts[3]]],
        _ => Vec::new(),
    }
}
