//! The estimators: path tracing with next-event estimation on the environment and BRDF
//! sampling combined by Veach's multiple importance sampling, the unshadowed estimate, and
//! ambient occlusion.
//!
//! Emissive surfaces (glTF emission) add their radiance where a camera ray or a
//! BRDF-sampled ray hits them, with weight 1: nothing else samples them (no next-event
//! estimation towards emissive triangles; an environment shadow ray that hits one counts as
//! blocked), so BRDF sampling is the only strategy that produces those paths and the
//! estimator stays unbiased, only noisier for small bright emitters.
//!
//! At every surface vertex the geometric normal and the shading normal are both turned
//! towards the outgoing direction `ω_o` (CONVENTIONS.md: a back-facing shading normal is
//! flipped toward the viewer; a normal-mapped one as `Vertex::oriented` says). A direction on the other side of the *geometric* surface
//! would pass through it, so it contributes nothing (no light leaks through thin geometry)
//! except in the unshadowed mode, which by definition ignores geometry.

use crate::rng::Sampler;
use crate::settings::{MisHeuristic, Mode};
use crate::vertex::Vertex;
use crate::Renderer;
use glam::Vec3;
use prt_shading::{
    eval, is_pure_delta, luminance, pdf, sample, sample_cosine_hemisphere, BsdfSample, Frame,
};

/// MIS weight of strategy `a` against `b` (pdfs in solid angle).
pub(crate) fn mis_weight(h: MisHeuristic, a: f32, b: f32) -> f32 {
    if a.is_infinite() {
        return 1.0;
    }
    let (a, b) = match h {
        MisHeuristic::Power => (a * a, b * b),
        MisHeuristic::Balance => (a, b),
    };
    if a + b > 0.0 {
        a / (a + b)
    } else {
        0.0
    }
}

impl Renderer<'_> {
    /// Radiance leaving `v` towards `wo` (or the AO fraction as grey), per the mode.
    pub(crate) fn li_surface(&self, v: Vertex, wo: Vec3, s: &mut Sampler) -> Vec3 {
        match self.settings.mode {
            Mode::Path => v.le + self.li_path(v, wo, s),
            Mode::Unshadowed => v.le + self.li_unshadowed(v, wo, s),
            Mode::AmbientOcclusion { max_distance } => Vec3::splat(self.ambient_occlusion(
                &v,
                wo,
                s,
                max_distance.unwrap_or(f32::INFINITY),
            )),
        }
    }

    /// What a ray that leaves the scene sees.
    pub(crate) fn background(&self, dir: Vec3) -> Vec3 {
        match self.settings.mode {
            Mode::AmbientOcclusion { .. } => Vec3::ONE,
            _ => self.env.radiance(dir),
        }
    }

    fn li_path(&self, mut v: Vertex, mut wo: Vec3, s: &mut Sampler) -> Vec3 {
        let h = self.settings.mis;
        let mut radiance = Vec3::ZERO;
        let mut beta = Vec3::ONE;
        let mut indirect = 0u32;
        loop {
            let (ng, ns) = v.oriented(wo);
            // Next-event estimation: one environment sample, shadow-tested. At a pure mirror
            // it would always get a BRDF value of zero, so it is not drawn (its two numbers
            // are still taken, so the sample mapping and the image stay the same).
            let u_env = s.next_2d();
            let nee = !is_pure_delta(&v.mat);
            if let Some(es) = nee.then(|| self.env.sample(u_env)).flatten() {
                let cos = ns.dot(es.dir);
                if es.pdf > 0.0 && cos > 0.0 && ng.dot(es.dir) > 0.0 {
                    let f = eval(&v.mat, ns, wo, es.dir);
                    if f != Vec3::ZERO
                        && !self
                            .accel
                            .occluded(v.spawn(ng, es.dir), es.dir, f32::INFINITY)
                    {
                        let w = mis_weight(h, es.pdf, pdf(&v.mat, ns, wo, es.dir));
                        radiance += beta * f * es.radiance * (cos * w / es.pdf);
                    }
                }
            }
            // BRDF sampling: continues the path and hits the environment with MIS.
            let Some(bs) = sample(&v.mat, ns, wo, s.next_3d()) else {
                break;
            };
            if ng.dot(bs.wi) <= 0.0 {
                break;
            }
            beta *= bs.weight;
            if beta == Vec3::ZERO || !beta.is_finite() {
                break;
            }
            let origin = v.spawn(ng, bs.wi);
            if self.only_escape_matters(indirect) {
                // The path ends at this ray's hit whatever it hits, and no surface emits:
                // only whether it escapes matters, which an occlusion query answers (it
                // agrees with `closest_hit` on hit or miss for every ray of unbounded length,
                // so the image is bit-identical).
                if !self.accel.occluded(origin, bs.wi, f32::INFINITY) {
                    radiance += self.escaped(beta, &bs);
                }
                break;
            }
            let Some(hit) = self.accel.closest_hit(origin, bs.wi, f32::INFINITY) else {
                radiance += self.escaped(beta, &bs);
                break;
            };
            // Emission at the hit: direct light from an emitter, counted before the bounce
            // limit (like the environment seen by the same ray).
            let le = self.emitted(&hit);
            radiance += beta * le;
            indirect += 1;
            if self.settings.bounces >= 0 {
                if indirect > self.settings.bounces as u32 {
                    break;
                }
            } else if indirect >= self.settings.rr_start_bounce {
                let survive = luminance(beta).min(self.settings.rr_max_survival);
                if survive.is_nan() || survive <= 0.0 || s.next_f32() >= survive {
                    break;
                }
                beta /= survive;
            }
            v = self.vertex_emitting(&hit, le);
            wo = -bs.wi;
        }
        radiance
    }

    /// Whether a BRDF-sampled ray leaving the vertex after `indirect` reflections is the
    /// path's last one and what it hits cannot add light (no emissive surface in the scene).
    fn only_escape_matters(&self, indirect: u32) -> bool {
        !self.emissive && self.settings.bounces >= 0 && indirect >= self.settings.bounces as u32
    }

    /// The environment's contribution through throughput `beta` of a BRDF-sampled ray that
    /// escapes: its radiance, MIS-weighted against environment sampling unless the lobe is
    /// a delta.
    fn escaped(&self, beta: Vec3, bs: &BsdfSample) -> Vec3 {
        let (l, env_pdf) = self.env.radiance_and_pdf(bs.wi);
        let w = if bs.is_delta {
            1.0
        } else {
            mis_weight(self.settings.mis, bs.pdf, env_pdf)
        };
        beta * l * w
    }

    fn li_unshadowed(&self, v: Vertex, wo: Vec3, s: &mut Sampler) -> Vec3 {
        let h = self.settings.mis;
        let (_, ns) = v.oriented(wo);
        let mut radiance = Vec3::ZERO;
        if let Some(es) = self.env.sample(s.next_2d()) {
            let cos = ns.dot(es.dir);
            if es.pdf > 0.0 && cos > 0.0 {
                let f = eval(&v.mat, ns, wo, es.dir);
                let w = mis_weight(h, es.pdf, pdf(&v.mat, ns, wo, es.dir));
                radiance += f * es.radiance * (cos * w / es.pdf);
            }
        }
        if let Some(bs) = sample(&v.mat, ns, wo, s.next_3d()) {
            let w = if bs.is_delta {
                1.0
            } else {
                mis_weight(h, bs.pdf, self.env.pdf(bs.wi))
            };
            radiance += bs.weight * self.env.radiance(bs.wi) * w;
        }
        radiance
    }

    fn ambient_occlusion(&self, v: &Vertex, wo: Vec3, s: &mut Sampler, tmax: f32) -> f32 {
        let (ng, ns) = v.oriented(wo);
        let w = Frame::from_normal(ns).to_world(sample_cosine_hemisphere(s.next_2d()));
        if ng.dot(w) <= 0.0 || self.accel.occluded(v.spawn(ng, w), w, tmax) {
            0.0
        } else {
            1.0
        }
    }
}
