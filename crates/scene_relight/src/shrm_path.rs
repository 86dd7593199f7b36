//! The `--glossy shrm` path: an object's glossy specular looked up in a spherical harmonic
//! reflection map ([`crate::shrm`]) prefiltered once per distinct environment and lobe (a
//! rotation of the environment is a rotated lookup), times a specular-occlusion factor.
//!
//! **The occlusion.** The SHRM integrates the unoccluded environment to the order the lobe
//! needs. For a per-vertex bake relit at every vertex under the scene's environment the
//! factor is the sharp lobe's own traced visibility ([`crate::shrm_occlusion`]), per channel.
//! Otherwise (per-pixel or per-texel bakes, subsets, lighting given as coefficients) it falls
//! back to the bake's visibility, known only to its order: the luminance ratio of the fitted
//! lobe's lighting with and without it, `k = lum(Σ w (L ⊛ V)) / lum(Σ w L)` clamped to
//! `[0, 1]` (1 where the unshadowed value is not positive) — an approximation that measured
//! 27.6 dB against 45.1 for the traced factor on the gold bunny at roughness 0.4
//! (crates/relight/README.md).
//!
//! **Image formation.** Per-vertex results keep their lookups' inputs ([`ShrmSpecular`]) so
//! that image formation can look the SHRM up at a sub-pixel sample's interpolated normal and
//! position: interpolating per-vertex lookups (Gouraud) flattens highlights that vary inside
//! a pixel (46.6 against 41.5 dB unshadowed on the same bunny). It does so on triangles whose
//! vertex lookups disagree by more than 40 % and interpolates the others (`imaging.rs`,
//! `SHRM_GOURAUD_SPREAD`: 43.9 against 44.9 dB shadowed, at about two thirds of the frame).

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
    pub(crate) shrm: Arc<Shrm>,
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
    let p = Arc::new(Prefiltered {
        shrm: Arc::new(shrm),
        note,
    });
    if let Ok(mut c) = cache.lock() {
        c.push((key, p.clone()));
    }
    Ok(p)
}

/// The SHRM specular of points (`positions`, `normals`) seen from `eye` under the environment
/// rotated by `rotate_y_deg` about +Y: per channel `k · Σ_q w_q,c S_q,c` with the colour
/// weights `colour[q]` (one or one per point) and the occlusion factor `k` (per point and
/// channel).
pub(crate) fn shade(
    shrm: &Shrm,
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    view: (DVec3, Option<DMat3>),
    colour: [&[[f32; 3]]; 2],
    occlusion: &[[f32; 3]],
) -> Vec<[f32; 3]> {
    (0..normals.len())
        .into_par_iter()
        .map(|p| {
            let w = colour.map(|w| if w.len() == 1 { w[0] } else { w[p] });
            specular_at(
                shrm,
                DVec3::from_array(normals[p].map(f64::from)),
                DVec3::from_array(positions[p].map(f64::from)),
                view,
                w,
                occlusion[p],
            )
        })
        .collect()
}

/// The SHRM's first component at each point (`positions`, `normals`): the lobe with unit
/// colour (`D·V` of the glTF metal, the unit-specular lobe of the others) integrated against
/// the unoccluded environment, per channel.
pub(crate) fn lobe_integral(
    shrm: &Shrm,
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    (eye, q): (DVec3, Option<DMat3>),
) -> Vec<[f64; 3]> {
    (0..normals.len())
        .into_par_iter()
        .map(|p| {
            let n = DVec3::from_array(normals[p].map(f64::from)).normalize_or_zero();
            let x = DVec3::from_array(positions[p].map(f64::from));
            shrm.lookup(n, (eye - x).normalize_or_zero(), q.as_ref())[0]
        })
        .collect()
}

/// The eye and the environment's rotation (`None` for none) of a lookup under the environment
/// turned by `rotate_y_deg` about +Y.
pub(crate) fn view(eye: [f32; 3], rotate_y_deg: f64) -> (DVec3, Option<DMat3>) {
    (
        DVec3::from_array(eye.map(f64::from)),
        (rotate_y_deg != 0.0).then(|| DMat3::from_rotation_y(rotate_y_deg.to_radians())),
    )
}

/// One point's SHRM specular: `k · Σ_q w_q,c S_q,c(n, ω_o)` at normal `n` (normalised here)
/// and position `p`, `ω_o` toward the eye; 0 where the normal faces away from it.
fn specular_at(
    shrm: &Shrm,
    n: DVec3,
    p: DVec3,
    (eye, q): (DVec3, Option<DMat3>),
    colour: [[f32; 3]; 2],
    occlusion: [f32; 3],
) -> [f32; 3] {
    let s = shrm.lookup(
        n.normalize_or_zero(),
        (eye - p).normalize_or_zero(),
        q.as_ref(),
    );
    std::array::from_fn(|c| {
        let v: f64 = (0..shrm.components)
            .map(|qi| f64::from(colour[qi][c]) * s[qi][c])
            .sum();
        (f64::from(occlusion[c]) * v).max(0.0) as f32
    })
}

/// An object's `--glossy shrm` specular kept for image formation ([`crate::Relit::shrm`]):
/// what a sub-pixel ray's hit needs to look the SHRM up at its own interpolated normal and
/// position instead of interpolating the vertices' looked-up values (Gouraud), which flattens
/// a highlight narrower than a triangle. The per-vertex factors (occlusion, colour weights)
/// and the rest of the radiance are interpolated; only the lookup is per sample.
#[derive(Clone, Debug)]
pub struct ShrmSpecular {
    table: Arc<Shrm>,
    /// Colour weights per component: one, or one per vertex.
    colour: [Vec<[f32; 3]>; 2],
    /// The specular-occlusion factor `k` per vertex and channel.
    occlusion: Vec<[f32; 3]>,
    /// Per vertex, the radiance without the SHRM specular (the diffuse term).
    rest: Vec<[f32; 3]>,
    eye: DVec3,
    rotation: Option<DMat3>,
}

impl ShrmSpecular {
    pub(crate) fn new(
        table: Arc<Shrm>,
        colour: [Vec<[f32; 3]>; 2],
        occlusion: Vec<[f32; 3]>,
        rest: Vec<[f32; 3]>,
        (eye, rotation): (DVec3, Option<DMat3>),
    ) -> Self {
        Self {
            table,
            colour,
            occlusion,
            rest,
            eye,
            rotation,
        }
    }

    /// The same with the occlusion factor 1 everywhere: the unshadowed SHRM specular (for
    /// measuring the occlusion's share of an error against an unshadowed render).
    #[must_use]
    pub fn unoccluded(&self) -> Self {
        Self {
            occlusion: vec![[1.0; 3]; self.occlusion.len()],
            ..self.clone()
        }
    }

    /// The specular-occlusion factor `k` of each vertex, per channel.
    #[must_use]
    pub fn occlusion(&self) -> &[[f32; 3]] {
        &self.occlusion
    }

    /// The per-vertex radiance (rest plus the SHRM specular looked up at each vertex): what
    /// Gouraud image formation interpolates.
    #[must_use]
    pub fn vertex_radiance(&self, mesh: &prt_scene::Mesh) -> Vec<[f32; 3]> {
        (0..self.rest.len())
            .into_par_iter()
            .map(|v| {
                let s = specular_at(
                    &self.table,
                    mesh.normals[v].normalize_or(glam::Vec3::Y).as_dvec3(),
                    mesh.positions[v].as_dvec3(),
                    (self.eye, self.rotation),
                    self.colour.each_ref().map(|w| pick(w, v)),
                    self.occlusion[v],
                );
                std::array::from_fn(|c| self.rest[v][c] + s[c])
            })
            .collect()
    }

    /// The radiance at barycentrics `(u, v)` of triangle `tri` of `mesh` (the object's): the
    /// rest, occlusion and colour weights interpolated from the vertices, the SHRM looked up
    /// at the interpolated normal and position.
    #[must_use]
    pub fn at(&self, mesh: &prt_scene::Mesh, tri: usize, u: f32, v: f32) -> [f32; 3] {
        let mut sum = LookupSum::default();
        let rest = self.add_sample(mesh, tri, u, v, &mut sum);
        let s = self.lookup_sum(&sum);
        std::array::from_fn(|c| rest[c] + s[c])
    }

    /// Adds the lookup inputs interpolated at barycentrics `(u, v)` of triangle `tri` (normal,
    /// position, occlusion, colour weights) to `sum`, and returns the rest of the radiance
    /// there (interpolated).
    pub(crate) fn add_sample(
        &self,
        mesh: &prt_scene::Mesh,
        tri: usize,
        u: f32,
        v: f32,
        sum: &mut LookupSum,
    ) -> [f32; 3] {
        let idx = mesh.indices[tri].map(|i| i as usize);
        let wts = [1.0 - u - v, u, v];
        let (mut n, mut p, mut k) = (DVec3::ZERO, DVec3::ZERO, [0.0f32; 3]);
        let mut colour = [[0.0f32; 3]; 2];
        let mut rest = [0.0f32; 3];
        for (&i, wt) in idx.iter().zip(wts) {
            let w = f64::from(wt);
            n += w * mesh.normals[i].normalize_or(glam::Vec3::Y).as_dvec3();
            p += w * mesh.positions[i].as_dvec3();
            (0..3).for_each(|ch| k[ch] += wt * self.occlusion[i][ch]);
            for (q, cq) in colour.iter_mut().enumerate() {
                let c = pick(&self.colour[q], i);
                (0..3).for_each(|ch| cq[ch] += wt * c[ch]);
            }
            (0..3).for_each(|ch| rest[ch] += wt * self.rest[i][ch]);
        }
        sum.n += n;
        sum.p += p;
        (0..3).for_each(|ch| sum.k[ch] += k[ch]);
        for (s, c) in sum.colour.iter_mut().zip(colour) {
            (0..3).for_each(|ch| s[ch] += c[ch]);
        }
        sum.count += 1;
        rest
    }

    /// The SHRM specular at the mean of `sum`'s samples (normal, position, occlusion, colour
    /// weights) times their count: one lookup for all of a pixel's samples on this object.
    pub(crate) fn lookup_sum(&self, sum: &LookupSum) -> [f32; 3] {
        if sum.count == 0 {
            return [0.0; 3];
        }
        let m = f64::from(sum.count);
        let mf = sum.count as f32;
        let s = specular_at(
            &self.table,
            sum.n,
            sum.p / m,
            (self.eye, self.rotation),
            sum.colour.map(|c| c.map(|x| x / mf)),
            sum.k.map(|x| x / mf),
        );
        s.map(|x| x * mf)
    }
}

/// A pixel's samples on one object, summed for one lookup at their mean
/// ([`ShrmSpecular::add_sample`], [`ShrmSpecular::lookup_sum`]): interpolated normals (the
/// lookup normalises their sum), positions, occlusion and colour weights.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct LookupSum {
    n: DVec3,
    p: DVec3,
    k: [f32; 3],
    colour: [[f32; 3]; 2],
    count: u32,
}

/// Weight `i` of a list holding one for all points or one per point.
fn pick(w: &[[f32; 3]], i: usize) -> [f32; 3] {
    if w.len() == 1 {
        w[0]
    } else {
        w.get(i).copied().unwrap_or([0.0; 3])
    }
}
