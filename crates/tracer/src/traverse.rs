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

use glam::{UVec2, Vec3A};
use obvhs::{cwbvh::CwBvh, ray::Ray, ray::RayHit};

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
    use super::{CwBvh, Ray, UVec2, Vec3A, NODE_TMIN};
    use obvhs::cwbvh::node::{extract_byte64, CwBvhNode};
    use std::arch::x86_64::{
        __m256, _mm256_add_ps, _mm256_cmp_ps, _mm256_cvtepi32_ps, _mm256_cvtepu8_epi32,
        _mm256_max_ps, _mm256_min_ps, _mm256_movemask_ps, _mm256_mul_ps, _mm256_set1_ps,
        _mm_loadl_epi64, _CMP_LE_OQ,
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
        let tmax = _mm256_min_ps(tmax, _mm256_set1_ps(ray.tmax));
        let mut inside = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tmin, tmax)) as u32;
        let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
        let mut mask = 0u32;
        while inside != 0 {
            let child = inside.trailing_zeros() as usize;
            inside &= inside - 1;
            mask |= extract_byte64(child_bits8, child) << extract_byte64(bit_index8, child);
        }
        mask
    }
}
