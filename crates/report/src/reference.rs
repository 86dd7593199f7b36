//! Step 1 of a report: the path-traced reference (cached), rendered until its own noise
//! ceiling reaches the target, with the half difference of its two half images, which
//! estimates its error per pixel; then the path tracer's convergence against it.

use crate::budget::{ldr_noise_psnr, masked_mean_square};
use crate::cache::reference_key;
use crate::data::{ConvergencePoint, ReferenceInfo, ReportSettings};
use crate::error::ReportError;
use crate::run::Run;
use prt_compare::{compare, Image};
use prt_scene_relight::imaging::RgbImage;
use prt_scene_relight::io::{read_reference, write_exr, write_reference, CachedReference};
use std::path::Path;
use std::time::Instant;

/// The most samples per pixel of the path-tracing convergence series.
const MAX_CONVERGENCE_SPP: u32 = 256;

/// The reference of a report and what its noise allows.
pub(crate) struct Reference {
    /// The render: radiance, half difference, samples and seconds.
    pub data: CachedReference,
    /// Its radiance as a comparison image.
    pub image: Image,
    /// Its noise: mean squared error against its expectation over object pixels.
    pub noise_mse: f64,
    /// The PSNR ceiling that noise sets on the 8-bit view (object pixels).
    pub noise_psnr: f64,
    /// What `report.json` says of it.
    pub info: ReferenceInfo,
}

/// The reference's render settings (an even sample count, so its two half images estimate
/// its noise).
fn render_settings(s: &ReportSettings) -> prt_tracer::RenderSettings {
    prt_tracer::RenderSettings {
        spp: s.reference_spp + s.reference_spp % 2,
        bounces: s.bounces as i32,
        seed: s.seed,
        aovs: true,
        progress: s.progress,
        target_psnr_ldr: s.reference_psnr,
        ..Default::default()
    }
}

/// Reads the reference from the cache or renders it (and writes it to `images/reference.exr`),
/// and measures its noise.
pub(crate) fn path_traced_reference(run: &Run) -> Result<Reference, ReportError> {
    let s = run.settings;
    let rs = render_settings(s);
    let path = run.out_dir.join("cache").join(format!(
        "reference-{:016x}.bin",
        reference_key(run.scene, &rs)
    ));
    let (data, cached) = cached_or_rendered(run, &rs, &path)?;
    let image = run.image(&data.radiance);
    write_exr(
        &run.out_dir.join("images/reference.exr"),
        &RgbImage {
            width: run.width as usize,
            height: run.height as usize,
            pixels: image.pixels.clone(),
        },
        &[
            ("kind", "reference".into()),
            ("spp", data.spp.to_string()),
            ("seed", s.seed.to_string()),
        ],
    )?;
    let noise_mse = masked_mean_square(&data.half_difference, run.mask.as_slice());
    let noise_psnr = ldr_noise_psnr(&data.radiance, &data.half_difference, run.mask.as_slice());
    let info = ReferenceInfo {
        spp: data.spp,
        seconds: data.seconds,
        cached,
        file: path.display().to_string(),
        noise_mse,
        noise_psnr_ldr: noise_psnr,
        target_psnr_ldr: s.reference_psnr,
        target_met: s.reference_psnr.map(|p| noise_psnr >= p),
    };
    if let Some(p) = s.reference_psnr {
        if noise_psnr < p {
            run.say(&format!(
                "the reference stopped at the cap of {} spp with a noise ceiling of {noise_psnr:.1} dB, short of {p} dB (raise --reference-spp)",
                data.spp
            ));
        }
    }
    Ok(Reference {
        data,
        image,
        noise_mse,
        noise_psnr,
        info,
    })
}

/// The cached reference at `path` when it has the camera's size, else a new render written
/// there; and whether it came from the cache.
fn cached_or_rendered(
    run: &Run,
    rs: &prt_tracer::RenderSettings,
    path: &Path,
) -> Result<(CachedReference, bool), ReportError> {
    let s = run.settings;
    let (w, h) = (run.width, run.height);
    match read_reference(path) {
        Ok(r) if r.width == w && r.height == h => {
            run.say(&format!("reusing the cached reference {}", path.display()));
            Ok((r, true))
        }
        _ => {
            let reference_spp = rs.spp;
            run.say(&format!(
                "path-traced reference, {} bounce(s), {}",
                s.bounces,
                s.reference_psnr
                    .map_or(format!("{reference_spp} spp"), |p| format!(
                    "until its 8-bit noise ceiling reaches {p} dB (at most {reference_spp} spp)"
                ))
            ));
            let out = prt_tracer::render(run.scene, rs)?;
            let r = CachedReference {
                width: w,
                height: h,
                spp: out.settings.spp,
                seconds: out.seconds,
                radiance: out.radiance,
                half_difference: out.aovs.expect("aovs asked").half_difference,
            };
            write_reference(path, &r)?;
            Ok((r, false))
        }
    }
}

/// The path tracer with another seed at 1, 2, 4, … spp (up to half the reference's, at most
/// [`MAX_CONVERGENCE_SPP`]), each render timed and measured against the reference.
pub(crate) fn convergence(
    run: &Run,
    reference: &Reference,
) -> Result<Vec<ConvergencePoint>, ReportError> {
    let rs = render_settings(run.settings);
    let mut convergence = Vec::new();
    let mut spp = 1;
    while spp <= (reference.data.spp / 2).min(MAX_CONVERGENCE_SPP) {
        let cs = prt_tracer::RenderSettings {
            spp,
            seed: run.settings.seed.wrapping_add(0x5eed),
            aovs: false,
            progress: false,
            target_psnr_ldr: None,
            ..rs.clone()
        };
        let t = Instant::now();
        let out = prt_tracer::render(run.scene, &cs)?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let m = compare(&run.image(&out.radiance), &reference.image, Some(&run.mask))?;
        let mm = m.masked.expect("mask given");
        convergence.push(ConvergencePoint {
            spp,
            ms,
            psnr_ldr: mm.psnr_ldr,
            rel_l2: mm.rel_l2,
        });
        spp *= 2;
    }
    Ok(convergence)
}
