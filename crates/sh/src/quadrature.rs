//! Gauss–Legendre rules and exact product quadrature on the sphere.

use glam::DVec3;
use std::f64::consts::PI;

/// Gauss–Legendre nodes and weights on `[-1, 1]` (exact for polynomials of degree `2n − 1`).
///
/// Nodes by Newton iteration on the three-term recurrence from Tricomi's initial guesses;
/// converged to rounding for every `n` used here (checked by integrating monomials in tests).
#[must_use]
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut nodes = vec![0.0; n];
    let mut weights = vec![0.0; n];
    let nf = n as f64;
    for k in 0..n.div_ceil(2) {
        // Tricomi's approximation of the k-th root (descending).
        let theta = PI * (4.0 * k as f64 + 3.0) / (4.0 * nf + 2.0);
        let mut x = (1.0 - (nf - 1.0) / (8.0 * nf * nf * nf)) * theta.cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (p, d) = legendre_and_derivative(n, x);
            dp = d;
            let dx = p / d;
            x -= dx;
            if dx.abs() < 1e-16 {
                let (_, d) = legendre_and_derivative(n, x);
                dp = d;
                break;
            }
        }
        nodes[k] = x;
        nodes[n - 1 - k] = -x;
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        weights[k] = w;
        weights[n - 1 - k] = w;
    }
    if n % 2 == 1 {
        nodes[n / 2] = 0.0;
    }
    (nodes, weights)
}

fn legendre_and_derivative(n: usize, x: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, x);
    if n == 0 {
        return (1.0, 0.0);
    }
    for k in 2..=n {
        let kf = k as f64;
        let p2 = ((2.0 * kf - 1.0) * x * p1 - (kf - 1.0) * p0) / kf;
        p0 = p1;
        p1 = p2;
    }
    let d = n as f64 * (x * p1 - p0) / (x * x - 1.0);
    (p1, d)
}

/// A product rule on the sphere: Gauss–Legendre in `z = cos θ` times uniform `φ`.
///
/// With `n` GL nodes and `2n` azimuths it integrates every spherical polynomial of degree
/// `≤ 2n − 1` exactly (up to rounding). Weights sum to `4π`.
#[derive(Clone, Debug)]
pub struct SphereQuadrature {
    /// Unit directions.
    pub dirs: Vec<DVec3>,
    /// Solid-angle weights.
    pub weights: Vec<f64>,
}

impl SphereQuadrature {
    /// Rule exact for spherical polynomials up to `degree`.
    #[must_use]
    pub fn exact_for_degree(degree: usize) -> Self {
        let n = degree / 2 + 1;
        let (z, w) = gauss_legendre(n);
        let m = 2 * n;
        let mut dirs = Vec::with_capacity(n * m);
        let mut weights = Vec::with_capacity(n * m);
        for (zi, wi) in z.iter().zip(&w) {
            let s = (1.0 - zi * zi).max(0.0).sqrt();
            for j in 0..m {
                let phi = 2.0 * PI * (j as f64 + 0.5) / m as f64;
                dirs.push(DVec3::new(s * phi.cos(), s * phi.sin(), *zi));
                weights.push(wi * 2.0 * PI / m as f64);
            }
        }
        Self { dirs, weights }
    }
}
