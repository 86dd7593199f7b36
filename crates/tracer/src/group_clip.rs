//! Where rays enter the scale groups' world boxes, four boxes or four rays at a time.
//!
//! Every ray of a scene with more than one scale group (`accel.rs`) is clipped against each
//! group's f64 world box before any traversal: the slab test of Kay & Kajiya (1986) in the
//! branch-free form of Williams et al. (2005), with the ray's reciprocal direction. Done one
//! box at a time in scalar code, Rust's NaN-dropping `f64::min`/`max` cost three instructions
//! each, and the walk over the groups was 5–6 % of a sample's instructions on `millimetre`
//! (a part next to a floor). Here the same formulas run in the four f64 lanes of an AVX2
//! register: a ray against four groups' boxes ([`GroupBoxes::ray_entries`], for single rays),
//! or four rays against one box ([`GroupBoxes::lane_entries`], for packets).
//!
//! **The same numbers.** Each lane performs the scalar clip's IEEE operations in the same
//! order (a subtraction, then a multiplication by the reciprocal, no fused multiply-add), and
//! `min`/`max` keep the scalar ones' rule that a NaN operand (`0 · ∞`, an origin on a slab
//! plane of a zero direction component) is dropped in favour of the other. So every lane's
//! entry distance and verdict are the scalar group entry's (`accel.rs`'s unit test
//! `group_clips_are_the_scalar_entries` compares them on random and degenerate rays), and
//! the renders are bit-identical.

use glam::DVec3;

/// Four boxes in structure-of-arrays form: `lo[axis][lane]`, `hi[axis][lane]`.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct Quad {
    lo: [[f64; 4]; 3],
    hi: [[f64; 4]; 3],
}

/// The groups' world boxes, in quads of four (the last one padded with empty lanes, which
/// are masked out), or nothing where the CPU lacks AVX2 (callers then clip one box at a
/// time).
#[derive(Clone, Debug, Default)]
pub(crate) struct GroupBoxes {
    quads: Vec<Quad>,
    len: usize,
}

/// Four rays in structure-of-arrays form, for [`GroupBoxes::lane_entries`].
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(crate) struct RayQuad {
    origin: [[f64; 4]; 3],
    inv: [[f64; 4]; 3],
}

impl RayQuad {
    /// Four rays' origins and reciprocal directions `1 / dir` (each component the IEEE
    /// quotient, as the scalar `DVec3::ONE / dir`).
    pub(crate) fn new(origins: [DVec3; 4], dirs: [DVec3; 4]) -> Self {
        let column = |v: &[DVec3; 4], axis: usize| std::array::from_fn(|lane| v[lane][axis]);
        let mut inv = [[0.0; 4]; 3];
        for (axis, row) in inv.iter_mut().enumerate() {
            *row = column(&dirs, axis).map(|d| 1.0 / d);
        }
        Self {
            origin: std::array::from_fn(|axis| column(&origins, axis)),
            inv,
        }
    }
}

impl GroupBoxes {
    /// The boxes `(lo, hi)` of the groups in order, if this CPU has AVX2; else an empty set
    /// ([`GroupBoxes::is_wide`] false).
    pub(crate) fn new(boxes: &[(DVec3, DVec3)]) -> Self {
        if !crate::traverse::wide_node_test() {
            return Self::default();
        }
        let empty = Quad {
            lo: [[f64::INFINITY; 4]; 3],
            hi: [[f64::NEG_INFINITY; 4]; 3],
        };
        let mut quads = vec![empty; boxes.len().div_ceil(4)];
        for (i, (lo, hi)) in boxes.iter().enumerate() {
            let q = &mut quads[i / 4];
            for axis in 0..3 {
                q.lo[axis][i % 4] = lo[axis];
                q.hi[axis][i % 4] = hi[axis];
            }
        }
        Self {
            quads,
            len: boxes.len(),
        }
    }

    /// Whether the four-lane clips run (AVX2 present and at least one box).
    pub(crate) fn is_wide(&self) -> bool {
        !self.quads.is_empty()
    }

    /// Number of quads of four boxes.
    pub(crate) fn quads(&self) -> usize {
        self.quads.len()
    }

    /// Bit `k` set for each real box of quad `q`.
    fn real(&self, q: usize) -> u8 {
        let n = (self.len - 4 * q).min(4);
        (1u8 << n) - 1
    }

    /// The ray `origin` (reciprocal direction `inv`) against the boxes of quad `q`: bit `k`
    /// set where it enters box `4q + k` by `tmax`, and the entry `t` there (`0` when the
    /// origin is inside), as the scalar clip gives them.
    ///
    /// # Panics
    /// If the set is not wide ([`GroupBoxes::is_wide`]) or `q` is out of range.
    pub(crate) fn ray_entries(
        &self,
        q: usize,
        origin: DVec3,
        inv: DVec3,
        tmax: f64,
    ) -> (u8, [f64; 4]) {
        #[allow(unsafe_code)] // Quads exist only where the CPU has AVX2.
        let (mask, t) = unsafe { avx2::ray_entries(&self.quads[q], &origin, &inv, tmax) };
        (mask & self.real(q), t)
    }

    /// Four rays against box `group`: bit `lane` set where ray `lane` enters it by
    /// `tmax[lane]`, and that entry `t`, as the scalar clip gives them.
    ///
    /// # Panics
    /// If the set is not wide or `group` is out of range.
    pub(crate) fn lane_entries(
        &self,
        group: usize,
        rays: &RayQuad,
        tmax: [f64; 4],
    ) -> (u8, [f64; 4]) {
        assert!(group < self.len, "group {group} of {}", self.len);
        #[allow(unsafe_code)] // Quads exist only where the CPU has AVX2.
        unsafe {
            avx2::entries(&self.quads[group / 4], group % 4, rays, tmax)
        }
    }
}

#[cfg(not(target_arch = "x86_64"))]
#[allow(unsafe_code)] // Stubs with the x86-64 kernels' signatures.
mod avx2 {
    use super::{Quad, RayQuad};
    use glam::DVec3;

    /// Never called: no quads are built off x86-64.
    pub(super) unsafe fn entries(_: &Quad, _: usize, _: &RayQuad, _: [f64; 4]) -> (u8, [f64; 4]) {
        unreachable!("four-lane clips only run on x86-64")
    }

    /// Never called: no quads are built off x86-64.
    pub(super) unsafe fn ray_entries(_: &Quad, _: &DVec3, _: &DVec3, _: f64) -> (u8, [f64; 4]) {
        unreachable!("four-lane clips only run on x86-64")
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)] // Intrinsics and `#[target_feature]` functions, called only after detection.
mod avx2 {
    use super::{Quad, RayQuad};
    use glam::DVec3;
    use std::arch::x86_64::{
        __m256d, _mm256_and_pd, _mm256_blendv_pd, _mm256_cmp_pd, _mm256_load_pd, _mm256_loadu_pd,
        _mm256_max_pd, _mm256_min_pd, _mm256_movemask_pd, _mm256_mul_pd, _mm256_set1_pd,
        _mm256_setzero_pd, _mm256_storeu_pd, _mm256_sub_pd, _CMP_GE_OQ, _CMP_LE_OQ, _CMP_UNORD_Q,
    };

    /// `x.min(y)` lane by lane, as Rust's `f64::min`: a NaN `x` gives `y`; otherwise `MINPD`
    /// with `y` first, which gives `x` when `y` is NaN (and `x` on a tie).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn min(x: __m256d, y: __m256d) -> __m256d {
        _mm256_blendv_pd(_mm256_min_pd(y, x), y, _mm256_cmp_pd::<_CMP_UNORD_Q>(x, x))
    }

    /// `x.max(y)` lane by lane, as Rust's `f64::max` (the same NaN rule as [`min`]).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn max(x: __m256d, y: __m256d) -> __m256d {
        _mm256_blendv_pd(_mm256_max_pd(y, x), y, _mm256_cmp_pd::<_CMP_UNORD_Q>(x, x))
    }

    /// One ray against the four boxes of `quad`: [`clip`] with the ray in every lane.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn ray_entries(
        quad: &Quad,
        origin: &DVec3,
        inv: &DVec3,
        tmax: f64,
    ) -> (u8, [f64; 4]) {
        let o = [origin.x, origin.y, origin.z].map(|c| _mm256_set1_pd(c));
        let inv = [inv.x, inv.y, inv.z].map(|c| _mm256_set1_pd(c));
        let lo = quad.lo.map(|row| _mm256_load_pd(row.as_ptr()));
        let hi = quad.hi.map(|row| _mm256_load_pd(row.as_ptr()));
        clip([lo, hi], o, inv, _mm256_set1_pd(tmax))
    }

    /// Four rays against box `k` of `quad` (broadcast to every lane): [`clip`] lane by lane.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn entries(
        quad: &Quad,
        k: usize,
        ray: &RayQuad,
        tmax: [f64; 4],
    ) -> (u8, [f64; 4]) {
        let o = ray.origin.map(|row| _mm256_load_pd(row.as_ptr()));
        let inv = ray.inv.map(|row| _mm256_load_pd(row.as_ptr()));
        let lo = quad.lo.map(|row| _mm256_set1_pd(row[k]));
        let hi = quad.hi.map(|row| _mm256_set1_pd(row[k]));
        clip([lo, hi], o, inv, _mm256_loadu_pd(tmax.as_ptr()))
    }

    /// Lane `k`: the ray of origin `o` and reciprocal direction `inv` (per axis) against the
    /// box `[lo, hi]` of `bounds` in that lane, with the scalar clip's operations in its order: the origin inside the
    /// box gives `[0, ∞)`; otherwise `a = (lo − o)·inv`, `b = (hi − o)·inv`,
    /// `t0 = min(a_x, b_x) ⊔ min(a_y, b_y) ⊔ min(a_z, b_z)` (`⊔`: max), `t1` likewise; the
    /// box is entered if `t0 ≤ t1`, `t1 ≥ 0` and `t0 ≤ tmax`, at `max(t0, 0)`.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn clip(
        bounds: [[__m256d; 3]; 2],
        o: [__m256d; 3],
        inv: [__m256d; 3],
        tmax: __m256d,
    ) -> (u8, [f64; 4]) {
        let mut inside = _mm256_cmp_pd::<_CMP_LE_OQ>(_mm256_setzero_pd(), _mm256_setzero_pd());
        let mut t0 = _mm256_setzero_pd();
        let mut t1 = _mm256_setzero_pd();
        for axis in 0..3 {
            let (lo, hi) = (bounds[0][axis], bounds[1][axis]);
            let within = _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GE_OQ>(o[axis], lo),
                _mm256_cmp_pd::<_CMP_LE_OQ>(o[axis], hi),
            );
            inside = _mm256_and_pd(inside, within);
            let a = _mm256_mul_pd(_mm256_sub_pd(lo, o[axis]), inv[axis]);
            let b = _mm256_mul_pd(_mm256_sub_pd(hi, o[axis]), inv[axis]);
            let (near, far) = (min(a, b), max(a, b));
            if axis == 0 {
                (t0, t1) = (near, far);
            } else {
                (t0, t1) = (max(t0, near), min(t1, far));
            }
        }
        let zero = _mm256_setzero_pd();
        t0 = _mm256_blendv_pd(t0, zero, inside);
        t1 = _mm256_blendv_pd(t1, _mm256_set1_pd(f64::INFINITY), inside);
        let clipped = _mm256_and_pd(
            _mm256_cmp_pd::<_CMP_LE_OQ>(t0, t1),
            _mm256_cmp_pd::<_CMP_GE_OQ>(t1, zero),
        );
        let reached = _mm256_cmp_pd::<_CMP_LE_OQ>(t0, tmax);
        let mask = _mm256_movemask_pd(_mm256_and_pd(clipped, reached)) as u8;
        // `t0.max(0.0)`: `t0` is not NaN in a lane that passed `t0 ≤ t1`.
        let mut out = [0.0; 4];
        _mm256_storeu_pd(out.as_mut_ptr(), max(t0, zero));
        (mask, out)
    }
}
