//! A neighbourhood whose cells are all leaf cells of its own level, coded for one isovalue
//! straight from the bricks.
//!
//! Most of a large leaf's neighbourhoods lie away from level and domain boundaries: every cell
//! is a [`LEAF`](super::local::LEAF) cell and [`Neighbourhood::classify`] codes each from its
//! value alone. Their codes are then written as the bricks' rows are read, without the kinds,
//! bounds and pending flags a [`Neighbourhood`] keeps (and without its classification pass):
//! the same codes, one byte written per cell instead of about sixteen. A neighbourhood with any
//! other cell is left to [`Neighbourhood::fill`].
//!
//! [`Neighbourhood`]: super::local::Neighbourhood
//! [`Neighbourhood::classify`]: super::local::Neighbourhood::classify
//! [`Neighbourhood::fill`]: super::local::Neighbourhood::fill

use crate::error::Result;
use amr_format::IBox;

use super::blocks::level_box;
use super::leaf_tree::LeafTree;
use super::local::{code, ABOVE, BELOW};
use crate::reconstruct::Sampler;

/// Per-thread scratch: the codes of the last plain neighbourhood.
#[derive(Default)]
pub struct PlainCodes {
    /// The cells coded: a level box, x fastest.
    pub cells: IBox,
    codes: Vec<u8>,
    touching: Vec<u32>,
    /// The brick and level box of each leaf of `touching` with cells in `cells`.
    blocks: Vec<(u32, IBox)>,
}

impl PlainCodes {
    /// Codes the level-`level` cells of box `g` for `iso` when every one is a leaf cell of
    /// `level` inside the domain, as [`Neighbourhood::classify`] of the same box would; false,
    /// with the codes meaning nothing, when some cell is not (coarser, refined, outside the
    /// domain or uncovered).
    ///
    /// [`Neighbourhood::classify`]: super::local::Neighbourhood::classify
    pub fn code<D: AsRef<[u8]>>(
        &mut self,
        (sampler, leaves): (&Sampler<'_, D>, &LeafTree),
        level: u32,
        g: IBox,
        iso: f32,
    ) -> Result<bool> {
        let grid = sampler.grid();
        if !grid.domain(level).contains_box(&g) {
            return Ok(false);
        }
        let (s, o) = (grid.scale(level), grid.offset());
        let region = IBox::new(
            [0, 1, 2].map(|a| g.lo[a] * s[a] - o[a]),
            [0, 1, 2].map(|a| g.hi[a] * s[a] - o[a]),
        );
        self.touching.clear();
        leaves.for_each_leaf_overlapping(&region, |l| self.touching.push(l));
        let same_level = |&l: &u32| sampler.leaf_top(l).is_some_and(|(_, lv)| lv == level);
        if !self.touching.iter().all(same_level) {
            return Ok(false);
        }
        let n = g.num_cells().unwrap_or(0) as usize;
        self.cells = g;
        // The leaves' level boxes inside `g` cover it when they hold its cells between them
        // without overlapping: each aligned to level cells (disjoint finest boxes, so disjoint
        // blocks) and inside its brick.
        // Not cleared first: when the blocks below cover `g` (they are disjoint), every code is
        // written, and otherwise the codes mean nothing.
        self.codes.resize(n, 0);
        let at_level = |f: &IBox| level_box(grid, level, f);
        let mut covered = 0u64;
        self.blocks.clear();
        for &l in &self.touching {
            let Some((brick, _)) = sampler.leaf_top(l) else {
                return Ok(false);
            };
            // `region` is whole level cells, so this is the leaf's level box clipped to `g`.
            let part = leaves.leaf_box(l).intersect(&region);
            let block = at_level(&part);
            let aligned = (0..3).all(|a| {
                block.lo[a] * s[a] - o[a] == part.lo[a] && block.hi[a] * s[a] - o[a] == part.hi[a]
            });
            let bc = sampler.brick_cells(brick);
            if !aligned || !bc.contains_box(&block) {
                return Ok(false);
            }
            let Some(cells) = block.num_cells() else {
                return Ok(false);
            };
            covered = covered.saturating_add(cells);
            if cells == 0 {
                continue;
            }
            if let Some(values) = sampler.values_in_place(brick) {
                prefetch_rows(values, &bc, &block);
            }
            self.blocks.push((brick, block));
        }
        if covered != n as u64 {
            return Ok(false);
        }
        for &(brick, block) in &self.blocks {
            let slab = sampler.values(brick)?;
            let values: &[f32] = &slab;
            let bc = sampler.brick_cells(brick);
            let be = block.extent();
            let w = be[0] as usize;
            let (ge, ce) = (g.extent(), bc.extent());
            let (dy, sy) = (ge[0] as usize, ce[0] as usize);
            let (dz, sz) = (dy * ge[1] as usize, sy * ce[1] as usize);
            let (mut d0, mut s0) = (g.linear_index(block.lo), bc.linear_index(block.lo));
            for _ in 0..be[2] {
                let (mut d, mut src) = (d0, s0);
                for _ in 0..be[1] {
                    let (Some(to), Some(from)) =
                        (self.codes.get_mut(d..d + w), values.get(src..src + w))
                    else {
                        return Ok(false);
                    };
                    code_row(to, from, iso);
                    d += dy;
                    src += sy;
                }
                d0 += dz;
                s0 += sz;
            }
        }
        Ok(true)
    }

    /// The codes of the last [`Self::code`] that returned true.
    #[inline]
    pub fn codes(&self) -> &[u8] {
        &self.codes
    }
}

/// Asks the caches for the rows of `block` (cells inside `brick`, the box of `values`), the
/// first and last value of each, before they are read: a block's rows lie in as many cache lines
/// and, one layer to a page, pages as it has rows and layers, which the hardware prefetchers
/// (within a page, one stride at a time) do not fetch ahead, so that each row would otherwise
/// wait for memory in turn. A hint: nothing where the target has none.
#[inline]
fn prefetch_rows(values: &[f32], brick: &IBox, block: &IBox) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let (be, ce) = (block.extent(), brick.extent());
        let (w, ny, nz) = (be[0] as usize, be[1] as usize, be[2] as usize);
        let (sy, sz) = (ce[0] as usize, ce[0].saturating_mul(ce[1]) as usize);
        let first = brick.linear_index(block.lo);
        // The rows start at increasing offsets: when the last one ends inside `values`, all do.
        let end = (nz.saturating_sub(1).saturating_mul(sz))
            .saturating_add(ny.saturating_sub(1).saturating_mul(sy))
            .saturating_add(w)
            .saturating_add(first);
        if w == 0 || ny == 0 || nz == 0 || end > values.len() {
            return;
        }
        let mut layer = values[first..].as_ptr();
        for _ in 0..nz {
            let mut row = layer;
            for _ in 0..ny {
                // SAFETY: SSE is part of every x86-64 target; a prefetch reads nothing
                // architecturally and never faults, and both addresses lie inside `values`
                // (checked above for the last row).
                unsafe {
                    _mm_prefetch::<_MM_HINT_T0>(row.cast());
                    _mm_prefetch::<_MM_HINT_T0>(row.wrapping_add(w - 1).cast());
                }
                row = row.wrapping_add(sy);
            }
            layer = layer.wrapping_add(sz);
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (values, brick, block);
}

/// Writes the code of each value of `src` for `iso` to `dst` (as long): eight at a time by
/// vector compares where the target has them (rows are a few tens of cells, too short for the
/// compiler's own vector loop), a row's last values as the eight that end it (recoding a few,
/// to the same codes) rather than one by one, and the values of rows shorter than eight one by
/// one.
#[inline]
fn code_row(dst: &mut [u8], src: &[f32], iso: f32) {
    let n = dst.len().min(src.len());
    let done = code_eights(&mut dst[..n], &src[..n], iso);
    if done == n || (n >= 8 && code_eights(&mut dst[n - 8..n], &src[n - 8..n], iso) == 8) {
        return;
    }
    for (c, &v) in dst[done..n].iter_mut().zip(&src[done..n]) {
        *c = code(v, v, iso);
    }
}

/// Codes the leading multiple of eight values of `src` into `dst` (of the same length);
/// returns how many.
#[cfg(target_arch = "x86_64")]
#[inline]
fn code_eights(dst: &mut [u8], src: &[f32], iso: f32) -> usize {
    use std::arch::x86_64::*;
    let n = dst.len().min(src.len()) / 8 * 8;
    // SAFETY: SSE2 is part of every x86-64 target. Each step reads eight `f32`s at `src[k..]`
    // and writes eight bytes at `dst[k..]` with `k + 8 <= n`, inside both slices; the loads
    // and the store are unaligned ones.
    unsafe {
        let iso4 = _mm_set1_ps(iso);
        let (above, below) = (_mm_set1_epi8(ABOVE as i8), _mm_set1_epi8(BELOW as i8));
        let mut k = 0;
        while k < n {
            let a = _mm_loadu_ps(src.as_ptr().add(k));
            let b = _mm_loadu_ps(src.as_ptr().add(k + 4));
            // All ones where `v >= iso` (false for NaN), and where `v < iso`.
            let ge = _mm_packs_epi32(
                _mm_castps_si128(_mm_cmpge_ps(a, iso4)),
                _mm_castps_si128(_mm_cmpge_ps(b, iso4)),
            );
            let lt = _mm_packs_epi32(
                _mm_castps_si128(_mm_cmplt_ps(a, iso4)),
                _mm_castps_si128(_mm_cmplt_ps(b, iso4)),
            );
            let bytes = _mm_or_si128(
                _mm_and_si128(_mm_packs_epi16(ge, ge), above),
                _mm_and_si128(_mm_packs_epi16(lt, lt), below),
            );
            _mm_storel_epi64(dst.as_mut_ptr().add(k).cast(), bytes);
            k += 8;
        }
    }
    n
}

/// Codes the leading multiple of eight values of `src` into `dst`: none on this target, whose
/// values [`code_row`] codes one by one.
#[cfg(not(target_arch = "x86_64"))]
#[inline]
fn code_eights(_: &mut [u8], _: &[f32], _: f32) -> usize {
    0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The vector coding gives [`code`] of every value, at every row length and offset.
    #[test]
    fn code_row_equals_code_of_each_value() {
        let iso = 10.0f32;
        let pick = [
            iso,
            iso.next_down(),
            iso.next_up(),
            -iso,
            0.0,
            -0.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            1e30,
            -1e-30,
        ];
        let values: Vec<f32> = (0..97)
            .map(|i| pick[(i * 7 + i / 5) % pick.len()])
            .collect();
        for start in 0..3 {
            for len in 0..40 {
                let src = &values[start..start + len];
                let mut dst = vec![0xff; len];
                code_row(&mut dst, src, iso);
                let want: Vec<u8> = src.iter().map(|&v| code(v, v, iso)).collect();
                assert_eq!(dst, want, "start {start}, length {len}");
            }
        }
    }
}
