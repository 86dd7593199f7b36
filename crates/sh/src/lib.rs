//! Real spherical harmonics to high order, in the convention of `CONVENTIONS.md`: real,
//! orthonormal, Condon–Shortley phase included, θ from +Z and φ = atan2(y, x), flat index
//! `l(l+1) + m`, and "order n" = n bands (`n²` coefficients).
//!
//! What it provides, each in its own module:
//! - [`Basis`]: evaluation of all `n²` functions at a direction by recurrences on normalised
//!   Legendre functions with `sin^m θ` factored out (no factorials, no division at the poles),
//!   in f64 and f32, allocation-free batch API; accurate to 1e-12 up to order 40 and finite far
//!   beyond (see `legendre`).
//! - [`project_env`]: the **exact** projection of a piecewise-constant lat-long map (per-texel
//!   integrals in closed form in φ and Gauss–Legendre to rounding in θ), angular probes by
//!   per-texel subsampling, and [`project_fn`] for functions; [`reconstruct_latlong`].
//! - [`Rotation`]: rotation of coefficient vectors by the Ivanic–Ruedenberg recurrence
//!   (J. Phys. Chem. 1996, erratum 1998), O(n³).
//! - [`zonal`]: clamped-cosine and normalised-Phong zonal lobes by a stable recurrence,
//!   rotation of zonal lobes, convolution (Ramamoorthi & Hanrahan 2001; Sloan, Kautz & Snyder
//!   2002).
//! - [`GauntTensor`]: the sparse real triple-product tensor, SH products and product matrices
//!   (Ng, Ramamoorthi & Hanrahan 2004; Lee & Kim 2014, eq. 2.2).
//! - [`window`]: Hann and Lanczos windows and a deringing search (Sloan 2008).
//! - [`irradiance`]: the 9-coefficient irradiance quadratic form of Ramamoorthi & Hanrahan 2001
//!   and irradiance at any order.
//!
//! ```
//! use prt_sh::{zonal, Basis};
//! // Lambert's band multipliers: A_0 = π, A_1 = 2π/3, A_2 = π/4.
//! let a = zonal::clamped_cosine_bands(3).unwrap();
//! assert!((a[2] - std::f64::consts::FRAC_PI_4).abs() < 1e-15);
//! let y = Basis::new(64).unwrap().eval(glam::DVec3::new(0.3, -0.2, 0.9));
//! assert_eq!(y.len(), 4096);
//! ```

mod eval;
mod gaunt;
mod index;
pub mod irradiance;
mod legendre;
mod project;
pub mod quadrature;
mod rotate;
pub mod window;
pub mod zonal;

pub use eval::{
    eval_basis, eval_low_f32, reconstruct, BandCursor, Basis, BAND_CURSOR_MAX_ORDER, LOW_BANDS,
};
pub use gaunt::{azimuthal_triple, GauntTensor, MAX_GAUNT_ORDER};
pub use index::{check_order, coefficient_count, degree_and_order, index, ShError, MAX_ORDER};
pub use legendre::LegendreTable;
pub use project::{
    latlong_frame, nodes_for_trig_degree, project_env, project_fn, reconstruct_latlong,
    reconstruct_rgb, EnvMapping, ImageRef, RgbCoefficients, MAX_ANGULAR_SUBSAMPLES,
};
pub use rotate::Rotation;
