//! Inverse lighting and BRDF together (Ramamoorthi & Hanrahan 2001, §6 of Ramamoorthi's
//! thesis): the lighting of [`crate::inverse`] and one material's albedo (per channel) and,
//! for Phong, its exponent.
//!
//! Given the material, the image is linear in the lighting; given the lighting and exponent, it is
//! linear in the albedo (`I = a ⊙ D·L + S_e·L` on the material's pixels, `D` the diffuse transfer at
//! unit albedo, `S_e` the specular at exponent `e`); the exponent enters through the Phong
//! lobe relighting shades with the options' [`crate::PhongModel`] (by default the lobe with the
//! light's cosine inside, fitted per view elevation at each exponent tried; the fitted tables
//! are cached per exponent and order). So at each exponent the
//! fit searches the albedo (golden section per channel) with the lighting solved for each
//! albedo (variable projection), and searches the exponent by golden section on `ln e`.
//!
//! **The scale ambiguity.** An image determines `albedo × lighting`, not each: scaling the
//! lighting by `k` and every reflectance by `1/k` gives the same image. What fixes the scale
//! here, said in the result: the objects of *other* (known) materials in the image, when there
//! are any (a light probe, as the thesis uses a known object), and for Phong the material's
//! `specular`, held at the scene's value (the albedo is then fitted relative to it: the image
//! determines the diffuse/specular ratio through their different frequency content). A
//! Lambertian material alone in the image has no scale: the fit refuses it.

use crate::bound::Bound;
use crate::error::SceneRelightError;
use crate::imaging::{object_ids, RgbImage};
use crate::inverse::{
    basis_images, conditioning, model_order, prepare_pixels, well_determined, FitOptions,
};
use nalgebra::{DMatrix, DVector};
use prt_scene::{Material, Scene};
use serde::Serialize;

/// The fitted material (with the lighting of [`crate::inverse::fit_lighting`] beside it).
#[derive(Clone, Debug, Serialize)]
pub struct MaterialFit {
    /// The material's name.
    pub material: String,
    /// Its fitted albedo (diffuse reflectance), per channel.
    pub albedo: [f64; 3],
    /// Its fitted Phong exponent (Phong materials).
    pub exponent: Option<f64>,
    /// What fixes the albedo × lighting scale.
    pub scale_fixed_by: String,
    /// The fitted lighting at the options' order, rows `[r, g, b]`.
    pub coefficients: Vec<[f64; 3]>,
    /// Bands the image determines at the fitted material.
    pub well_determined: usize,
    /// `‖residual‖ / ‖image‖` over the fitted pixels (weighted).
    pub relative_residual: f64,
    /// Exponents tried by the search, with their relative residual.
    pub search: Vec<[f64; 2]>,
}

/// The scene with material `index` replaced by `m`.
fn with_material(scene: &Scene, index: usize, m: Material) -> Scene {
    let mut s = scene.clone();
    s.materials[index] = m;
    s
}

/// One channel's normal equations, split by rows: the other objects' (`o`, diffuse as they
/// are) and the material's (`n`: diffuse at unit albedo `D`, specular `S`). At albedo `a` the
/// material's rows are `a D + S`, so every product the fit needs is a 2 × 2 combination of
/// these, formed once per exponent.
struct Gram {
    oo: DMatrix<f64>,
    dd: DMatrix<f64>,
    ds: DMatrix<f64>,
    ss: DMatrix<f64>,
    ob: DVector<f64>,
    db: DVector<f64>,
    sb: DVector<f64>,
    bb: f64,
    rows: usize,
}

impl Gram {
    fn new(d: &DMatrix<f64>, s: Option<&DMatrix<f64>>, b: &DVector<f64>, on: &[bool]) -> Self {
        let pick = |m: &DMatrix<f64>, want: bool| {
            let rows: Vec<usize> = (0..on.len()).filter(|&r| on[r] == want).collect();
            m.select_rows(rows.iter())
        };
        let (d_o, d_n) = (pick(d, false), pick(d, true));
        let bv = DMatrix::from_column_slice(b.len(), 1, b.as_slice());
        let (b_o, b_n) = (pick(&bv, false), pick(&bv, true));
        let s_n = s.map_or_else(
            || DMatrix::zeros(d_n.nrows(), d_n.ncols()),
            |s| pick(s, true),
        );
        Self {
            oo: d_o.tr_mul(&d_o),
            dd: d_n.tr_mul(&d_n),
            ds: d_n.tr_mul(&s_n),
            ss: s_n.tr_mul(&s_n),
            ob: d_o.tr_mul(&b_o).column(0).into_owned(),
            db: d_n.tr_mul(&b_n).column(0).into_owned(),
            sb: s_n.tr_mul(&b_n).column(0).into_owned(),
            bb: b.norm_squared(),
            rows: b.len(),
        }
    }

    /// `AᵀA` and `Aᵀb` at albedo `a`.
    fn at(&self, a: f64) -> (DMatrix<f64>, DVector<f64>) {
        let g = &self.oo + &self.dd * (a * a) + (&self.ds + self.ds.transpose()) * a + &self.ss;
        (g, &self.ob + &self.db * a + &self.sb)
    }

    /// `‖A x − b‖²` at albedo `a`.
    fn residual2(&self, a: f64, x: &DVector<f64>) -> f64 {
        let (g, r) = self.at(a);
        (self.bb - 2.0 * x.dot(&r) + x.dot(&(g * x))).max(0.0)
    }

    /// The lighting at albedo `a`: the regularised solve of [`crate::inverse`] (bands
    /// `≥ well` under the prior, two rounds; truncation at `limit`) on the normal equations
    /// (eigenvalues below `λ_max / limit²` dropped).
    fn lighting(&self, a: f64, well: usize, limit: f64) -> DVector<f64> {
        let (g, r) = self.at(a);
        let cols = g.ncols();
        let model = (cols as f64).sqrt().round() as usize;
        let solve = |damping: &[f64]| {
            let mut h = g.clone();
            for (i, d) in damping.iter().enumerate() {
                h[(i, i)] += d * d;
            }
            let eig = h.symmetric_eigen();
            let cutoff = eig.eigenvalues.max() / (limit * limit);
            let mut x = DVector::zeros(cols);
            for (k, &l) in eig.eigenvalues.iter().enumerate() {
                if l > cutoff {
                    let v = eig.eigenvectors.column(k);
                    x += v * (v.dot(&r) / l);
                }
            }
            x
        };
        let mut damping = vec![0.0; cols];
        let mut x = solve(&damping);
        if well >= model {
            return x;
        }
        for _ in 0..2 {
            let dof = self.rows.saturating_sub(cols).max(1) as f64;
            let noise = (self.residual2(a, &x) / dof).sqrt();
            let top = well.max(1);
            let s2 = (0..top * top)
                .map(|i| {
                    let l = (i as f64).sqrt().floor() + 1.0;
                    l * l * x[i] * x[i]
                })
                .sum::<f64>()
                / (top * top) as f64;
            if s2 <= 0.0 {
                break;
            }
            for (i, d) in damping.iter_mut().enumerate().skip(well * well) {
                *d = noise * ((i as f64).sqrt().floor() + 1.0) / s2.sqrt();
            }
            x = solve(&damping);
        }
        x
    }
}

/// At one exponent, per channel: the albedo by golden section on `[0, 2]` of the residual
/// minimised over the lighting (linear given the albedo: variable projection), the lighting
/// over the model's bands, and the total squared residual.
fn fit_at_exponent(
    grams: &[Gram; 3],
    well: usize,
    limit: f64,
) -> ([f64; 3], Vec<DVector<f64>>, f64) {
    let mut albedo = [0.0; 3];
    let mut lights = Vec::new();
    let mut total = 0.0;
    for (c, gram) in grams.iter().enumerate() {
        let cost = |a: f64| gram.residual2(a, &gram.lighting(a, well, limit));
        let a = golden_scalar(&cost, 0.0, 2.0, 1e-6);
        let x = gram.lighting(a, well, limit);
        total += gram.residual2(a, &x);
        albedo[c] = a;
        lights.push(x);
    }
    (albedo, lights, total)
}

/// The minimiser of `f` on `[lo, hi]` by golden section to a bracket of `tol`.
fn golden_scalar(f: &dyn Fn(f64) -> f64, mut lo: f64, mut hi: f64, tol: f64) -> f64 {
    let phi = (5f64.sqrt() - 1.0) / 2.0;
    let (mut x1, mut x2) = (hi - phi * (hi - lo), lo + phi * (hi - lo));
    let (mut f1, mut f2) = (f(x1), f(x2));
    while hi - lo > tol {
        if f1 <= f2 {
            (hi, x2, f2) = (x2, x1, f1);
            x1 = hi - phi * (hi - lo);
            f1 = f(x1);
        } else {
            (lo, x1, f1) = (x1, x2, f2);
            x2 = lo + phi * (hi - lo);
            f2 = f(x2);
        }
    }
    0.5 * (lo + hi)
}

/// Fits the lighting and material `name`'s albedo (and Phong exponent) to `image`.
///
/// # Errors
/// An unknown material, one that is neither `lambert` nor `phong`, a Lambertian material with
/// nothing in the image to fix the scale, no pixel of the material, and the errors of
/// [`crate::inverse::fit_lighting`].
pub fn fit_material(
    bound: &Bound,
    image: &RgbImage,
    name: &str,
    opt: &FitOptions,
) -> Result<MaterialFit, SceneRelightError> {
    let scene = bound.scene();
    let index = scene
        .material_names
        .iter()
        .position(|n| n == name)
        .ok_or_else(|| {
            SceneRelightError::Invalid(format!(
                "no material named {name:?} (the scene has {})",
                scene.material_names.join(", ")
            ))
        })?;
    let specular = match scene.materials[index] {
        Material::Lambert { .. } => None,
        Material::Phong { specular, .. } => Some(specular),
        _ => {
            return Err(SceneRelightError::Invalid(format!(
                "material {name:?}: --fit-material fits lambert and phong materials"
            )))
        }
    };
    let model = model_order(bound, opt)?;
    let (pixels, sqrt_w, b) =
        prepare_pixels(bound, image, opt.weights.as_deref(), opt.max_occlusion)?;
    let ids = object_ids(scene, bound.accel())?;
    let on_material: Vec<bool> = pixels
        .iter()
        .map(|&p| ids[p].is_some_and(|o| scene.meshes[o].material == index))
        .collect();
    let on = on_material.iter().filter(|&&x| x).count();
    if on == 0 {
        return Err(SceneRelightError::Invalid(format!(
            "material {name:?} covers no fitted pixel"
        )));
    }
    let probe = on < pixels.len();
    let scale_fixed_by = match (probe, specular) {
        (true, _) => "the objects of other (known) materials in the image".to_string(),
        (false, Some(s)) => format!("the material's specular, held at {s:?}"),
        (false, None) => {
            return Err(SceneRelightError::Invalid(format!(
                "material {name:?} is Lambertian and alone in the image: albedo × lighting is all \
                 the image determines; add an object of known material (a probe) to fix the scale"
            )))
        }
    };
    // The diffuse part at unit albedo (other objects as they are); it does not depend on the
    // exponent.
    let basis = |m: Material| -> Result<[DMatrix<f64>; 3], SceneRelightError> {
        let s = with_material(scene, index, m);
        let bd = Bound::new(&s, bound.accel(), bound.bake())?;
        basis_images(&bd, &pixels, &sqrt_w, model, opt.phong)
    };
    let d = basis(Material::Lambert { albedo: [1.0; 3] })?;
    let b2: f64 = b.iter().map(DVector::norm_squared).sum();
    let rel = |r2: f64| if b2 > 0.0 { (r2 / b2).sqrt() } else { 0.0 };
    let (cond, gain) = conditioning(&d, model);
    let well = well_determined(&cond, &gain, opt.condition_limit, opt.min_gain).min(opt.order);
    let mut search = Vec::new();
    let (albedo, lights, r2, exponent) = match specular {
        None => {
            let grams = [0, 1, 2].map(|c| Gram::new(&d[c], None, &b[c], &on_material));
            let (a, l, r2) = fit_at_exponent(&grams, well, opt.condition_limit);
            (a, l, r2, None)
        }
        Some(spec) => {
            let mut eval = |ln_e: f64| -> Result<_, SceneRelightError> {
                let e = ln_e.exp();
                let s = basis(Material::Phong {
                    albedo: [0.0; 3],
                    specular: spec,
                    exponent: e as f32,
                })?;
                let grams = [0, 1, 2].map(|c| Gram::new(&d[c], Some(&s[c]), &b[c], &on_material));
                let (a, l, r2) = fit_at_exponent(&grams, well, opt.condition_limit);
                search.push([e, rel(r2)]);
                Ok((a, l, r2, Some(e)))
            };
            golden(&mut eval, 0.0, 1000f64.ln(), 1e-3)?
        }
    };
    let n2 = opt.order * opt.order;
    Ok(MaterialFit {
        material: name.to_string(),
        albedo,
        exponent,
        scale_fixed_by,
        coefficients: (0..n2)
            .map(|i| [lights[0][i], lights[1][i], lights[2][i]])
            .collect(),
        well_determined: well,
        relative_residual: rel(r2),
        search,
    })
}

/// `scene` with the fitted material's albedo (and exponent) in place of its own.
#[must_use]
pub fn fitted_scene(scene: &Scene, fit: &MaterialFit) -> Scene {
    let Some(index) = scene.material_names.iter().position(|n| *n == fit.material) else {
        return scene.clone();
    };
    let albedo = fit.albedo.map(|a| a as f32);
    let m = match scene.materials[index] {
        Material::Phong {
            specular, exponent, ..
        } => Material::Phong {
            albedo,
            specular,
            exponent: fit.exponent.map_or(exponent, |e| e as f32),
        },
        _ => Material::Lambert { albedo },
    };
    with_material(scene, index, m)
}

/// The fit's value at its best point.
type Eval = ([f64; 3], Vec<DVector<f64>>, f64, Option<f64>);

/// Golden-section search of `f`'s residual (`.2`) over `[lo, hi]` to a bracket of `tol`: the
/// best evaluation.
fn golden(
    f: &mut dyn FnMut(f64) -> Result<Eval, SceneRelightError>,
    mut lo: f64,
    mut hi: f64,
    tol: f64,
) -> Result<Eval, SceneRelightError> {
    let phi = (5f64.sqrt() - 1.0) / 2.0;
    let mut x1 = hi - phi * (hi - lo);
    let mut x2 = lo + phi * (hi - lo);
    let mut f1 = f(x1)?;
    let mut f2 = f(x2)?;
    while hi - lo > tol {
        if f1.2 <= f2.2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - phi * (hi - lo);
            f1 = f(x1)?;
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + phi * (hi - lo);
            f2 = f(x2)?;
        }
    }
    Ok(if f1.2 <= f2.2 { f1 } else { f2 })
}
