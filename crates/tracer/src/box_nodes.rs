//! The CWBVH's nodes with their child boxes decoded to floats, for the single-ray traversals
//! (occlusion and closest hit) on CPUs with AVX2 and FMA.
//!
//! obvhs stores a node's eight child boxes as bytes relative to the node's origin and a
//! power-of-two scale per axis (Ylitie, Karras & Laine 2017): compact for a GPU, but a CPU
//! then spends about half of each node test turning the 48 bytes back into floats. Here every
//! node is decoded once, after the build, into six rows of eight f32 planes, each rounded
//! outward so that it holds the quantised box it came from, next to its children's node
//! indices or leaf ranges: the layout of Embree's eight-wide nodes (Wald, Woop, Benthin,
//! Johnson & Ernst 2014, "Embree: A Kernel Framework for Efficient CPU Ray Tracing"). A
//! child's entry and exit distances are then one fused multiply-add per plane,
//! `plane · (1/d) + (−o · (1/d))`, with the reciprocal and the offset computed once per ray.
//!
//! **Same answers.** A float box contains its quantised box, and the slab distances differ
//! from obvhs' by a few f32 roundings, far below the padding every primitive box carries
//! (`accel`'s `PAD_RELATIVE`, 2⁻¹⁷ of the group's extent): every child whose quantised box
//! the ray meets is still entered, and a few more may be at the rounding edge. The exact
//! triangle tests decide every hit, the closest hit's tie rule does not depend on the order
//! candidates come in, and an any-hit query only asks whether one exists: occlusion answers
//! and closest hits are bit for bit those of the CWBVH traversals (`tests/accel.rs`).
//!
//! **Cost.** 256 bytes a node (four cache lines, 64-byte aligned) against obvhs' 80, built in
//! one pass over the nodes. The traversals keep their stack in a fixed array; a tree too deep
//! for it (more than [`MAX_DEPTH`] levels) is not decoded, and its rays take the CWBVH
//! traversals.

use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::Ray;

/// Deepest tree the fixed traversal stacks hold: a node pushes at most eight children after
/// popping itself, so a walk never holds more than `1 + 7 · depth` entries.
pub const MAX_DEPTH: usize = 18;

/// Entries of the traversal stacks (`1 + 7 · MAX_DEPTH`, rounded up).
const STACK: usize = 128;

const _: () = assert!(7 * MAX_DEPTH < STACK);

/// One CWBVH node decoded: child planes as floats, child links as plain indices.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct BoxNode {
    /// `min x, max x, min y, max y, min z, max z` of the eight children, each rounded
    /// outward (an empty child: `+∞` and `−∞`, which no ray enters).
    planes: [[f32; 8]; 6],
    /// An inner child's node index; a leaf child's first primitive slot.
    child: [u32; 8],
    /// A leaf child's primitive count (at most three); 0 for inner and empty children.
    count: [u8; 8],
    /// Bit `i`: child `i` is an inner node.
    inner: u8,
}

/// The nodes of one CWBVH as [`BoxNode`]s, node `i` decoded from obvhs' node `i`; empty when
/// the CPU lacks AVX2 or FMA or the tree is deeper than [`MAX_DEPTH`].
#[derive(Clone, Debug, Default)]
pub struct BoxNodes(Vec<BoxNode>);

impl BoxNodes {
    /// Decodes `bvh`'s nodes, or nothing where the traversals over them would not run.
    #[must_use]
    pub fn of(bvh: &CwBvh) -> Self {
        if !usable() || depth(bvh) > MAX_DEPTH {
            return Self::default();
        }
        Self(bvh.nodes.iter().map(decode).collect())
    }

    /// Whether the traversals below run on these nodes (else the caller takes the CWBVH's).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Whether any leaf the ray reaches holds a hit: `leaf(first, count)` answers for the
    /// leaf of slots `first..first + count`, and the first `true` ends the walk. `None` when
    /// the nodes were not decoded (the caller walks the CWBVH instead).
    pub fn any<F: FnMut(usize, usize) -> bool>(&self, ray: &Ray, leaf: F) -> Option<bool> {
        if self.is_empty() {
            return None;
        }
        #[allow(unsafe_code)] // Non-empty nodes exist only where the CPU has AVX2 and FMA.
        unsafe {
            Some(avx2::any(&self.0, ray, leaf))
        }
    }

    /// Closest-hit traversal, nearest child first: `hit(slot)` tests a candidate and returns
    /// its ray-local distance (or `∞`), which shortens the ray; `touch(slot)` is told of a
    /// leaf's slots when the leaf is pushed (a prefetch). Returns whether it ran: `false` when
    /// the nodes were not decoded (the caller walks the CWBVH instead).
    pub fn closest<F: FnMut(usize) -> f32, T: Fn(usize)>(
        &self,
        ray: &Ray,
        hit: F,
        touch: T,
    ) -> bool {
        if self.is_empty() {
            return false;
        }
        #[allow(unsafe_code)] // Non-empty nodes exist only where the CPU has AVX2 and FMA.
        unsafe {
            avx2::closest(&self.0, ray, hit, touch);
        }
        true
    }
}

/// Whether this CPU runs the traversals (AVX2 and FMA).
fn usable() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Levels of inner nodes on the longest path from the root (1 for a root alone).
fn depth(bvh: &CwBvh) -> usize {
    if bvh.nodes.is_empty() {
        return 0;
    }
    let mut deepest = 0;
    let mut todo = vec![(0u32, 1usize)];
    while let Some((index, level)) = todo.pop() {
        deepest = deepest.max(level);
        let node = &bvh.nodes[index as usize];
        for c in 0..8 {
            if !node.is_child_empty(c) && !node.is_leaf(c) {
                todo.push((node.child_node_index(c), level + 1));
            }
        }
    }
    deepest
}

/// `x` rounded to an f32 at or below it (`down`), or at or above it.
fn round_outward(x: f64, down: bool) -> f32 {
    let r = x as f32;
    if down && f64::from(r) > x {
        r.next_down()
    } else if !down && f64::from(r) < x {
        r.next_up()
    } else {
        r
    }
}

/// `node` decoded: each plane `p + q · 2^e` (exact in f64: `q` has 8 bits, `p` 24) rounded
/// outward to f32.
fn decode(node: &CwBvhNode) -> BoxNode {
    let extent = node.compute_extent();
    let rows = [
        (&node.child_min_x, 0, true),
        (&node.child_max_x, 0, false),
        (&node.child_min_y, 1, true),
        (&node.child_max_y, 1, false),
        (&node.child_min_z, 2, true),
        (&node.child_max_z, 2, false),
    ];
    let mut out = BoxNode {
        planes: [[0.0; 8]; 6],
        child: [0; 8],
        count: [0; 8],
        inner: 0,
    };
    for c in 0..8 {
        let empty = node.is_child_empty(c);
        for (k, &(q, axis, down)) in rows.iter().enumerate() {
            out.planes[k][c] = match (empty, down) {
                (true, true) => f32::INFINITY,
                (true, false) => f32::NEG_INFINITY,
                (false, _) => round_outward(
                    f64::from(node.p[axis]) + f64::from(q[c]) * f64::from(extent[axis]),
                    down,
                ),
            };
        }
        if empty {
            continue;
        }
        if node.is_leaf(c) {
            let (first, count) = node.child_primitives(c);
            out.child[c] = first;
            out.count[c] = count as u8;
        } else {
            out.child[c] = node.child_node_index(c);
            out.inner |= 1 << c;
        }
    }
    out
}

/// `mask` with bit `p` moved to bit `p ^ o` (`o < 8`): three conditional swaps.
fn xor_permute(mask: u32, o: u32) -> u32 {
    let mut m = mask;
    if o & 1 != 0 {
        m = (m & 0x55) << 1 | (m & 0xaa) >> 1;
    }
    if o & 2 != 0 {
        m = (m & 0x33) << 2 | (m & 0xcc) >> 2;
    }
    if o & 4 != 0 {
        m = (m & 0x0f) << 4 | (m & 0xf0) >> 4;
    }
    m
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)] // Intrinsics and `#[target_feature]` functions, called only after detection.
mod avx2 {
    use super::{xor_permute, BoxNode, Ray, STACK};
    use crate::traverse::{octant_inverse, prefetch, Entry, NODE_TMIN};
    use std::arch::x86_64::{
        __m256, _mm256_cmp_ps, _mm256_fmadd_ps, _mm256_load_ps, _mm256_max_ps, _mm256_min_ps,
        _mm256_movemask_ps, _mm256_set1_ps, _mm256_storeu_ps, _CMP_LE_OQ,
    };
    use std::mem::MaybeUninit;

    /// A ray set up for the slab tests: per axis the rows of its near and far planes, and
    /// `1/d` and `−o/d` in every lane.
    struct Slabs {
        near: [usize; 3],
        far: [usize; 3],
        inv: [__m256; 3],
        offset: [__m256; 3],
        tmin: __m256,
    }

    impl Slabs {
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn new(ray: &Ray) -> Self {
            let (d, inv, o) = (ray.direction, ray.inv_direction, ray.origin);
            let rows = |k: usize, negative: bool| {
                if negative {
                    (2 * k + 1, 2 * k)
                } else {
                    (2 * k, 2 * k + 1)
                }
            };
            let (x, y, z) = (rows(0, d.x < 0.0), rows(1, d.y < 0.0), rows(2, d.z < 0.0));
            Self {
                near: [x.0, y.0, z.0],
                far: [x.1, y.1, z.1],
                inv: [
                    _mm256_set1_ps(inv.x),
                    _mm256_set1_ps(inv.y),
                    _mm256_set1_ps(inv.z),
                ],
                offset: [
                    _mm256_set1_ps(-o.x * inv.x),
                    _mm256_set1_ps(-o.y * inv.y),
                    _mm256_set1_ps(-o.z * inv.z),
                ],
                tmin: _mm256_set1_ps(NODE_TMIN),
            }
        }

        /// Entry and exit distances of the eight children, the entry clamped below by obvhs'
        /// node `tmin` and the exit above by `tmax` (a NaN from `0 · ∞` is dropped by the
        /// `max`/`min` order, which keeps the child: conservative).
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn test(&self, node: &BoxNode, tmax: f32) -> (__m256, __m256) {
            let t = |row: usize, k: usize| {
                // SAFETY: `BoxNode` is 64-byte aligned and each row is 32 bytes at a multiple
                // of 32.
                let plane = unsafe { _mm256_load_ps(node.planes[row].as_ptr()) };
                _mm256_fmadd_ps(plane, self.inv[k], self.offset[k])
            };
            let entry = _mm256_max_ps(
                t(self.near[0], 0),
                _mm256_max_ps(
                    t(self.near[1], 1),
                    _mm256_max_ps(t(self.near[2], 2), self.tmin),
                ),
            );
            let exit = _mm256_min_ps(
                t(self.far[0], 0),
                _mm256_min_ps(
                    t(self.far[1], 1),
                    _mm256_min_ps(t(self.far[2], 2), _mm256_set1_ps(tmax)),
                ),
            );
            (entry, exit)
        }

        /// The children (bit `i`: child `i`) the ray enters before `tmax`.
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn accepted(&self, node: &BoxNode, tmax: f32) -> u32 {
            let (entry, exit) = self.test(node, tmax);
            _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(entry, exit)) as u32
        }
    }

    /// [`super::BoxNodes::any`].
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA; `nodes` must hold the whole tree (no deeper than
    /// [`super::MAX_DEPTH`]).
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn any<F: FnMut(usize, usize) -> bool>(
        nodes: &[BoxNode],
        ray: &Ray,
        mut leaf: F,
    ) -> bool {
        let slabs = Slabs::new(ray);
        let order = octant_inverse(ray.direction) as u32;
        let mut stack = [MaybeUninit::<u32>::uninit(); STACK];
        stack[0].write(0);
        let mut len = 1;
        while len > 0 {
            len -= 1;
            // SAFETY: slots below `len` were written; the depth bound keeps `len` in range.
            let node = &nodes[unsafe { stack[len].assume_init() } as usize];
            let accepted = slabs.accepted(node, ray.tmax);
            let inner = u32::from(node.inner);
            let mut leaves = accepted & !inner;
            while leaves != 0 {
                let c = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                if node.count[c] != 0 && leaf(node.child[c] as usize, usize::from(node.count[c])) {
                    return true;
                }
            }
            // The farthest by octant pushed first, so the nearest comes off next.
            let mut going = xor_permute(accepted & inner, order);
            while going != 0 {
                let c = (going.trailing_zeros() ^ order) as usize;
                going &= going - 1;
                stack[len].write(node.child[c]);
                len += 1;
            }
        }
        false
    }

    /// [`super::BoxNodes::closest`].
    ///
    /// # Safety
    /// As [`any`].
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn closest<F: FnMut(usize) -> f32, T: Fn(usize)>(
        nodes: &[BoxNode],
        ray: &Ray,
        mut hit: F,
        touch: T,
    ) {
        let slabs = Slabs::new(ray);
        let mut tmax = ray.tmax;
        let mut stack = [MaybeUninit::<Entry>::uninit(); STACK];
        // The root is entered unconditionally, as in obvhs.
        stack[0].write(Entry { t: 0.0, what: 0 });
        let mut len = 1;
        while len > 0 {
            len -= 1;
            // SAFETY: slots below `len` were written; the depth bound keeps `len` in range.
            let e = unsafe { stack[len].assume_init() };
            if e.t > tmax {
                continue;
            }
            if let Some((first, count)) = e.slots() {
                for slot in first..first + count {
                    tmax = tmax.min(hit(slot));
                }
                continue;
            }
            let node = &nodes[e.what as usize];
            let (entry, exit) = slabs.test(node, tmax);
            let mut mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(entry, exit)) as u32;
            let mut t = [0.0f32; 8];
            _mm256_storeu_ps(t.as_mut_ptr(), entry);
            // The accepted children, farthest first, so the nearest comes off the stack next.
            let base = len;
            while mask != 0 {
                let c = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let inner = node.inner & (1 << c) != 0;
                if !inner && node.count[c] == 0 {
                    continue;
                }
                // A node's accepted children are fetched together (all four lines of each)
                // instead of one after another as they come off the stack.
                let entry = if inner {
                    prefetch(&nodes[node.child[c] as usize]);
                    Entry {
                        t: t[c],
                        what: node.child[c],
                    }
                } else {
                    let (first, count) = (node.child[c], u32::from(node.count[c]));
                    touch(first as usize);
                    if count > 1 {
                        touch((first + count - 1) as usize);
                    }
                    Entry::leaf(t[c], first, count)
                };
                // Insertion into the node's run of the stack, descending distance.
                let mut i = len;
                // SAFETY: slots `base..len` were written in this loop.
                while i > base && unsafe { stack[i - 1].assume_init() }.t < entry.t {
                    stack[i] = stack[i - 1];
                    i -= 1;
                }
                stack[i].write(entry);
                len += 1;
            }
        }
    }
}

#[cfg(not(target_arch = "x86_64"))]
#[allow(unsafe_code)] // Stubs with the x86-64 traversals' signatures.
mod avx2 {
    //! Never called: [`super::BoxNodes::of`] decodes nothing without AVX2.
    use super::{BoxNode, Ray};

    pub(super) unsafe fn any<F: FnMut(usize, usize) -> bool>(_: &[BoxNode], _: &Ray, _: F) -> bool {
        unreachable!("box nodes are decoded only on x86-64 with AVX2 and FMA")
    }

    pub(super) unsafe fn closest<F: FnMut(usize) -> f32, T: Fn(usize)>(
        _: &[BoxNode],
        _: &Ray,
        _: F,
        _: T,
    ) {
        unreachable!("box nodes are decoded only on x86-64 with AVX2 and FMA")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xor_permute_moves_bit_p_to_p_xor_o() {
        for o in 0..8 {
            for mask in 0..256u32 {
                let want = (0..8)
                    .filter(|p| mask & (1 << p) != 0)
                    .fold(0, |m, p| m | 1 << (p ^ o));
                assert_eq!(xor_permute(mask, o), want, "mask {mask:08b}, o {o}");
            }
        }
    }

    /// Every decoded child holds its quantised box (obvhs' documented decoding, `p + q · 2^e`,
    /// in f64) within one f32 step on each side, and links to the same node or primitives.
    #[test]
    fn decoded_boxes_hold_the_quantised_ones() {
        let mut tris = Vec::new();
        for m in [
            crate::test_util::uv_sphere(glam::Vec3::ZERO, 1.0, 16, 32, true),
            crate::test_util::open_box(glam::Vec3::new(0.0, -0.5, 0.0), 2.0),
        ] {
            for idx in &m.indices {
                let [v0, v1, v2] = idx.map(|i| glam::Vec3A::from(m.positions[i as usize]));
                tris.push(obvhs::triangle::Triangle { v0, v1, v2 });
            }
        }
        let bvh = obvhs::cwbvh::builder::build_cwbvh_from_tris(
            &tris,
            obvhs::BvhBuildParams::medium_build(),
            &mut std::time::Duration::default(),
        );
        assert!(depth(&bvh) <= MAX_DEPTH);
        let (mut leaves, mut inner) = (0, 0);
        for node in &bvh.nodes {
            let d = decode(node);
            for c in 0..8 {
                if node.is_child_empty(c) {
                    assert!(d.planes[0][c] == f32::INFINITY && d.planes[1][c] == f32::NEG_INFINITY);
                    continue;
                }
                let q = [
                    node.child_min_x,
                    node.child_max_x,
                    node.child_min_y,
                    node.child_max_y,
                    node.child_min_z,
                    node.child_max_z,
                ];
                for (k, row) in q.iter().enumerate() {
                    let axis = k / 2;
                    let scale = f64::from(f32::from_bits(u32::from(node.e[axis]) << 23));
                    let exact = f64::from(node.p[axis]) + f64::from(row[c]) * scale;
                    let got = d.planes[k][c];
                    let (inside, step) = if k % 2 == 0 {
                        (f64::from(got) <= exact, got.next_up())
                    } else {
                        (f64::from(got) >= exact, got.next_down())
                    };
                    assert!(inside, "plane {k} of child {c}: {got} against {exact}");
                    assert!(
                        (f64::from(step) - exact) * if k % 2 == 0 { 1.0 } else { -1.0 } > 0.0,
                        "plane {k} of child {c}: {got} more than a step from {exact}"
                    );
                }
                if node.is_leaf(c) {
                    let (first, count) = node.child_primitives(c);
                    assert_eq!((d.child[c], u32::from(d.count[c])), (first, count));
                    leaves += 1;
                } else {
                    assert_eq!((d.child[c], d.count[c]), (node.child_node_index(c), 0));
                    assert!(d.inner & (1 << c) != 0);
                    inner += 1;
                }
            }
        }
        assert!(
            leaves > 100 && inner > 10,
            "{leaves} leaves, {inner} inner children"
        );
    }

    #[test]
    fn outward_rounding_brackets_the_value() {
        for x in [0.1f64, -0.1, 1.0 / 3.0, 1e-30, -7.25, 16_777_217.0, 0.0] {
            let (lo, hi) = (round_outward(x, true), round_outward(x, false));
            assert!(f64::from(lo) <= x && x <= f64::from(hi), "{x}: {lo} {hi}");
            assert!(
                hi == lo || hi == lo.next_up(),
                "{x}: {lo} {hi} one ulp apart at most"
            );
        }
    }
}
