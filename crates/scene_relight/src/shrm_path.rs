//! The `--glossy shrm` path: an object's glossy specular looked up in a spherical harmonic
//! reflection map ([`crate::shrm`]) prefiltered once per distinct environment and lobe (a
//! rotation of the environment is a rotated lookup), times a specular-occlusion factor from
//! the bake's visibility transfer.
//!
//! **The occlusion is an approximation.** The SHRM integrates the unoccluded environment to
//! the order the lobe needs; the bake's visibility is known only to its own order. A point's
//! factor is the luminance ratio of the fitted lobe's lighting with and without the baked
//! visibility at the bake's order, `k = lum(Σ w (L ⊛ V)) / lum(Σ w L)` clamped to `[0, 1]`
//! (1 where the unshadowed value is not positive): the share of the lobe-weighted light the
//! point's self-occlusion removes, as a blurred lobe sees it, applied to the sharp lobe's
//! value. (The lobe-weighted visibility alone, `Σ w V / ∫ w H_n`, measured worse on the bunny
//! — 27.8 against 39.8 dB for gold at roughness 0.8 — as it darkens a lobe for blocked
//! directions that hold little light.)

use crate::error::SceneRelightError;
use crate::shrm::{lobe_spectrum, LobeSpectrum, Shrm, ShrmLobe};
use glam::{DMat3, DVec3};
use prt_scene::{Mapping, Scene};
use rayon::prelude::*;
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Instant;

/// Relative RMS shading error (over the lighting's rotations, view elevations and components;
/// `LobeSpectrum::shading_error`) the SHRM's order and twist are chosen for: half of it to
/// each. 1 % of the specular keeps a bright highlight's error near the 40 dB of an 8-bit image.
pub const SHRM_SHADING_TOLERANCE: f64 = 0.01;
/// Largest SH order an SHRM is prefiltered at (a roughness-0.1 glTF lobe would want more).
pub const SHRM_MAX_ORDER: usize = 64;
/// Largest twist Fourier degree.
pub const SHRM_MAX_TWIST: usize = 8;
/// Tabulated view elevations.
pub const SHRM_ELEVATIONS: usize = 16;
/// Grid rows per band of the chosen order: `rows = k·L + 1` over `θ_R ∈ [0, π]`, `2(rows − 1)`
/// columns. Bilinear interpolation of band `l` at spacing `h = π/(kL)` errs by about
/// `(l h)²/8` of that band's amplitude: 3 % at `l = L/2`, 14 % at `l = L` for `k = 3`, where
/// the lobe's coefficients have fallen to the tolerance.
pub const SHRM_ROWS_PER_BAND: usize = 3;

/// A prefiltered SHRM and how it was made.
pub(crate) struct Prefiltered {
    pub(crate) shrm: Shrm,
    /// What to say of it (order, twist, grid, cost).
    pub(crate) note: String,
}

type Key = (String, u32, u64);
/// The process's SHRMs by lobe and environment.
type Cache = Mutex<Vec<(Key, Arc<Prefiltered>)>>;

/// The SHRM of `lobe` under the scene's environment (or `lighting`, coefficients given to the
/// run), built once per process per (lobe, environment).
///
/// # Errors
/// A projection or prefilter the SH code refuses.
pub(crate) fn prefiltered(
    scene: &Scene,
    lobe: ShrmLobe,
    lighting: Option<&[[f64; 3]]>,
) -> Result<Arc<Prefiltered>, SceneRelightError> {
    static CACHE: OnceLock<Cache> = OnceLock::new();
    let cache = CACHE.get_or_init(|| Mutex::new(Vec::new()));
    let env = &scene.environment;
    let bytes: Vec<u8> = match lighting {
        Some(l) => l.iter().flatten().flat_map(|v| v.to_le_bytes()).collect(),
        None => env
            .image
            .texels
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect(),
    };
    let key: Key = (
        format!(
            "{lobe:?} {} {:?}",
            env.image.width,
            lighting.map(<[_]>::len)
        ),
        crc32fast::hash(&bytes),
        env.rotation_y_deg.to_bits(),
    );
    if let Ok(c) = cache.lock() {
        if let Some((_, p)) = c.iter().find(|(k, _)| *k == key) {
            return Ok(p.clone());
        }
    }
    let start = Instant::now();
    let full = lobe_spectrum(lobe, SHRM_MAX_ORDER, SHRM_MAX_TWIST, SHRM_ELEVATIONS)?;
    // The lighting to the largest order, whose spectrum (with the lobe's) sets the order.
    let mut coeffs = match lighting {
        Some(l) => l.to_vec(),
        None => {
            let mapping = match env.mapping {
                Mapping::LatLong => prt_sh::EnvMapping::LatLong,
                Mapping::Angular => prt_sh::EnvMapping::Angular { subsamples: 4 },
            };
            let img = prt_sh::ImageRef {
                width: env.image.width,
                height: env.image.height,
                texels: &env.image.texels,
            };
            prt_sh::project_env(img, mapping, SHRM_MAX_ORDER, env.rotation_y_deg)?
        }
    };
    let available = ((coeffs.len() as f64).sqrt() as usize).min(SHRM_MAX_ORDER);
    let power = LobeSpectrum::band_power(&coeffs, available);
    let (order, twist) = full.choose(SHRM_SHADING_TOLERANCE, &power);
    coeffs.truncate(order * order);
    let error = full.shading_error(order, twist, &power);
    let spectrum = full.truncated(order, twist);
    let t_project = start.elapsed().as_secs_f64();
    let rows = SHRM_ROWS_PER_BAND * order + 1;
    let shrm = Shrm::prefilter(&spectrum, &coeffs, rows, 2 * (rows - 1))?;
    let note = format!(
        "SHRM of {lobe:?}: order {order}, twist {twist} (shading error {:.2} % ≤ {:.0} % under this lighting's spectrum; the lobe alone {:.1} %), {rows} × {} × {} table, lobe + environment projected in {:.0} ms, prefiltered in {:.0} ms (once per environment; a rotation is a rotated lookup)",
        100.0 * error,
        100.0 * SHRM_SHADING_TOLERANCE,
        100.0 * full.truncation_error(order, twist),
        2 * (rows - 1),
        SHRM_ELEVATIONS,
        1e3 * t_project,
        1e3 * (start.elapsed().as_secs_f64() - t_project)
    );
    let p = Arc::new(Prefiltered { shrm, note });
    if let Ok(mut c) = cache.lock() {
        c.push((key, p.clone()));
    }
    Ok(p)
}

/// The SHRM specular of points (`positions`, `normals`) seen from `eye` under the environment
/// rotated by `rotate_y_deg` about +Y: per channel `k · Σ_q w_q,c S_q,c` with the colour
/// weights `colour[q]` (one or one per point) and the occlusion factor `k` (per point).
#[allow(clippy::too_many_arguments)]
pub(crate) fn shade(
    shrm: &Shrm,
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    eye: [f32; 3],
    rotate_y_deg: f64,
    colour: [&[[f32; 3]]; 2],
    occlusion: &[f32],
) -> Vec<[f32; 3]> {
    let q = (rotate_y_deg != 0.0).then(|| DMat3::from_rotation_y(rotate_y_deg.to_radians()));
    let eye = DVec3::from_array(eye.map(f64::from));
    (0..normals.len())
        .into_par_iter()
        .map(|p| {
            let n = DVec3::from_array(normals[p].map(f64::from)).normalize_or_zero();
            let wo = (eye - DVec3::from_array(positions[p].map(f64::from))).normalize_or_zero();
            let s = shrm.lookup(n, wo, q.as_ref());
            let k = f64::from(occlusion[p]);
            std::array::from_fn(|c| {
                let mut v = 0.0;
                for (qi, w) in colour.iter().enumerate().take(shrm.components) {
                    let w = if w.len() == 1 { w[0] } else { w[p] };
                    v += f64::from(w[c]) * s[qi][c];
                }
                (k * v).max(0.0) as f32
            })
        })
        .collect()
}
