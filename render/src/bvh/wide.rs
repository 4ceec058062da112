//! A compressed wide BVH (obvhs's CWBVH8 layout) built directly from boxes in Morton order.
//!
//! The boxes' centres are radix-sorted along a Morton curve. A node's run of sorted boxes is cut
//! where the highest bit in which the run's first and last codes differ flips (the cut a linear
//! BVH or an octree makes), the spatially largest run first, until the node has eight children or
//! no run of two boxes or more is left. Runs of at most three boxes become leaves, longer runs
//! child nodes. No binary BVH and no cost table are built: the build is a sort and one pass over
//! the boxes.

use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::CwBvh;

/// Most boxes in one leaf (the node format's limit).
const LEAF_MAX: usize = 3;

/// Node depth past which runs are cut at their middle, so that the depth stays far below
/// obvhs's traversal stack of 32 whatever the codes.
const MORTON_DEPTH: u32 = 20;

/// Build scratch: the sort keys, kept between builds, and a primitive index array handed back
/// after a build ([`WideBuilder::recycle`]), which the next build fills instead of fresh memory.
#[derive(Default)]
pub struct WideBuilder {
    keys: Vec<u64>,
    tmp: Vec<u64>,
    prims: Vec<u32>,
}

impl WideBuilder {
    /// A CWBVH over `boxes` ([`WideBuilder::build_coded`]), their centres' Morton codes taken
    /// on a grid of `2^21` steps per axis over the centres' bounds.
    pub fn build(&mut self, boxes: &[Aabb]) -> CwBvh {
        let mut codes = Vec::new();
        centre_codes(boxes, &mut codes);
        self.build_coded(boxes, &codes)
    }

    /// A CWBVH over `boxes`, which are sorted by `codes` (one Morton code per box, each axis's
    /// bits three apart, x highest); its `primitive_indices[i]` is the index in `boxes` of its
    /// primitive `i`. Only the bits in which the codes differ are sorted by (the lowest of them
    /// when they are more than the keys hold beside the box indices). The same boxes and codes
    /// always give the same BVH.
    pub fn build_coded(&mut self, boxes: &[Aabb], codes: &[u64]) -> CwBvh {
        let n = boxes.len();
        if n == 0 {
            return CwBvh::default();
        }
        assert!(n <= u32::MAX as usize, "{n} boxes in one BVH");
        assert_eq!(codes.len(), n, "one Morton code per box");
        let index_bits = (usize::BITS - (n - 1).leading_zeros()).max(1);
        self.sort(codes, index_bits);
        let index_mask = (1u64 << index_bits) - 1;
        let mut prims = std::mem::take(&mut self.prims);
        prims.clear();
        // A leaf writes three primitives before it drops those past its own.
        prims.reserve(n + 2);
        // The leaves read their boxes through the keys' indices: no copy of the boxes in
        // the keys' order.
        let mut b = Build {
            boxes,
            keys: &self.keys,
            shift: index_bits,
            index_mask,
            nodes: Vec::with_capacity(n / 4 + 1),
            prims,
        };
        b.nodes.push(CwBvhNode::default());
        let total = b.root(n);
        CwBvh {
            nodes: b.nodes,
            primitive_indices: b.prims,
            total_aabb: total,
            exact_node_aabbs: None,
            uses_spatial_splits: false,
        }
    }

    /// Takes back a built BVH's primitive index array once it has been read: the next build
    /// writes its primitives there. A chunked build's primitive arrays (a quarter megabyte
    /// each) would otherwise each be fresh pages of a new mapping.
    pub fn recycle(&mut self, prims: Vec<u32>) {
        self.prims = prims;
    }

    /// A buffer of the scratch that is free between builds (the radix sort's second buffer,
    /// as large as the last build's boxes), for the caller's own use.
    pub fn spare(&mut self) -> &mut Vec<u64> {
        &mut self.tmp
    }

    /// Bytes of scratch held.
    pub fn scratch_bytes(&self) -> usize {
        (self.keys.capacity() + self.tmp.capacity()) * 8 + self.prims.capacity() * 4
    }

    /// Fills `self.keys` with `code << index_bits | index`, sorted by code (then index), where
    /// `code` is the bits of `codes[index]` in which the codes differ, as many as fit above
    /// `index_bits` from the highest down.
    fn sort(&mut self, codes: &[u64], index_bits: u32) {
        let first = codes[0];
        let differ = codes.iter().fold(0, |d, &c| d | (c ^ first));
        let room = 64 - index_bits;
        let (shift, bits) = match differ {
            0 => (0, 0),
            d => {
                let (low, high) = (d.trailing_zeros(), 64 - d.leading_zeros());
                (low.max(high.saturating_sub(room)), (high - low).min(room))
            }
        };
        let mask = if bits == 0 {
            0
        } else {
            u64::MAX >> (64 - bits)
        };
        let mut counts = [[0u32; 256]; 8];
        let digits = bits.div_ceil(8) as usize;
        self.keys.clear();
        self.keys.extend(codes.iter().enumerate().map(|(i, &c)| {
            let code = c >> shift & mask;
            count_digits(&mut counts, code, digits);
            code << index_bits | i as u64
        }));
        self.tmp.resize(self.keys.len(), 0);
        radix_passes(&mut self.keys, &mut self.tmp, index_bits, &counts[..digits]);
    }
}

/// Writes to `codes` the Morton code of each box's centre on a grid of `2^21` steps per axis
/// over the centres' bounds.
pub fn centre_codes(boxes: &[Aabb], codes: &mut Vec<u64>) {
    let mut lo = Vec3A::splat(f32::INFINITY);
    let mut hi = Vec3A::splat(f32::NEG_INFINITY);
    for b in boxes {
        let c = b.min + b.max;
        lo = lo.min(c);
        hi = hi.max(c);
    }
    let steps = ((1u64 << 21) - 1) as f32;
    let scale = Vec3A::splat(steps) / (hi - lo).max(Vec3A::splat(f32::MIN_POSITIVE));
    // Whole numbers below 2^21 plus 2^23 keep themselves in their low mantissa bits (a NaN's
    // low bits are 0, what its conversion gave): no conversion to integers.
    let magic = Vec3A::splat(8_388_608.0);
    codes.clear();
    codes.extend(boxes.iter().map(|b| {
        let q = ((b.min + b.max - lo) * scale)
            .clamp(Vec3A::ZERO, Vec3A::splat(steps))
            .floor()
            + magic;
        morton([q.x.to_bits(), q.y.to_bits(), q.z.to_bits()])
    }));
}

/// The Morton code of grid step `q` (the low 21 bits of each axis): x's bits at `3 i + 2`, y's
/// at `3 i + 1`, z's at `3 i`.
#[inline(always)]
pub fn morton(q: [u32; 3]) -> u64 {
    spread(u64::from(q[0])) << 2 | spread(u64::from(q[1])) << 1 | spread(u64::from(q[2]))
}

/// [`morton`] by bit deposit, for a CPU with BMI2.
///
/// # Safety
/// The CPU must have BMI2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "bmi2")]
#[inline]
pub unsafe fn morton_bmi2(q: [u32; 3]) -> u64 {
    use std::arch::x86_64::_pdep_u64;
    const Z: u64 = 0x1249_2492_4924_9249;
    let d = |v: u32, mask: u64| _pdep_u64(u64::from(v), mask);
    d(q[0], Z << 2) | d(q[1], Z << 1) | d(q[2], Z)
}

/// Each 11-bit number's bits spread three apart (bit `i` to bit `3 i`): 8 KiB.
const SPREAD_11: [u32; 2048] = {
    let mut t = [0u32; 2048];
    let mut b = 0;
    while b < 2048 {
        let mut i = 0;
        while i < 11 {
            t[b] |= ((b as u32 >> i) & 1) << (3 * i);
            i += 1;
        }
        b += 1;
    }
    t
};

/// Spreads the low 21 bits of `v` three bits apart: two table look-ups.
#[inline(always)]
fn spread(v: u64) -> u64 {
    let x = v & 0x1f_ffff;
    u64::from(SPREAD_11[(x & 0x7ff) as usize]) | u64::from(SPREAD_11[(x >> 11) as usize]) << 33
}

/// Stable LSD radix sort of `keys` by their bits from `from` up, a byte at a time; bytes that
/// are the same in every key are skipped.
#[cfg(test)]
fn radix_sort(keys: &mut Vec<u64>, tmp: &mut Vec<u64>, from: u32) {
    let digits = (64 - from).div_ceil(8) as usize;
    let mut counts = [[0u32; 256]; 8];
    for &k in keys.iter() {
        count_digits(&mut counts, k >> from, digits);
    }
    radix_passes(keys, tmp, from, &counts[..digits]);
}

/// Counts each of the low `digits` bytes of `k` (a key shifted down to its sorted bits).
#[inline(always)]
fn count_digits(counts: &mut [[u32; 256]; 8], k: u64, digits: usize) {
    for (d, count) in counts[..digits].iter_mut().enumerate() {
        count[(k >> (8 * d) & 0xff) as usize] += 1;
    }
}

/// The passes of the radix sort of `keys` by their bytes from bit `from` up, given the counts
/// of each byte over all keys (taken before, as a permutation does not change them); a byte that
/// is the same in every key is skipped.
fn radix_passes(keys: &mut Vec<u64>, tmp: &mut Vec<u64>, from: u32, counts: &[[u32; 256]]) {
    for (d, count) in counts.iter().enumerate() {
        if count.iter().any(|&c| c as usize == keys.len()) {
            continue;
        }
        let shift = from + 8 * d as u32;
        let mut at = [0u32; 256];
        let mut sum = 0;
        for (a, &c) in at.iter_mut().zip(count) {
            *a = sum;
            sum += c;
        }
        // Slices, not the vectors: their pointers and lengths stay in registers.
        let (from, to) = (&keys[..], &mut tmp[..keys.len()]);
        for &k in from {
            let d = (k >> shift & 0xff) as usize;
            to[at[d] as usize] = k;
            at[d] += 1;
        }
        std::mem::swap(keys, tmp);
    }
}

/// One build: the sorted keys, the boxes, and the nodes and primitive order written so far.
struct Build<'a> {
    /// The boxes, box `k & index_mask` for key `k`.
    boxes: &'a [Aabb],
    keys: &'a [u64],
    shift: u32,
    index_mask: u64,
    nodes: Vec<CwBvhNode>,
    prims: Vec<u32>,
}

/// The runs `[a, b)` of sorted boxes that become one node's children, in the order they were
/// made (a cut run keeps its place for its first half; its second half comes last).
struct Runs {
    a: [usize; 8],
    b: [usize; 8],
    /// Which run to cut first, the largest: `rank << 3 | place`, with `rank` the highest
    /// differing code bit plus one (0: all codes equal) above the length, 0 for runs of one box
    /// and for unused places. The greatest key is the run to cut, the last of equal ranks.
    key: [u64; 8],
    len: usize,
}

impl Build<'_> {
    /// The rank of the run `[a, b)` (see [`Runs::key`]).
    #[inline(always)]
    fn rank(&self, a: usize, b: usize, depth: u32) -> u64 {
        let n = (b - a) as u64;
        if n < 2 {
            return 0;
        }
        let x = (self.keys[a] ^ self.keys[b - 1]) >> self.shift;
        let bit = if depth >= MORTON_DEPTH {
            0
        } else {
            64 - x.leading_zeros()
        };
        u64::from(bit) << 32 | n
    }

    /// Where the run `[a, b)` of rank `rank` is cut: at the first code with its highest
    /// differing bit set, or in the middle when the codes are equal.
    #[inline(always)]
    fn cut(&self, a: usize, b: usize, rank: u64) -> usize {
        match (rank >> 32) as u32 {
            0 => a + (b - a) / 2,
            bit => {
                let shift = self.shift + bit - 1;
                // The keys are sorted, so those with the bit clear come first.
                a + self.keys[a..b].partition_point(|&k| k >> shift & 1 == 0)
            }
        }
    }

    /// The runs of the node over `[a, b)`: the largest run cut (the last of equal ranks) until
    /// there are eight or no run of two boxes or more is left.
    #[inline(always)]
    fn runs(&self, a: usize, b: usize, depth: u32) -> Runs {
        let mut runs = Runs {
            a: [a; 8],
            b: [b; 8],
            key: [0, 1, 2, 3, 4, 5, 6, 7],
            len: 1,
        };
        runs.key[0] = self.rank(a, b, depth) << 3;
        while runs.len < 8 {
            // One maximum of eight keys, no branch per place.
            let best = runs.key.iter().fold(0, |m, &k| m.max(k));
            let (i, rank) = ((best & 7) as usize, best >> 3);
            if rank == 0 {
                break;
            }
            let (ra, rb) = (runs.a[i], runs.b[i]);
            let m = self.cut(ra, rb, rank);
            let n = runs.len;
            runs.b[i] = m;
            runs.key[i] = self.rank(ra, m, depth) << 3 | i as u64;
            runs.a[n] = m;
            runs.b[n] = rb;
            runs.key[n] = self.rank(m, rb, depth) << 3 | n as u64;
            runs.len += 1;
        }
        runs
    }

    /// Writes the tree over the `n` sorted boxes, its root at `self.nodes[0]`; returns its box.
    /// On a CPU with AVX2 and BMI2 the recursion is compiled for them (three-operand vector
    /// instructions, shifts without a count register): the same nodes, in fewer instructions.
    fn root(&mut self, n: usize) -> Aabb {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("bmi2")
        {
            // SAFETY: the CPU has AVX2 and BMI2, checked just above.
            return unsafe { self.node_v3(0, 0, n, 0) };
        }
        self.node_plain(0, 0, n, 0)
    }

    /// [`Build::node`] for a CPU with AVX2 and BMI2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,bmi2")]
    fn node_v3(&mut self, at: usize, a: usize, b: usize, depth: u32) -> Aabb {
        self.node::<true>(at, a, b, depth)
    }

    /// [`Build::node`] for any CPU.
    fn node_plain(&mut self, at: usize, a: usize, b: usize, depth: u32) -> Aabb {
        self.node::<false>(at, a, b, depth)
    }

    /// [`Build::node`] of a child, compiled as its parent (`V3`: for AVX2 and BMI2).
    #[inline(always)]
    fn child<const V3: bool>(&mut self, at: usize, a: usize, b: usize, depth: u32) -> Aabb {
        #[cfg(target_arch = "x86_64")]
        if V3 {
            // SAFETY: `V3` nodes run only where the CPU has AVX2 and BMI2 (`Build::root`).
            return unsafe { self.node_v3(at, a, b, depth) };
        }
        self.node_plain(at, a, b, depth)
    }

    /// Writes the node of the sorted boxes `[a, b)` at `self.nodes[at]` and its subtree after
    /// the nodes written so far; returns its box.
    #[inline(always)]
    fn node<const V3: bool>(&mut self, at: usize, a: usize, b: usize, depth: u32) -> Aabb {
        let runs = self.runs(a, b, depth);
        let len = runs.len;

        let prim_base = self.prims.len();
        // Copies: the slices' addresses and lengths stay in registers across the writes.
        let (boxes, keys, index_mask) = (self.boxes, self.keys, self.index_mask);
        let mut child_box = [Aabb::empty(); 8];
        let mut leaf_meta = [0u8; 8];
        let child_base = self.nodes.len();
        let mut inner_at = [0usize; 8];
        let mut inner = 0;
        for i in 0..len {
            let (ra, rb) = (runs.a[i], runs.b[i]);
            let n = rb - ra;
            if n <= LEAF_MAX {
                let first = self.prims.len();
                leaf_meta[i] = (first - prim_base) as u8 | [0, 0x20, 0x60, 0xe0][n];
                // The first, second and last boxes are all of a run of one to three (some
                // twice): no loop of one to three turns, whose count branches mispredict.
                let (second, last) = (ra + n / 2, rb - 1);
                let prim = |k: usize| (keys[k] & index_mask) as u32;
                let p = [prim(ra), prim(second), prim(last)];
                let b = |k: usize| &boxes[p[k] as usize];
                child_box[i] = b(0).union(b(1)).union(b(2));
                self.prims.extend_from_slice(&p);
                self.prims.truncate(first + n);
            } else {
                inner_at[i] = child_base + inner;
                inner += 1;
            }
        }
        self.nodes.resize(child_base + inner, CwBvhNode::default());
        for i in 0..len {
            if leaf_meta[i] == 0 {
                child_box[i] = self.child::<V3>(inner_at[i], runs.a[i], runs.b[i], depth + 1);
            }
        }

        let total = child_box[..len]
            .iter()
            .fold(Aabb::empty(), |t, c| t.union(c));
        let slots = order_children(&total, &child_box[..len]);
        let mut node = CwBvhNode {
            primitive_base_idx: prim_base as u32,
            child_base_idx: child_base as u32,
            ..Default::default()
        };
        let (p, e, rcp) = quantization(&total);
        node.p = Vec3::from(p);
        node.e = e;
        let mut slot_node = [usize::MAX; 8];
        let max = Vec3A::splat(255.0);
        // Whole numbers in `0..=255` plus 2^23 keep themselves in their low mantissa bits: the
        // low byte of the sum's bits is the plane, with no conversion (a NaN gives 0, as its
        // conversion did).
        let magic = Vec3A::splat(8_388_608.0);
        for (i, &s) in slots[..len].iter().enumerate() {
            let c = &child_box[i];
            let (lo, hi) = floor_ceil::<V3>((c.min - p) * rcp, (c.max - p) * rcp);
            let qlo = lo.clamp(Vec3A::ZERO, max) + magic;
            let qhi = hi.clamp(Vec3A::ZERO, max) + magic;
            node.child_min_x[s] = qlo.x.to_bits() as u8;
            node.child_min_y[s] = qlo.y.to_bits() as u8;
            node.child_min_z[s] = qlo.z.to_bits() as u8;
            node.child_max_x[s] = qhi.x.to_bits() as u8;
            node.child_max_y[s] = qhi.y.to_bits() as u8;
            node.child_max_z[s] = qhi.z.to_bits() as u8;
            if leaf_meta[i] != 0 {
                node.child_meta[s] = leaf_meta[i];
            } else {
                node.imask |= 1 << s;
                node.child_meta[s] = (24 + s as u8) | 0x20;
                slot_node[s] = inner_at[i];
            }
        }
        if inner > 1 {
            let mut moved = [CwBvhNode::default(); 8];
            let mut k = 0;
            for &n in slot_node.iter().filter(|&&n| n != usize::MAX) {
                moved[k] = self.nodes[n];
                k += 1;
            }
            self.nodes[child_base..child_base + k].copy_from_slice(&moved[..k]);
        }
        self.nodes[at] = node;
        total
    }
}

/// The origin, the per-axis exponents and the reciprocal of the step of a node's 8-bit child
/// planes over `total` (the step a power of two with 255 steps covering the box).
#[inline(always)]
fn quantization(total: &Aabb) -> (Vec3A, [u8; 3], Vec3A) {
    let p = total.min;
    let extent = (total.max - total.min).max(Vec3A::splat(1e-20));
    let mut e = [0u8; 3];
    let mut rcp = Vec3A::ZERO;
    for a in 0..3 {
        let mut step = pow2_at_least(extent[a] / 255.0);
        while p[a] + 255.0 * step < total.max[a] {
            step *= 2.0;
        }
        e[a] = (step.to_bits() >> 23) as u8;
        rcp[a] = 1.0 / step;
    }
    (p, e, rcp)
}

/// `lo.floor()` and `hi.ceil()`; for `V3` (compiled for AVX2, which includes SSE4.1) one
/// rounding instruction each instead of the SSE2 sequence of conversions and masks. The two
/// differ only in the sign of a zero result, which the planes' clamp to `0..=255` erases.
#[inline(always)]
fn floor_ceil<const V3: bool>(lo: Vec3A, hi: Vec3A) -> (Vec3A, Vec3A) {
    #[cfg(target_arch = "x86_64")]
    if V3 {
        // SAFETY: `V3` nodes run only where the CPU has AVX2 (`Build::root`), so SSE4.1.
        return unsafe { floor_ceil_sse41(lo, hi) };
    }
    (lo.floor(), hi.ceil())
}

/// [`floor_ceil`] by SSE4.1's rounding instructions.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse4.1")]
#[inline]
fn floor_ceil_sse41(lo: Vec3A, hi: Vec3A) -> (Vec3A, Vec3A) {
    use std::arch::x86_64::{_mm_ceil_ps, _mm_floor_ps};
    (
        Vec3A::from(_mm_floor_ps(lo.into())),
        Vec3A::from(_mm_ceil_ps(hi.into())),
    )
}

/// The least power of two at or above `x` (a positive normal `f32`).
fn pow2_at_least(x: f32) -> f32 {
    let bits = x.to_bits();
    let exp = (bits >> 23) + u32::from(bits & 0x7f_ffff != 0);
    f32::from_bits(exp << 23)
}

/// The direction signs of slot `s`'s rays: bit 2 of `s` x negative, bit 1 y, bit 0 z.
const SLOT_DIRECTION: [Vec3A; 8] = {
    let mut d = [Vec3A::ZERO; 8];
    let mut s = 0;
    while s < 8 {
        d[s] = Vec3A::new(
            if s & 4 != 0 { -1.0 } else { 1.0 },
            if s & 2 != 0 { -1.0 } else { 1.0 },
            if s & 1 != 0 { -1.0 } else { 1.0 },
        );
        s += 1;
    }
    d
};

/// The slot of each child: slot `s` is visited first by rays whose direction octant is `s`
/// (bit 2: x negative, bit 1: y, bit 0: z), so a child is placed in the slot of the direction it
/// lies furthest against (the cost `d . (centre of child - centre of node)` of Ylitie et al. and
/// obvhs): each slot goes to the cheapest child that wants it, and children left without one
/// take, in turn, their cheapest free slot.
#[inline(always)]
fn order_children(total: &Aabb, children: &[Aabb]) -> [usize; 8] {
    /// No child, or no slot.
    const NONE: usize = 8;
    let centre = total.center();
    let mut v = [Vec3A::ZERO; 8];
    for (c, b) in children.iter().enumerate() {
        v[c] = b.center() - centre;
    }
    let cost = |c: usize, s: usize| SLOT_DIRECTION[s].dot(v[c]);
    // The loops below choose by selects rather than branches: the choices are unpredictable.
    let mut owner = [NONE; 8];
    let mut owner_cost = [0.0f32; 8];
    for c in 0..children.len() {
        // The cheapest slot of child c is the octant it lies in, mirrored.
        let s = MIRRORED_OCTANT[v[c].cmpgt(Vec3A::ZERO).bitmask() as usize];
        let k = cost(c, s);
        let take = owner[s] == NONE || k < owner_cost[s];
        owner[s] = if take { c } else { owner[s] };
        owner_cost[s] = if take { k } else { owner_cost[s] };
    }
    // One place past the children, where slots without an owner write.
    let mut slot_of = [NONE; 9];
    for (s, &c) in owner.iter().enumerate() {
        slot_of[c] = s;
    }
    for c in 0..children.len() {
        if slot_of[c] != NONE {
            continue;
        }
        let (mut best_cost, mut best) = (f32::INFINITY, NONE);
        for (s, &o) in owner.iter().enumerate() {
            let k = cost(c, s);
            let better = o == NONE && (k < best_cost || best == NONE);
            best_cost = if better { k } else { best_cost };
            best = if better { s } else { best };
        }
        owner[best] = c;
        slot_of[c] = best;
    }
    let mut slots = [NONE; 8];
    slots.copy_from_slice(&slot_of[..8]);
    slots
}

/// The slot whose rays come from the octant of a bit mask `x | y << 1 | z << 2` of positive
/// components: the mirrored octant, in the slots' bit order (x in bit 2, z in bit 0).
const MIRRORED_OCTANT: [usize; 8] = [0, 4, 2, 6, 1, 5, 3, 7];

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn nodes_built_for_avx2_equal_plain_nodes() {
        if !(std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("bmi2"))
        {
            return;
        }
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 40) as f32 / (1u64 << 24) as f32
        };
        let boxes: Vec<Aabb> = (0..5000)
            .map(|_| {
                let lo = Vec3A::new(next(), next(), next()) * 100.0;
                Aabb::new(lo, lo + Vec3A::new(next(), next(), next()))
            })
            .collect();
        let mut codes = Vec::new();
        centre_codes(&boxes, &mut codes);
        let n = boxes.len();
        let index_bits = (usize::BITS - (n - 1).leading_zeros()).max(1);
        let mut w = WideBuilder::default();
        w.sort(&codes, index_bits);
        let index_mask = (1u64 << index_bits) - 1;
        let sorted: Vec<Aabb> = w
            .keys
            .iter()
            .map(|&k| boxes[(k & index_mask) as usize])
            .collect();
        let build = |v3: bool| {
            let mut b = Build {
                boxes: &sorted,
                keys: &w.keys,
                shift: index_bits,
                index_mask,
                nodes: vec![CwBvhNode::default()],
                prims: Vec::with_capacity(n + 2),
            };
            let total = if v3 {
                // SAFETY: the CPU has AVX2 and BMI2, checked above.
                unsafe { b.node_v3(0, 0, n, 0) }
            } else {
                b.node_plain(0, 0, n, 0)
            };
            (format!("{:?} {total:?}", b.nodes), b.prims)
        };
        let (plain, v3) = (build(false), build(true));
        assert!(plain.1.len() == n);
        assert_eq!(plain, v3);
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn morton_by_bit_deposit_equals_morton() {
        if !std::arch::is_x86_feature_detected!("bmi2") {
            return;
        }
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..10_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let q = [x as u32, (x >> 21) as u32, (x >> 42) as u32].map(|v| v & 0x1f_ffff);
            // SAFETY: the CPU has BMI2, checked above.
            assert_eq!(unsafe { morton_bmi2(q) }, morton(q), "{q:?}");
        }
        // SAFETY: as above.
        assert_eq!(
            unsafe { morton_bmi2([0x1f_ffff; 3]) },
            morton([0x1f_ffff; 3])
        );
    }

    /// The planes of the rounding instructions equal those of the SSE2 sequence, zeros'
    /// signs, NaNs, infinities and whole numbers past 2^23 included.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn rounding_by_sse41_gives_the_same_planes() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let max = Vec3A::splat(255.0);
        let values = [
            -0.0,
            0.0,
            -0.3,
            0.3,
            1.0,
            -1.0,
            254.5,
            255.0,
            255.5,
            1e9,
            -1e9,
            8_388_609.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            17.999_998,
            -17.000_002,
        ];
        for &a in &values {
            for &b in &values {
                let (lo, hi) = (Vec3A::new(a, b, a), Vec3A::new(b, a, -a));
                let (fast, plain) = (floor_ceil::<true>(lo, hi), floor_ceil::<false>(lo, hi));
                let q = |v: Vec3A| v.clamp(Vec3A::ZERO, max).to_array().map(f32::to_bits);
                assert_eq!(q(fast.0), q(plain.0), "floor {lo}");
                assert_eq!(q(fast.1), q(plain.1), "ceil {hi}");
            }
        }
    }

    #[test]
    fn powers_of_two() {
        assert_eq!(pow2_at_least(1.0), 1.0);
        assert_eq!(pow2_at_least(1.5), 2.0);
        assert_eq!(pow2_at_least(0.25), 0.25);
        assert_eq!(pow2_at_least(0.3), 0.5);
        assert_eq!(
            pow2_at_least(1e-20 / 255.0),
            (1e-20f32 / 255.0).log2().ceil().exp2()
        );
    }

    #[test]
    fn spread_interleaves() {
        assert_eq!(spread(0b11), 0b1001);
        assert_eq!(spread(0x1f_ffff).count_ones(), 21);
        // The table gives what the shifts and masks gave.
        let shifts = |v: u64| {
            let mut x = v & 0x1f_ffff;
            x = (x | x << 32) & 0x001f_0000_0000_ffff;
            x = (x | x << 16) & 0x001f_0000_ff00_00ff;
            x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
            x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
            (x | x << 2) & 0x1249_2492_4924_9249
        };
        for v in (0..1u64 << 21)
            .step_by(97)
            .chain([0x1f_ffff, 1 << 20, 0xff_ffff])
        {
            assert_eq!(spread(v), shifts(v), "{v:#x}");
        }
    }

    #[test]
    fn radix_sort_sorts_by_the_high_bits_stably() {
        let mut keys: Vec<u64> = (0..1000u64).map(|i| (i * 7919 % 613) << 10 | i).collect();
        let mut want = keys.clone();
        want.sort_by_key(|k| (k >> 10, k & 1023));
        let mut tmp = vec![0; keys.len()];
        radix_sort(&mut keys, &mut tmp, 10);
        assert_eq!(keys, want);
        // High bits in every byte, from a start that is not a multiple of 8.
        let mut keys: Vec<u64> = (0..5000u64)
            .map(|i| i.wrapping_mul(0x9e37_79b9_7f4a_7c15) & !0x1fff | i)
            .collect();
        let mut want = keys.clone();
        want.sort_by_key(|k| (k >> 13, k & 0x1fff));
        let mut tmp = vec![0; keys.len()];
        radix_sort(&mut keys, &mut tmp, 13);
        assert_eq!(keys, want);
    }

    fn grid(n: usize) -> Vec<Aabb> {
        (0..n)
            .map(|i| {
                let p = Vec3A::new((i % 17) as f32, (i / 17 % 13) as f32, (i / 221) as f32);
                Aabb::new(p, p + Vec3A::splat(1.0 + (i % 3) as f32))
            })
            .collect()
    }

    #[test]
    fn the_bvh_is_valid_and_holds_every_box_once() {
        for n in [1, 2, 3, 4, 5, 9, 24, 25, 100, 1000, 5000] {
            let boxes = grid(n);
            let bvh = WideBuilder::default().build(&boxes);
            let mut seen = bvh.primitive_indices.clone();
            seen.sort();
            assert_eq!(seen, (0..n as u32).collect::<Vec<_>>(), "{n} boxes");
            let r = bvh.validate(&boxes, false);
            assert!(r.max_depth < 16, "{n} boxes: depth {}", r.max_depth);
        }
    }

    #[test]
    fn equal_boxes_still_give_a_shallow_bvh() {
        let boxes = vec![Aabb::new(Vec3A::ZERO, Vec3A::ONE); 5000];
        let bvh = WideBuilder::default().build(&boxes);
        let r = bvh.validate(&boxes, false);
        assert!(r.max_depth < 10, "depth {}", r.max_depth);
    }
}

#[cfg(test)]
mod quality {
    use super::*;
    use obvhs::cwbvh::builder::build_cwbvh;
    use obvhs::BvhBuildParams;

    /// Node and leaf-primitive surface-area costs of `bvh` (relative to its root's area).
    fn sah(bvh: &CwBvh) -> (usize, f64, f64) {
        let root = f64::from(bvh.nodes[0].aabb().half_area());
        let (mut nodes, mut prims) = (0.0, 0.0);
        for n in &bvh.nodes {
            nodes += f64::from(n.aabb().half_area()) / root;
            for c in 0..8 {
                if n.is_leaf(c) && !n.is_child_empty(c) {
                    let (_, count) = n.child_primitives(c);
                    prims += f64::from(n.child_aabb(c).half_area()) / root * f64::from(count);
                }
            }
        }
        (bvh.nodes.len(), nodes, prims)
    }

    /// The octant boxes of the cells of a 160^3 grid that a sphere's shell crosses.
    fn shell() -> Vec<Aabb> {
        let mut boxes = Vec::new();
        let n = 160;
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let c = Vec3A::new(x as f32, y as f32, z as f32) + 0.5 - n as f32 / 2.0;
                    if (c.length() - 60.0).abs() < 0.9 {
                        for o in 0..8 {
                            let lo = c - 0.5
                                + 0.5
                                    * Vec3A::new(
                                        (o & 1) as f32,
                                        (o >> 1 & 1) as f32,
                                        (o >> 2) as f32,
                                    );
                            boxes.push(Aabb::new(lo, lo + 0.5));
                        }
                    }
                }
            }
        }
        boxes
    }

    #[test]
    #[ignore = "prints the surface-area costs of the Morton and PLOC builds"]
    fn surface_area_costs() {
        let boxes = shell();
        let ours = WideBuilder::default().build(&boxes);
        let mut t = std::time::Duration::ZERO;
        let ploc = build_cwbvh(&boxes, BvhBuildParams::fast_build(), &mut t);
        eprintln!("{} boxes", boxes.len());
        eprintln!("Morton (nodes, node cost, prim cost): {:?}", sah(&ours));
        eprintln!("PLOC   (nodes, node cost, prim cost): {:?}", sah(&ploc));
        for (name, b) in [("Morton", &ours), ("PLOC", &ploc)] {
            let mut hist = [[0usize; 9]; 3];
            for n in &b.nodes {
                let inner = n.imask.count_ones() as usize;
                let leaves = (0..8)
                    .filter(|&c| n.is_leaf(c) && !n.is_child_empty(c))
                    .count();
                let prims: u32 = (0..8)
                    .filter(|&c| n.is_leaf(c) && !n.is_child_empty(c))
                    .map(|c| n.child_primitives(c).1)
                    .sum();
                hist[0][inner] += 1;
                hist[1][leaves] += 1;
                hist[2][(prims as usize / 3).min(8)] += 1;
            }
            eprintln!("{name}: nodes by inner children {:?}", hist[0]);
            eprintln!("{name}: nodes by leaf children {:?}", hist[1]);
            eprintln!("{name}: nodes by leaf prims / 3 {:?}", hist[2]);
        }
    }
}
