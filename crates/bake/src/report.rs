//! What a bake returns besides its file: the figures its log and `--json` output show.

use prt_bakefile::{Bake, Decision};
use serde::Serialize;

/// What a bake measured, for the log and `--json` output.
#[derive(Clone, Debug, Serialize)]
pub struct BakeReport {
    /// One entry per object.
    pub objects: Vec<ObjectReport>,
    /// Rays traced in all.
    pub rays_traced: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Every decision the baker made, with its reason.
    pub decisions: Vec<Decision>,
}

/// Per-object figures.
#[derive(Clone, Debug, Serialize)]
pub struct ObjectReport {
    /// Object name.
    pub name: String,
    /// Order baked.
    pub order: usize,
    /// Points baked (in this shard).
    pub points: u64,
    /// Fraction of diffuse rays that hit the scene.
    pub hit_fraction: f64,
    /// Fraction of diffuse rays that hit the back of a surface.
    pub backface_fraction: f64,
    /// Fraction of diffuse rays traced from points more than half of whose rays hit the back
    /// of a surface: rays started inside geometry.
    pub inside_fraction: f64,
    /// Transfer kinds stored.
    pub kinds: Vec<String>,
}

/// A bake and its report.
#[derive(Clone, Debug)]
pub struct BakeOutput {
    /// What goes into the file.
    pub bake: Bake,
    /// What the log shows.
    pub report: BakeReport,
}
