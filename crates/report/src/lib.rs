//! Speed-against-error reports (`prt report`): the experiments that answer "how much accuracy
//! does the faster method give away, and how much time does it save?" and their presentation.
//! [`report`] renders the path-traced reference to a noise target, bakes, relights at every
//! order with full-order and locally adaptive SH (Sloan, Kautz & Snyder 2002; Lee & Kim 2014,
//! through `prt-scene-relight`) and measures each against the reference; [`budget`] splits
//! each order's error into its causes by controlled experiments (SH truncation, interpolation,
//! bake noise, model, reference noise); [`rf_section`] adds reflectance fields (Masselus et al.
//! 2004, through `prt-fields`); [`recommend`] measures each object's error per order from one
//! bake, behind `prt bake --target-psnr`; [`plots`] and [`viewer`] write the figures and the
//! self-contained interactive HDR page.

mod bakes;
pub mod budget;
mod cache;
mod data;
mod error;
mod figures;
mod live;
mod machine;
mod markdown;
mod orders;
mod outputs;
pub mod plots;
pub mod recommend;
mod reference;
pub mod report;
pub mod rf_section;
mod run;
pub mod viewer;

pub use error::ReportError;
pub use report::{run_report, ObjectRays, ReferenceInfo, ReportData, ReportSettings};
