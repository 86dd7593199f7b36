//! Evaluation of all real SH basis functions of an order at a direction.

use crate::index::{check_len, check_order, coefficient_count, index, ShError, MAX_ORDER};
use crate::legendre::LegendreTable;
use glam::{DVec3, Vec3};

/// Evaluates all `order²` basis functions at directions, without allocating per call.
///
/// The direction need not be normalised (it is, in f64). Build once per order and reuse:
/// ```
/// use prt_sh::Basis;
/// let basis = Basis::new(3).unwrap();
/// let mut y = vec![0.0; 9];
/// basis.eval_into(glam::DVec3::Z, &mut y).unwrap();
/// assert!((y[2] - (3.0 / (4.0 * std::f64::consts::PI)).sqrt()).abs() < 1e-15);
/// ```
#[derive(Clone, Debug)]
pub struct Basis {
    order: usize,
    table: LegendreTable,
}

impl Basis {
    /// Prepares evaluation for `order` bands (1 ≤ order ≤ [`MAX_ORDER`]).
    pub fn new(order: usize) -> Result<Self, ShError> {
        check_order(order, MAX_ORDER)?;
        Ok(Self {
            order,
            table: LegendreTable::new(order),
        })
    }

    /// The order (band count).
    #[must_use]
    pub fn order(&self) -> usize {
        self.order
    }

    /// Number of coefficients, `order²`.
    #[must_use]
    pub fn len(&self) -> usize {
        coefficient_count(self.order)
    }

    /// Always false (an order is at least 1).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Fills `out` (length `order²`) with `y_i(dir)` in f64.
    pub fn eval_into(&self, dir: DVec3, out: &mut [f64]) -> Result<(), ShError> {
        check_len(self.order, out.len())?;
        self.eval_unchecked(dir, out);
        Ok(())
    }

    /// Fills `out` with `y_i(dir)`; `out.len()` must be `order²` (checked in debug builds).
    pub fn eval_unchecked(&self, dir: DVec3, out: &mut [f64]) {
        debug_assert_eq!(out.len(), self.len());
        self.eval_with(dir, |i, v| out[i] = v);
    }

    /// The one evaluation loop, in f64 whatever the output type: for each `m` the azimuthal
    /// factor `(x + iy)^m = sin^m θ e^{imφ}` is advanced once, then the Legendre column
    /// `Q_l^m`, `l = m..order`, runs and each value is written with its cos and sin factor.
    #[inline]
    fn eval_with(&self, dir: DVec3, mut write: impl FnMut(usize, f64)) {
        let d = dir.normalize_or(DVec3::Z);
        let t = &self.table;
        let n = self.order;
        let (mut c, mut s) = (1.0f64, 0.0f64);
        for m in 0..n {
            if m > 0 {
                let c_next = d.x * c - d.y * s;
                s = d.x * s + d.y * c;
                c = c_next;
            }
            let mi = m as i64;
            let mut emit = |l: usize, q: f64| {
                if m == 0 {
                    write(index(l, 0), q);
                } else {
                    write(index(l, mi), q * c);
                    write(index(l, -mi), q * s);
                }
            };
            let mut q2 = t.diag(m);
            emit(m, q2);
            if m + 1 >= n {
                continue;
            }
            let mut q1 = ((2 * m + 3) as f64).sqrt() * d.z * q2;
            emit(m + 1, q1);
            for l in (m + 2)..n {
                let (a, b) = t.ab(l, m);
                let v = a * (d.z * q1 - b * q2);
                emit(l, v);
                q2 = q1;
                q1 = v;
            }
        }
    }

    /// Returns a new vector of `y_i(dir)`.
    #[must_use]
    pub fn eval(&self, dir: DVec3) -> Vec<f64> {
        let mut out = vec![0.0; self.len()];
        self.eval_unchecked(dir, &mut out);
        out
    }

    /// Single-precision evaluation into an f32 buffer, for hot loops (bakes, relighting).
    /// Max error against f64 is below 2e-5 up to order 30 (tested).
    pub fn eval_f32_into(&self, dir: Vec3, out: &mut [f32]) -> Result<(), ShError> {
        check_len(self.order, out.len())?;
        self.eval_f32_unchecked(dir, out);
        Ok(())
    }

    /// Single-precision output; the recurrences run in f64 (they cost the same as in f32 on
    /// scalar code, and f32 recurrences lose about 1e-4 by order 30).
    pub fn eval_f32_unchecked(&self, dir: Vec3, out: &mut [f32]) {
        debug_assert_eq!(out.len(), self.len());
        self.eval_with(dir.as_dvec3(), |i, v| out[i] = v as f32);
    }

    /// Evaluates at many directions: `out` holds `dirs.len()` consecutive blocks of `order²`.
    pub fn eval_batch(&self, dirs: &[DVec3], out: &mut [f64]) -> Result<(), ShError> {
        let n2 = self.len();
        if out.len() != dirs.len() * n2 {
            return Err(ShError::BufferLength {
                order: self.order,
                expected: dirs.len() * n2,
                got: out.len(),
            });
        }
        for (d, block) in dirs.iter().zip(out.chunks_exact_mut(n2)) {
            self.eval_unchecked(*d, block);
        }
        Ok(())
    }

    /// Access to the Legendre table (θ-part), for projection code.
    pub(crate) fn legendre(&self) -> &LegendreTable {
        &self.table
    }
}

/// Convenience: all basis functions of `order` at `dir` (allocates).
pub fn eval_basis(order: usize, dir: DVec3) -> Result<Vec<f64>, ShError> {
    Ok(Basis::new(order)?.eval(dir))
}

/// Value of the expansion `Σ c_i y_i(dir)` (reconstruction at one direction).
pub fn reconstruct(coeffs: &[f64], order: usize, dir: DVec3) -> Result<f64, ShError> {
    check_len(order, coeffs.len())?;
    let y = eval_basis(order, dir)?;
    Ok(coeffs.iter().zip(&y).map(|(c, y)| c * y).sum())
}
