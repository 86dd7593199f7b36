//! The real SH triple-product (Gaunt) tensor `G_ijk = ∫ y_i y_j y_k dω`, stored sparsely, and
//! SH products: `c = a ⊛ b` with `c_k = Σ_ij G_ijk a_i b_j`, and the product ("transfer")
//! matrix `M(a)_kj = Σ_i G_ijk a_i` of Lee & Kim 2014, eq. 2.2 (after Ng et al. 2004).
//!
//! Entries are computed exactly (to rounding): the azimuthal integral of three `cos`/`sin`
//! factors in closed form (as a sum over `e^{±imφ}` terms), and the polar integral of the
//! product of three `N_l^m(cos θ)` — a polynomial in `cos θ` of degree `l1+l2+l3` whenever the
//! azimuthal selection rule leaves `|m1|+|m2|+|m3|` even — by Gauss–Legendre with enough
//! nodes to be exact. Selection rules (triangle inequality, even `l1+l2+l3`, `|m3| ∈
//! {|m1|+|m2|, ||m1|−|m2||}`) skip the zeros without evaluating them.

use crate::index::{check_len, check_order, coefficient_count, degree_and_order, index, ShError};
use crate::legendre::LegendreTable;
use crate::quadrature::gauss_legendre;
use std::f64::consts::PI;

/// Largest order for which [`GauntTensor::new`] builds a tensor (the count of non-zeros grows
/// like order⁵; order 32 has a few tens of millions).
pub const MAX_GAUNT_ORDER: usize = 32;

/// Sparse real Gaunt tensor for one order, grouped by output index `k` with `i ≤ j`.
#[derive(Clone, Debug)]
pub struct GauntTensor {
    order: usize,
    /// `starts[k]..starts[k+1]` indexes the entries of output `k`.
    starts: Vec<usize>,
    /// `(i, j)` with `i ≤ j`, as u32 pairs.
    pairs: Vec<[u32; 2]>,
    values: Vec<f64>,
}

/// `∫₀^{2π} t_{m1} t_{m2} t_{m3} dφ`, with `t_m = cos(mφ)` (m > 0), `sin(|m|φ)` (m < 0), 1 (m = 0).
#[must_use]
pub fn azimuthal_triple(m1: i64, m2: i64, m3: i64) -> f64 {
    // Each t_m = Σ α e^{ikφ}: cos → (½ at +m, ½ at −m); sin → (−i/2 at +m, +i/2 at −m).
    fn terms(m: i64) -> [(i64, (f64, f64)); 2] {
        if m == 0 {
            [(0, (1.0, 0.0)), (0, (0.0, 0.0))]
        } else if m > 0 {
            [(m, (0.5, 0.0)), (-m, (0.5, 0.0))]
        } else {
            let a = -m;
            [(a, (0.0, -0.5)), (-a, (0.0, 0.5))]
        }
    }
    let mul = |a: (f64, f64), b: (f64, f64)| (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0);
    let mut re = 0.0;
    for (k1, c1) in terms(m1) {
        for (k2, c2) in terms(m2) {
            for (k3, c3) in terms(m3) {
                if k1 + k2 + k3 == 0 {
                    re += mul(mul(c1, c2), c3).0;
                }
            }
        }
    }
    2.0 * PI * re
}

impl GauntTensor {
    /// Builds the tensor of all `i, j, k < order²` (1 ≤ order ≤ [`MAX_GAUNT_ORDER`]).
    pub fn new(order: usize) -> Result<Self, ShError> {
        check_order(order, MAX_GAUNT_ORDER)?;
        let n2 = coefficient_count(order);
        // Polar factor tables N_l^m(x_q) (m ≥ 0 slots) at GL nodes exact for degree 3(order−1).
        let nodes = (3 * (order - 1)) / 2 + 1;
        let (gx, gw) = gauss_legendre(nodes);
        let table = LegendreTable::new(order);
        let mut polar = vec![0.0; nodes * n2];
        for (q, x) in gx.iter().enumerate() {
            let s = (1.0 - x * x).max(0.0).sqrt();
            table.fill_with_sin(*x, s, &mut polar[q * n2..(q + 1) * n2]);
        }
        let polar_at = |l: usize, m: i64, q: usize| polar[q * n2 + index(l, m.abs())];
        let mut per_k: Vec<Vec<([u32; 2], f64)>> = vec![Vec::new(); n2];
        for i in 0..n2 {
            let (l1, m1) = degree_and_order(i);
            for j in i..n2 {
                let (l2, m2) = degree_and_order(j);
                let mut m3s = [
                    (m1.abs() + m2.abs()),
                    (m1.abs() - m2.abs()).abs(),
                    -(m1.abs() + m2.abs()),
                    -(m1.abs() - m2.abs()).abs(),
                ];
                m3s.sort_unstable();
                let mut last = i64::MIN;
                for &m3 in &m3s {
                    if m3 == last {
                        continue;
                    }
                    last = m3;
                    let phi = azimuthal_triple(m1, m2, m3);
                    if phi.abs() < 1e-12 {
                        continue;
                    }
                    let lmin = (l1 as i64 - l2 as i64).unsigned_abs() as usize;
                    let lmin = lmin.max(m3.unsigned_abs() as usize);
                    let lmax = (l1 + l2).min(order - 1);
                    for l3 in lmin..=lmax {
                        if (l1 + l2 + l3) % 2 == 1 {
                            continue;
                        }
                        let mut theta = 0.0;
                        for q in 0..nodes {
                            theta += gw[q]
                                * polar_at(l1, m1, q)
                                * polar_at(l2, m2, q)
                                * polar_at(l3, m3, q);
                        }
                        let g = theta * phi;
                        if g.abs() > 1e-14 {
                            per_k[index(l3, m3)].push(([i as u32, j as u32], g));
                        }
                    }
                }
            }
        }
        let mut starts = Vec::with_capacity(n2 + 1);
        let mut pairs = Vec::new();
        let mut values = Vec::new();
        starts.push(0);
        for entries in per_k {
            for (p, v) in entries {
                pairs.push(p);
                values.push(v);
            }
            starts.push(pairs.len());
        }
        Ok(Self {
            order,
            starts,
            pairs,
            values,
        })
    }

    /// Order of the tensor.
    #[must_use]
    pub fn order(&self) -> usize {
        self.order
    }

    /// Number of stored entries (`i ≤ j`; each stands for one or two products).
    #[must_use]
    pub fn nonzeros(&self) -> usize {
        self.values.len()
    }

    /// `G_ijk` for any indices below `order²` (0 outside the sparsity pattern).
    #[must_use]
    pub fn get(&self, i: usize, j: usize, k: usize) -> f64 {
        let n2 = coefficient_count(self.order);
        if i >= n2 || j >= n2 || k >= n2 {
            return 0.0;
        }
        // G is fully symmetric: look it up with k as the largest-stored output is not required,
        // any of the three can be the output.
        let (a, b) = if i <= j {
            (i as u32, j as u32)
        } else {
            (j as u32, i as u32)
        };
        let range = self.starts[k]..self.starts[k + 1];
        self.pairs[range.clone()]
            .iter()
            .position(|p| *p == [a, b])
            .map_or(0.0, |pos| self.values[range.start + pos])
    }

    /// Iterates over `(i, j, k, G)` with `i ≤ j`.
    pub fn entries(&self) -> impl Iterator<Item = (usize, usize, usize, f64)> + '_ {
        (0..self.starts.len() - 1).flat_map(move |k| {
            (self.starts[k]..self.starts[k + 1]).map(move |e| {
                (
                    self.pairs[e][0] as usize,
                    self.pairs[e][1] as usize,
                    k,
                    self.values[e],
                )
            })
        })
    }

    /// SH product projected to this order: `c_k = Σ_ij G_ijk a_i b_j`. Time ∝ non-zeros.
    pub fn product_into(&self, a: &[f64], b: &[f64], c: &mut [f64]) -> Result<(), ShError> {
        check_len(self.order, a.len())?;
        check_len(self.order, b.len())?;
        check_len(self.order, c.len())?;
        for (k, ck) in c.iter_mut().enumerate() {
            let mut acc = 0.0;
            for e in self.starts[k]..self.starts[k + 1] {
                let [i, j] = self.pairs[e];
                let (i, j) = (i as usize, j as usize);
                let prod = if i == j {
                    a[i] * b[i]
                } else {
                    a[i] * b[j] + a[j] * b[i]
                };
                acc += self.values[e] * prod;
            }
            *ck = acc;
        }
        Ok(())
    }

    /// SH product `a ⊛ b` (allocating).
    pub fn product(&self, a: &[f64], b: &[f64]) -> Result<Vec<f64>, ShError> {
        let mut c = vec![0.0; coefficient_count(self.order)];
        self.product_into(a, b, &mut c)?;
        Ok(c)
    }

    /// The `order² × order²` product matrix of `a` (row-major): `(M b)_k = (a ⊛ b)_k`.
    pub fn product_matrix(&self, a: &[f64]) -> Result<Vec<f64>, ShError> {
        check_len(self.order, a.len())?;
        let n2 = coefficient_count(self.order);
        let mut m = vec![0.0; n2 * n2];
        for k in 0..n2 {
            let row = &mut m[k * n2..(k + 1) * n2];
            for e in self.starts[k]..self.starts[k + 1] {
                let [i, j] = self.pairs[e];
                let (i, j) = (i as usize, j as usize);
                let g = self.values[e];
                row[j] += g * a[i];
                if i != j {
                    row[i] += g * a[j];
                }
            }
        }
        Ok(m)
    }
}
