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
    /// The cells coded: a level box, x fastest (the box asked for less its lowest layer on
    /// each axis, see [`PlainCodes::code`]).
    pub cells: IBox,
    codes: Vec<u8>,
    touching: Vec<u32>,
    /// The brick and level box of each leaf of `touching` with cells in `cells`.
    blocks: Vec<(u32, IBox)>,
}

impl PlainCodes {
    /// Codes the level-`level` cells of box `g` above its lowest layer on each axis (the box
    /// [`Self::cells`]) for `iso` when every cell of `g` is a leaf cell of `level` inside the
    /// domain, as [`Neighbourhood::classify`] of the same cells would; false, with the codes
    /// meaning nothing, when some cell of `g` is not (coarser, refined, outside the domain or
    /// uncovered).
    ///
    /// `g` is a leaf's (or part's) cells grown by one: when all are leaf cells, every voxel the
    /// leaf owns is a merged dual cell whose lowest cell is one of the leaf's, so the cells
    /// below the leaf are checked but never read, and their codes are not written.
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
        let n = g.num_cells().unwrap_or(0);
        let coded = IBox::new(g.lo.map(|x| x + 1), g.hi);
        self.cells = coded;
        // The leaves' level boxes inside `g` cover it when they hold its cells between them
        // without overlapping: each aligned to level cells (disjoint finest boxes, so disjoint
        // blocks) and inside its brick.
        // Not cleared first: when the blocks below cover `g` (they are disjoint), their parts
        // inside `coded` write every code, and otherwise the codes mean nothing.
        self.codes
            .resize(coded.num_cells().unwrap_or(0) as usize, 0);
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
            let block = block.intersect(&coded);
            if block.is_empty() {
                continue;
            }
            if let Some(values) = sampler.values_in_place(brick) {
                prefetch_rows(values, &bc, &block);
            }
            self.blocks.push((brick, block));
        }
        if covered != n {
            return Ok(false);
        }
        for &(brick, block) in &self.blocks {
            let slab = sampler.values(brick)?;
            let values: &[f32] = &slab;
            let bc = sampler.brick_cells(brick);
            let (be, ge, ce) = (block.extent(), coded.extent(), bc.extent());
            let rows = Rows {
                w: be[0] as usize,
                ny: be[1] as usize,
                nz: be[2] as usize,
                dy: ge[0] as usize,
                dz: (ge[0] * ge[1]) as usize,
                sy: ce[0] as usize,
                sz: (ce[0] * ce[1]) as usize,
            };
            let (d0, s0) = (coded.linear_index(block.lo), bc.linear_index(block.lo));
            let (Some(to), Some(from)) = (self.codes.get_mut(d0..), values.get(s0..)) else {
                return Ok(false);
            };
            if !code_rows(to, from, rows, iso) {
                return Ok(false);
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

/// The rows of one block, in the codes and in the brick's values: `ny` rows of `w` cells in
/// each of `nz` layers, rows `dy` codes (`sy` values) apart and layers `dz` codes (`sz` values)
/// apart.
#[derive(Clone, Copy, Debug)]
struct Rows {
    w: usize,
    ny: usize,
    nz: usize,
    dy: usize,
    dz: usize,
    sy: usize,
    sz: usize,
}

impl Rows {
    /// One past the last element the rows reach when the first row starts at 0 and rows are
    /// `dy` and layers `dz` apart; `None` on overflow or with no rows.
    fn span(&self, dy: usize, dz: usize) -> Option<usize> {
        if self.w == 0 || self.ny == 0 || self.nz == 0 {
            return None;
        }
        (self.nz - 1)
            .checked_mul(dz)?
            .checked_add((self.ny - 1).checked_mul(dy)?)?
            .checked_add(self.w)
    }
}

/// Writes the code for `iso` of each value of the rows `rows` of `src` to the same place in
/// the rows of `dst` (each slice starting at its first row); false, with nothing written, when
/// a row does not fit in either. A block's bounds are checked once, not row by row: rows of
/// eight values or more are coded eight at a time by vector compares where the target has them
/// (a row's last values as the eight that end it, recoding a few to the same codes), shorter
/// rows (a neighbourhood's one-cell faces) one value at a time.
#[inline]
fn code_rows(dst: &mut [u8], src: &[f32], rows: Rows, iso: f32) -> bool {
    let (Some(dn), Some(sn)) = (rows.span(rows.dy, rows.dz), rows.span(rows.sy, rows.sz)) else {
        return rows.w == 0 || rows.ny == 0 || rows.nz == 0;
    };
    if dn > dst.len() || sn > src.len() {
        return false;
    }
    #[cfg(target_arch = "x86_64")]
    if rows.w >= 8 {
        if std::arch::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU has AVX, checked just above.
            unsafe { code_rows_by_eight_avx(&mut dst[..dn], &src[..sn], rows, iso) };
        } else {
            code_rows_by_eight(&mut dst[..dn], &src[..sn], rows, iso);
        }
        return true;
    }
    let (dst, src) = (&mut dst[..dn], &src[..sn]);
    let (mut d0, mut s0) = (0, 0);
    if rows.w == 1 {
        // A one-cell face: one value per row, the rows' loop alone.
        for _ in 0..rows.nz {
            let (mut d, mut s) = (d0, s0);
            for _ in 0..rows.ny {
                let v = src[s];
                dst[d] = code(v, v, iso);
                d += rows.dy;
                s += rows.sy;
            }
            d0 += rows.dz;
            s0 += rows.sz;
        }
        return true;
    }
    for _ in 0..rows.nz {
        let (mut d, mut s) = (d0, s0);
        for _ in 0..rows.ny {
            for (c, &v) in dst[d..d + rows.w].iter_mut().zip(&src[s..s + rows.w]) {
                *c = code(v, v, iso);
            }
            d += rows.dy;
            s += rows.sy;
        }
        d0 += rows.dz;
        s0 += rows.sz;
    }
    true
}

/// Calls `eight(d, s)` for each eight values of the rows `rows` (at least eight long) to code:
/// those at `s` in the values, whose codes go to `d`; a row's last eight end it (and may
/// overlap the eight before).
#[inline(always)]
fn for_each_eight(rows: Rows, mut eight: impl FnMut(usize, usize)) {
    debug_assert!(rows.w >= 8);
    // The start of a row's last eight.
    let tail = rows.w - 8;
    let (mut d0, mut s0) = (0, 0);
    for _ in 0..rows.nz {
        let (mut d, mut s) = (d0, s0);
        for _ in 0..rows.ny {
            let mut k = 0;
            while k < tail {
                eight(d + k, s + k);
                k += 8;
            }
            eight(d + tail, s + tail);
            d += rows.dy;
            s += rows.sy;
        }
        d0 += rows.dz;
        s0 += rows.sz;
    }
}

/// [`code_rows`] of rows at least eight long, eight values at a time by SSE2 compares; `dst`
/// and `src` hold every row (their spans, checked by the caller).
#[cfg(target_arch = "x86_64")]
#[inline]
fn code_rows_by_eight(dst: &mut [u8], src: &[f32], rows: Rows, iso: f32) {
    use std::arch::x86_64::*;
    debug_assert!(rows.span(rows.dy, rows.dz).is_some_and(|n| n <= dst.len()));
    debug_assert!(rows.span(rows.sy, rows.sz).is_some_and(|n| n <= src.len()));
    let (to, from) = (dst.as_mut_ptr(), src.as_ptr());
    // SAFETY: SSE2 is part of every x86-64 target.
    let (iso4, above, below) = unsafe {
        (
            _mm_set1_ps(iso),
            _mm_set1_epi8(ABOVE as i8),
            _mm_set1_epi8(BELOW as i8),
        )
    };
    // SAFETY: as above; every row starts at `d` in `dst` and `s` in
    // `src` with `d + w` and `s + w` at most the rows' spans, which the caller checked against
    // the slices' lengths; each step reads eight `f32`s at `s + k` and writes eight bytes at
    // `d + k` with `k + 8 <= w` ([`for_each_eight`]), inside both slices. The loads and the
    // store are unaligned ones.
    for_each_eight(rows, |d, s| unsafe {
        let a = _mm_loadu_ps(from.add(s));
        let b = _mm_loadu_ps(from.add(s + 4));
        // All ones where `!(v < iso)`, and where `!(v >= iso)`: both for NaN, as `code`'s.
        let ge = _mm_packs_epi32(
            _mm_castps_si128(_mm_cmpnlt_ps(a, iso4)),
            _mm_castps_si128(_mm_cmpnlt_ps(b, iso4)),
        );
        let lt = _mm_packs_epi32(
            _mm_castps_si128(_mm_cmpnge_ps(a, iso4)),
            _mm_castps_si128(_mm_cmpnge_ps(b, iso4)),
        );
        let bytes = _mm_or_si128(
            _mm_and_si128(_mm_packs_epi16(ge, ge), above),
            _mm_and_si128(_mm_packs_epi16(lt, lt), below),
        );
        _mm_storel_epi64(to.add(d).cast(), bytes);
    });
}

/// The byte of bit `k` of the index is its byte `k` (0 or 1), little-endian.
#[cfg(target_arch = "x86_64")]
const SPREAD_BITS: [u64; 256] = {
    let mut t = [0u64; 256];
    let mut m = 0;
    while m < 256 {
        let mut k = 0;
        while k < 8 {
            t[m] |= ((m as u64 >> k) & 1) << (8 * k);
            k += 1;
        }
        m += 1;
    }
    t
};

/// [`code_rows_by_eight`] by 8-lane AVX compares: the eight results of each compare as a bit
/// mask, its bits spread to bytes by [`SPREAD_BITS`] (about half the instructions of the SSE2
/// packing).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
fn code_rows_by_eight_avx(dst: &mut [u8], src: &[f32], rows: Rows, iso: f32) {
    use std::arch::x86_64::*;
    debug_assert!(rows.span(rows.dy, rows.dz).is_some_and(|n| n <= dst.len()));
    debug_assert!(rows.span(rows.sy, rows.sz).is_some_and(|n| n <= src.len()));
    let (to, from) = (dst.as_mut_ptr(), src.as_ptr());
    let iso8 = _mm256_set1_ps(iso);
    // SAFETY: as in `code_rows_by_eight` (reads of eight `f32`s and writes of eight bytes
    // inside both slices, unaligned); AVX is enabled for this function.
    for_each_eight(rows, |d, s| unsafe {
        let v = _mm256_loadu_ps(from.add(s));
        // Unordered negated compares: true for NaN, as `code`'s.
        let ge = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_NLT_UQ>(v, iso8)) as usize;
        let lt = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_NGE_UQ>(v, iso8)) as usize;
        let bytes = (SPREAD_BITS[ge & 0xff] * u64::from(ABOVE))
            | (SPREAD_BITS[lt & 0xff] * u64::from(BELOW));
        to.add(d).cast::<u64>().write_unaligned(bytes.to_le());
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The block coding gives [`code`] of every value of every row and leaves the rest, at
    /// every row length (the scalar and the vector paths), row and layer count and gap, and
    /// refuses rows that do not fit.
    #[test]
    fn code_rows_equals_code_of_each_value() {
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
        let values: Vec<f32> = (0..4000)
            .map(|i| pick[(i * 7 + i / 5) % pick.len()])
            .collect();
        for w in 0..21 {
            for (ny, nz) in [(1, 1), (3, 1), (1, 2), (2, 3)] {
                let (dy, sy) = (w + 3, w + 1);
                let (dz, sz) = (dy * (ny + 1), sy * ny + 5);
                let rows = Rows {
                    w,
                    ny,
                    nz,
                    dy,
                    dz,
                    sy,
                    sz,
                };
                let n = dz * nz + 8;
                let mut dst = vec![0xffu8; n];
                assert!(code_rows(&mut dst, &values, rows, iso));
                let mut want = vec![0xffu8; n];
                for z in 0..nz {
                    for y in 0..ny {
                        for x in 0..w {
                            let v = values[z * sz + y * sy + x];
                            want[z * dz + y * dy + x] = code(v, v, iso);
                        }
                    }
                }
                assert_eq!(dst, want, "{rows:?}");
                #[cfg(target_arch = "x86_64")]
                if w >= 8 {
                    let mut sse2 = vec![0xffu8; n];
                    code_rows_by_eight(&mut sse2, &values, rows, iso);
                    assert_eq!(sse2, want, "SSE2, {rows:?}");
                }
                if w > 0 {
                    let short = rows.span(dy, dz).unwrap() - 1;
                    assert!(!code_rows(&mut dst[..short], &values, rows, iso));
                    let short = rows.span(sy, sz).unwrap() - 1;
                    assert!(!code_rows(&mut dst, &values[..short], rows, iso));
                }
            }
        }
    }
}
