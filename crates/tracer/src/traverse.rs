//! Traversal of an obvhs CWBVH (Ylitie, Karras & Laine 2017, "Efficient Incoherent Ray
//! Traversal on GPUs Through Compressed Wide BVHs") with all eight child boxes of a node tested
//! at once where the CPU has AVX2, and obvhs' own traversal otherwise.
//!
//! obvhs 0.4.0 tests a node's children four at a time with SSE and builds each group of four
//! quantised child planes from bytes one scalar conversion at a time, which its own comments
//! name as the most expensive part of the node test. With AVX2 one `vpmovzxbd` and one
//! `vcvtdq2ps` turn a plane's eight bytes into eight floats. The traversal loop itself is
//! obvhs' public `traverse!` macro, expanded here inside a function compiled for AVX2 (chosen
//! once per call by `is_x86_feature_detected!`, so the binary still runs on any x86-64), with
//! this node test in place of `CwBvhNode::intersect_ray`.
//!
//! **Same candidates, same images.** The node test does obvhs' arithmetic operation for
//! operation — the slab distances as `q · (extent · 1/d) + (p − o) · 1/d` with one rounding per
//! multiply and add (no fused multiply-add), the same `max`/`min` order (so NaNs resolve the
//! same way), obvhs' fixed node `tmin` of `1e-4` and the ray's `tmax` — so it accepts exactly
//! the children obvhs accepts, the traversal visits the same nodes in the same order, and the
//! exact triangle tests of `accel` see the same candidates: hits and images are bit-identical
//! with and without AVX2 (`tests/accel.rs` compares the node masks on random nodes and rays,
//! and whole traversals against obvhs' own).
//!
//! **Own traversals of the same tree.** Two traversals here do not follow obvhs' loop, where
//! its order costs time on a CPU (`Accel` uses them for single rays where the CPU lacks FMA
//! or a tree is too deep for [`crate::box_nodes`], whose float-box traversals follow the same
//! two loops): [`closest_sorted`] (single closest-hit rays) keeps every
//! accepted child on the stack with its entry distance and visits the nearest first,
//! dropping entries beyond the hit found so far without loading their node (Embree-style;
//! obvhs keeps groups of children without distances, ordered by the ray's octant, a GPU
//! design), and [`any_leaves_first`] (occlusion rays) tests a node's accepted leaves at once
//! and stacks plain node indices. Both use the same node test, so they accept the same boxes
//! at a given `tmax`: the any-hit answer is the same, and so is the closest hit under a
//! tie rule that does not depend on the order candidates come in.
//!
//! **Packets.** [`closest_packet`] traverses up to [`PACKET`] rays together (Wald, Slusallek,
//! Benthin & Wagner 2001, "Interactive Rendering with Coherent Ray Tracing", with a mask of
//! the rays still in each node): a node is fetched once for the packet, and its eight child
//! boxes are tested against the eight rays with the rays in the SIMD lanes. Each (ray, child)
//! test is the single-ray test's arithmetic, operation for operation, with that ray's own
//! `tmax`, so every ray reaches exactly the primitives whose boxes the single-ray traversal
//! would accept at the same `tmax`; only the order of the candidates differs, which the
//! caller's closest-hit rule makes irrelevant (ties resolved by slot, not by order). Rays that
//! share an origin and nearby directions (a bake point's sorted rays, a pixel's camera rays)
//! share most nodes, and the fetch and the loop's bookkeeping are paid once for all of them.

use glam::{UVec2, Vec3A};
use obvhs::{cwbvh::CwBvh, ray::Ray, ray::RayHit};

/// Rays in a packet: the lanes of one AVX2 register.
pub const PACKET: usize = 8;

/// obvhs' fixed lower bound on a node's slab `tmin` (its private `EPSILON`; bug C of `accel`).
pub const NODE_TMIN: f32 = 1.0e-4;

/// Closest-hit traversal: calls `hit` on every candidate primitive slot the ray's boxes reach;
/// `hit` returns the ray-local distance of a hit (or `∞`), which shortens the ray.
pub fn closest<F: FnMut(usize) -> f32>(bvh: &CwBvh, ray: Ray, mut hit: F) {
    #[cfg(target_arch = "x86_64")]
    if wide_node_test() {
        #[allow(unsafe_code)] // Runtime feature dispatch: AVX2 is present.
        unsafe {
            return avx2::closest(bvh, ray, hit);
        }
    }
    bvh.ray_traverse(ray, &mut RayHit::none(), |_, slot| hit(slot));
}

/// Closest-hit traversal, nearest box first: like [`closest`] (the same node test, so the
/// same boxes accepted at a given `tmax`), but every accepted child goes on the stack with
/// its entry distance, children are visited in order of that distance, and an entry whose
/// distance is beyond the ray's current `tmax` when it comes off the stack is dropped
/// without loading its node (Embree-style, where obvhs keeps groups of children without
/// distances and approximates the order by the ray's octant). The candidates differ from
/// [`closest`]'s only by the ones this never needs to test: every box that can hold a hit
/// closer than the closest found so far is still visited, so with an order-independent
/// rule for ties the closest hit is the same.
///
/// `touch(slot)` is called for the first and the last slot of every leaf when it is accepted,
/// before its candidates are tested, so the caller can start loading the triangles (see
/// [`prefetch`]): the leaves a node accepts are then fetched together.
pub fn closest_sorted<F: FnMut(usize) -> f32, T: Fn(usize)>(
    bvh: &CwBvh,
    ray: Ray,
    hit: F,
    touch: T,
) {
    // A leaf's first slot is kept in 27 bits of a stack entry.
    #[cfg(target_arch = "x86_64")]
    if wide_node_test() && bvh.primitive_indices.len() < 1 << 27 {
        #[allow(unsafe_code)] // Runtime feature dispatch: AVX2 is present.
        unsafe {
            return avx2::closest_sorted(bvh, ray, hit, touch);
        }
    }
    closest(bvh, ray, hit);
}

/// Asks the CPU to start loading `item` into the cache, one prefetch per 64 bytes of it from
/// its start (a hint: no effect on results).
#[inline]
pub fn prefetch<T>(item: &T) {
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code)] // SSE is part of x86-64; a prefetch never faults.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = std::ptr::from_ref(item).cast::<i8>();
        for line in 0..std::mem::size_of::<T>().div_ceil(64).max(1) {
            _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * line));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = item;
}

/// A stack entry of the nearest-first traversals ([`closest_sorted`] and
/// [`crate::box_nodes::BoxNodes::closest`]): a child's entry distance and what it is (bit 31
/// set: a leaf, with its first primitive slot in bits 0..27 and its count in bits 27..30;
/// clear: an inner node's index).
#[derive(Clone, Copy)]
pub(crate) struct Entry {
    pub(crate) t: f32,
    pub(crate) what: u32,
}

/// Bit 31 of [`Entry::what`]: a leaf.
pub(crate) const LEAF: u32 = 1 << 31;

impl Entry {
    /// A leaf of `count` primitive slots from `first`, entered at `t`.
    #[inline]
    pub(crate) fn leaf(t: f32, first: u32, count: u32) -> Self {
        Self {
            t,
            what: LEAF | count << 27 | first,
        }
    }

    /// The slots `(first, count)` of a leaf entry; `None` for a node.
    #[inline]
    pub(crate) fn slots(self) -> Option<(usize, usize)> {
        (self.what & LEAF != 0).then_some((
            (self.what & ((1 << 27) - 1)) as usize,
            ((self.what >> 27) & 0b111) as usize,
        ))
    }
}

/// The octant order obvhs' traversal gives a direction's children (`oct_inv4 & 7`): child
/// `p ^ octant` comes `p`-th.
#[inline]
pub(crate) fn octant_inverse(d: Vec3A) -> usize {
    usize::from(d.x >= 0.0) << 2 | usize::from(d.y >= 0.0) << 1 | usize::from(d.z >= 0.0)
}

/// Any-hit traversal: whether `hit` returns a distance below the ray's `tmax` for a candidate
/// slot (traversal stops at the first).
pub fn any<F: FnMut(usize) -> f32>(bvh: &CwBvh, ray: Ray, mut hit: F) -> bool {
    #[cfg(target_arch = "x86_64")]
    if wide_node_test() {
        #[allow(unsafe_code)] // Runtime feature dispatch: AVX2 is present.
        unsafe {
            return avx2::any(bvh, ray, hit);
        }
    }
    !bvh.ray_traverse_miss(ray, |_, slot| hit(slot))
}

/// Any-hit traversal without obvhs' child groups: a node's accepted leaf children are tested
/// at once (the first hit below `tmax` ends it) and its inner children go on a stack of node
/// indices in obvhs' octant order. With `tmax` fixed, every box accepted on the way is the
/// same as in [`any`], so the answer is the same; only the order of the candidates differs.
pub fn any_leaves_first<F: FnMut(usize) -> f32>(bvh: &CwBvh, ray: Ray, hit: F) -> bool {
    #[cfg(target_arch = "x86_64")]
    if wide_node_test() {
        #[allow(unsafe_code)] // Runtime feature dispatch: AVX2 is present.
        unsafe {
            return avx2::any_leaves_first(bvh, ray, hit);
        }
    }
    any(bvh, ray, hit)
}

/// Closest-hit traversal of up to [`PACKET`] rays together: the rays whose bit is set in
/// `active`. `hit(lanes, slot, tmax)` is called for every candidate primitive slot with the
/// lanes (bit `i`: ray `i`) whose boxes reach it; it tests the slot against each of those rays
/// and lowers `tmax[i]` to the ray-local distance of a hit closer than it, which shortens
/// that ray (`tmax` starts at the rays' own `tmax`). Without AVX2 each ray runs [`closest`]
/// in turn.
pub fn closest_packet<F: FnMut(u8, usize, &mut [f32; PACKET])>(
    bvh: &CwBvh,
    rays: &[Ray; PACKET],
    active: u8,
    mut hit: F,
) {
    #[cfg(target_arch = "x86_64")]
    if wide_node_test() {
        #[allow(unsafe_code)] // Runtime feature dispatch: AVX2 is present.
        unsafe {
            return avx2::closest_packet(bvh, rays, active, hit);
        }
    }
    let mut tmax: [f32; PACKET] = std::array::from_fn(|i| rays[i].tmax);
    for (lane, ray) in rays.iter().enumerate() {
        if active & (1 << lane) != 0 {
            closest(bvh, *ray, |slot| {
                hit(1 << lane, slot, &mut tmax);
                tmax[lane]
            });
        }
    }
}

/// Whether [`closest`], [`any`] and [`node_hits`] run the AVX2 node test on this CPU.
#[must_use]
pub fn wide_node_test() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The hit mask of `node`'s children for `ray` (obvhs' `intersect_ray` result: child bits at
/// their slot positions), from the AVX2 test where the CPU has it, else from obvhs.
#[must_use]
pub fn node_hits(node: &obvhs::cwbvh::node::CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if wide_node_test() {
        #[allow(unsafe_code)] // Runtime feature dispatch: AVX2 is present.
        unsafe {
            return avx2::node_hits(node, ray, oct_inv4);
        }
    }
    node.intersect_ray(ray, oct_inv4)
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)] // Intrinsics and `#[target_feature]` functions, called only after detection.
mod avx2 {
    use super::{octant_inverse, CwBvh, Entry, Ray, UVec2, Vec3A, NODE_TMIN, PACKET};
    use obvhs::cwbvh::node::{extract_byte64, CwBvhNode};
    use smallvec::SmallVec;
    use std::arch::x86_64::{
        __m256, _mm256_add_ps, _mm256_blendv_ps, _mm256_broadcast_ss, _mm256_cmp_ps,
        _mm256_cvtepi32_ps, _mm256_cvtepu8_epi32, _mm256_loadu_ps, _mm256_max_ps, _mm256_min_ps,
        _mm256_movemask_ps, _mm256_mul_ps, _mm256_set1_ps, _mm256_setzero_ps, _mm256_storeu_ps,
        _mm256_sub_ps, _mm_loadl_epi64, _CMP_LE_OQ, _CMP_LT_OQ,
    };

    /// [`super::closest`] with the AVX2 node test.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn closest<F: FnMut(usize) -> f32>(bvh: &CwBvh, ray: Ray, mut hit: F) {
        let mut ray = ray;
        let mut state = bvh.new_traversal(ray.direction);
        let mut node;
        obvhs::traverse!(bvh, node, state, node_hits(node, &ray, state.oct_inv4), {
            let t = hit(state.primitive_id as usize);
            if t < ray.tmax {
                ray.tmax = t;
            }
        });
    }

    /// [`super::any`] with the AVX2 node test.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn any<F: FnMut(usize) -> f32>(bvh: &CwBvh, ray: Ray, mut hit: F) -> bool {
        let mut state = bvh.new_traversal(ray.direction);
        let mut node;
        let mut found = false;
        'outer: {
            obvhs::traverse!(bvh, node, state, node_hits(node, &ray, state.oct_inv4), {
                if hit(state.primitive_id as usize) < ray.tmax {
                    found = true;
                    break 'outer;
                }
            });
        }
        found
    }

    /// [`super::closest_sorted`] with the AVX2 node test.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn closest_sorted<F: FnMut(usize) -> f32, T: Fn(usize)>(
        bvh: &CwBvh,
        ray: Ray,
        mut hit: F,
        touch: T,
    ) {
        if bvh.nodes.is_empty() {
            return;
        }
        let mut ray = ray;
        let mut stack: SmallVec<[Entry; 128]> = SmallVec::new();
        // The root is entered unconditionally, as in obvhs.
        stack.push(Entry { t: 0.0, what: 0 });
        while let Some(e) = stack.pop() {
            if e.t > ray.tmax {
                continue;
            }
            if let Some((first, count)) = e.slots() {
                for slot in first..first + count {
                    let t = hit(slot);
                    if t < ray.tmax {
                        ray.tmax = t;
                    }
                }
                continue;
            }
            let node = &bvh.nodes[e.what as usize];
            let (mut mask, tmin) = slot_hits_t(node, &ray, ray.tmax);
            // The accepted children, farthest first, so the nearest comes off the stack next.
            let base = stack.len();
            while mask != 0 {
                let child = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if node.is_child_empty(child) {
                    continue;
                }
                let entry = if node.is_leaf(child) {
                    let (first, count) = node.child_primitives(child);
                    touch(first as usize);
                    if count > 1 {
                        touch((first + count - 1) as usize);
                    }
                    Entry::leaf(tmin[child], first, count)
                } else {
                    let index = node.child_node_index(child);
                    prefetch_node(bvh, index);
                    Entry {
                        t: tmin[child],
                        what: index,
                    }
                };
                // Insertion into the node's run of the stack, descending distance.
                let mut i = stack.len();
                stack.push(entry);
                while i > base && stack[i - 1].t < entry.t {
                    stack[i] = stack[i - 1];
                    i -= 1;
                }
                stack[i] = entry;
            }
        }
    }

    /// [`super::any_leaves_first`] with the AVX2 node test.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn any_leaves_first<F: FnMut(usize) -> f32>(
        bvh: &CwBvh,
        ray: Ray,
        mut hit: F,
    ) -> bool {
        if bvh.nodes.is_empty() {
            return false;
        }
        let oct_inv = octant_inverse(ray.direction);
        let mut stack: SmallVec<[u32; 64]> = SmallVec::new();
        stack.push(0);
        while let Some(index) = stack.pop() {
            let node = &bvh.nodes[index as usize];
            let accepted = slot_hits(node, &ray, ray.tmax);
            let inner = u32::from(node.imask);
            let mut leaves = accepted & !inner;
            while leaves != 0 {
                let child = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                let (first, count) = node.child_primitives(child);
                for slot in first..first + count {
                    if hit(slot as usize) < ray.tmax {
                        return true;
                    }
                }
            }
            let going = accepted & inner;
            if going != 0 {
                // Farthest (by octant) pushed first, so the nearest comes off next.
                for priority in 0..8 {
                    let child = priority ^ oct_inv;
                    if going & (1 << child) != 0 {
                        stack.push(node.child_node_index(child));
                    }
                }
            }
        }
        false
    }

    /// Starts loading node `index` into the cache (both of its lines): a node's accepted
    /// children are fetched together instead of one after another as they come off the stack.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn prefetch_node(bvh: &CwBvh, index: u32) {
        if let Some(node) = bvh.nodes.get(index as usize) {
            super::prefetch(node);
        }
    }

    /// The eight quantised planes `q` of one axis as floats (exact: bytes).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn planes(q: &[u8; 8]) -> __m256 {
        _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(q.as_ptr().cast())))
    }

    /// The slab distances `q · scale + offset` of eight planes (a multiply, then an add).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn slab(q: &[u8; 8], scale: f32, offset: f32) -> __m256 {
        _mm256_add_ps(
            _mm256_mul_ps(planes(q), _mm256_set1_ps(scale)),
            _mm256_set1_ps(offset),
        )
    }

    /// Entry and exit distances of one axis' slabs: the near planes are the low ones unless
    /// the ray runs towards `−axis`.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn slabs(
        lo: &[u8; 8],
        hi: &[u8; 8],
        negative: bool,
        scale: f32,
        offset: f32,
    ) -> (__m256, __m256) {
        let (near, far) = if negative { (hi, lo) } else { (lo, hi) };
        (slab(near, scale, offset), slab(far, scale, offset))
    }

    /// obvhs' `CwBvhNode::intersect_ray_simd`, eight children at once.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn node_hits(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
        let mut inside = slot_hits(node, ray, ray.tmax);
        let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
        let mut mask = 0u32;
        while inside != 0 {
            let child = inside.trailing_zeros() as usize;
            inside &= inside - 1;
            mask |= extract_byte64(child_bits8, child) << extract_byte64(bit_index8, child);
        }
        mask
    }

    /// The child slots (bit `i`: slot `i`) whose boxes the ray's slab test accepts with the
    /// ray ending at `tmax`.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn slot_hits(node: &CwBvhNode, ray: &Ray, tmax_ray: f32) -> u32 {
        let (tmin, tmax) = slab_test(node, ray, tmax_ray);
        _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tmin, tmax)) as u32
    }

    /// [`slot_hits`] and the entry distance of every child (meaningful where accepted).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn slot_hits_t(node: &CwBvhNode, ray: &Ray, tmax_ray: f32) -> (u32, [f32; 8]) {
        let (tmin, tmax) = slab_test(node, ray, tmax_ray);
        let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tmin, tmax)) as u32;
        let mut t = [0.0f32; 8];
        _mm256_storeu_ps(t.as_mut_ptr(), tmin);
        (mask, t)
    }

    /// The entry and exit distances of the ray in each of the eight child boxes, the entry
    /// clamped below by obvhs' node `tmin` and the exit above by `tmax_ray` (a child is hit
    /// where entry ≤ exit).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn slab_test(node: &CwBvhNode, ray: &Ray, tmax_ray: f32) -> (__m256, __m256) {
        let scale = node.compute_extent() * ray.inv_direction;
        let offset = (Vec3A::from(node.p) - ray.origin) * ray.inv_direction;
        let d = ray.direction;
        let (tmin_x, tmax_x) = slabs(
            &node.child_min_x,
            &node.child_max_x,
            d.x < 0.0,
            scale.x,
            offset.x,
        );
        let (tmin_y, tmax_y) = slabs(
            &node.child_min_y,
            &node.child_max_y,
            d.y < 0.0,
            scale.y,
            offset.y,
        );
        let (tmin_z, tmax_z) = slabs(
            &node.child_min_z,
            &node.child_max_z,
            d.z < 0.0,
            scale.z,
            offset.z,
        );
        let tmin = _mm256_max_ps(tmin_x, _mm256_max_ps(tmin_y, tmin_z));
        let tmax = _mm256_min_ps(tmax_x, _mm256_min_ps(tmax_y, tmax_z));
        let tmin = _mm256_max_ps(tmin, _mm256_set1_ps(NODE_TMIN));
        let tmax = _mm256_min_ps(tmax, _mm256_set1_ps(tmax_ray));
        (tmin, tmax)
    }

    /// A packet's rays with one component per register (lane `i`: ray `i`).
    struct Lanes {
        origin: [__m256; 3],
        inv_direction: [__m256; 3],
        /// All ones in the lanes whose direction runs towards `−axis`.
        negative: [__m256; 3],
    }

    impl Lanes {
        #[inline]
        #[target_feature(enable = "avx2")]
        unsafe fn new(rays: &[Ray; PACKET]) -> Self {
            let axis = |f: &dyn Fn(&Ray) -> f32| {
                let v: [f32; PACKET] = std::array::from_fn(|i| f(&rays[i]));
                _mm256_loadu_ps(v.as_ptr())
            };
            let zero = _mm256_setzero_ps();
            let dir = [
                axis(&|r| r.direction.x),
                axis(&|r| r.direction.y),
                axis(&|r| r.direction.z),
            ];
            Self {
                origin: [
                    axis(&|r| r.origin.x),
                    axis(&|r| r.origin.y),
                    axis(&|r| r.origin.z),
                ],
                inv_direction: [
                    axis(&|r| r.inv_direction.x),
                    axis(&|r| r.inv_direction.y),
                    axis(&|r| r.inv_direction.z),
                ],
                negative: dir.map(|d| _mm256_cmp_ps::<_CMP_LT_OQ>(d, zero)),
            }
        }
    }

    /// Per child slot, the lanes (bit `i`: ray `i`) whose slab test accepts the child: the
    /// arithmetic of [`node_hits`] for each ray, with the rays in the lanes instead of the
    /// children.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn packet_node_hits(
        node: &CwBvhNode,
        lanes: &Lanes,
        rays: &[Ray; PACKET],
        tmax: &[f32; PACKET],
        arriving: u8,
    ) -> [u8; 8] {
        if arriving.count_ones() <= SPARSE_LANES {
            return sparse_node_hits(node, rays, tmax, arriving);
        }
        let tmax = _mm256_loadu_ps(tmax.as_ptr());
        let extent = node.compute_extent();
        let p = Vec3A::from(node.p);
        let mut scale = [_mm256_setzero_ps(); 3];
        let mut offset = [_mm256_setzero_ps(); 3];
        for a in 0..3 {
            let inv = lanes.inv_direction[a];
            scale[a] = _mm256_mul_ps(_mm256_set1_ps(extent[a]), inv);
            offset[a] = _mm256_mul_ps(_mm256_sub_ps(_mm256_set1_ps(p[a]), lanes.origin[a]), inv);
        }
        // The six planes of every child as floats, converted eight at a time (exact: bytes).
        let bytes = [
            &node.child_min_x,
            &node.child_max_x,
            &node.child_min_y,
            &node.child_max_y,
            &node.child_min_z,
            &node.child_max_z,
        ];
        let mut q = [[0.0f32; 8]; 6];
        for (p, b) in q.iter_mut().zip(bytes) {
            _mm256_storeu_ps(p.as_mut_ptr(), planes(b));
        }
        let node_tmin = _mm256_set1_ps(NODE_TMIN);
        let mut out = [0u8; 8];
        for (child, lanes_hit) in out.iter_mut().enumerate() {
            if node.child_meta[child] == 0 {
                continue;
            }
            let mut near = [_mm256_setzero_ps(); 3];
            let mut far = [_mm256_setzero_ps(); 3];
            for a in 0..3 {
                let lo = _mm256_broadcast_ss(&q[2 * a][child]);
                let hi = _mm256_broadcast_ss(&q[2 * a + 1][child]);
                let neg = lanes.negative[a];
                let (qn, qf) = (_mm256_blendv_ps(lo, hi, neg), _mm256_blendv_ps(hi, lo, neg));
                near[a] = _mm256_add_ps(_mm256_mul_ps(qn, scale[a]), offset[a]);
                far[a] = _mm256_add_ps(_mm256_mul_ps(qf, scale[a]), offset[a]);
            }
            let t0 = _mm256_max_ps(near[0], _mm256_max_ps(near[1], near[2]));
            let t1 = _mm256_min_ps(far[0], _mm256_min_ps(far[1], far[2]));
            let t0 = _mm256_max_ps(t0, node_tmin);
            let t1 = _mm256_min_ps(t1, tmax);
            *lanes_hit = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t0, t1)) as u8;
        }
        out
    }

    /// At most this many rays in a node: test them one by one, eight children at a time.
    const SPARSE_LANES: u32 = 2;

    /// [`packet_node_hits`] for the few rays of `arriving`, each by the single-ray test (the
    /// same per-ray arithmetic; the SIMD lanes are the children).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn sparse_node_hits(
        node: &CwBvhNode,
        rays: &[Ray; PACKET],
        tmax: &[f32; PACKET],
        arriving: u8,
    ) -> [u8; 8] {
        let mut out = [0u8; 8];
        let mut todo = arriving;
        while todo != 0 {
            let lane = todo.trailing_zeros() as usize;
            todo &= todo - 1;
            let mut slots = slot_hits(node, &rays[lane], tmax[lane]);
            while slots != 0 {
                let child = slots.trailing_zeros() as usize;
                slots &= slots - 1;
                out[child] |= 1 << lane;
            }
        }
        out
    }

    /// [`super::closest_packet`] with the AVX2 packet node test.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn closest_packet<F: FnMut(u8, usize, &mut [f32; PACKET])>(
        bvh: &CwBvh,
        rays: &[Ray; PACKET],
        active: u8,
        mut hit: F,
    ) {
        if bvh.nodes.is_empty() || active == 0 {
            return;
        }
        let lanes = Lanes::new(rays);
        let mut tmax: [f32; PACKET] = std::array::from_fn(|i| rays[i].tmax);
        // A node's children are visited nearest first for the octant of the first ray in it, as
        // obvhs orders them (a ray alone in a subtree goes through it in its own order).
        let octants: [usize; PACKET] = std::array::from_fn(|i| octant_inverse(rays[i].direction));
        let mut stack: SmallVec<[(u32, u8); 64]> = SmallVec::new();
        stack.push((0, active));
        while let Some((index, arriving)) = stack.pop() {
            let node = &bvh.nodes[index as usize];
            let hits = packet_node_hits(node, &lanes, rays, &tmax, arriving);
            for (child, &lanes_hit) in hits.iter().enumerate() {
                let todo = lanes_hit & arriving;
                if todo == 0 || !node.is_leaf(child) {
                    continue;
                }
                let (first, count) = node.child_primitives(child);
                for slot in first..first + count {
                    hit(todo, slot as usize, &mut tmax);
                }
            }
            let oct_inv = octants[arriving.trailing_zeros() as usize];
            for priority in 0..8 {
                let child = priority ^ oct_inv;
                let going = hits[child] & arriving;
                if going != 0 && !node.is_leaf(child) {
                    stack.push((node.child_node_index(child), going));
                }
            }
        }
    }
}
