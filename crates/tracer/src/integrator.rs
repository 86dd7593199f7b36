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
use crate::settings::{MisHeuristic, Mode, SplitLobes};
use crate::vertex::Vertex;
use crate::{Hit, Renderer};
use glam::Vec3;
use prt_shading::{
    chooses_lobe, eval_and_pdf, eval_and_split_pdf, has_delta, is_pure_delta, luminance, sample,
    sample_cosine_hemisphere, sample_lobe, splits, BsdfSample, Frame, SplitLobe, SPLIT_LOBES,
};

/// A path of [`Mode::Path`] at a surface vertex: what it has gathered and what it carries.
#[derive(Clone, Copy, Debug)]
struct PathState {
    /// Radiance gathered so far (the first vertex's own emission excluded).
    radiance: Vec3,
    /// Throughput to the current vertex.
    beta: Vec3,
    /// Reflections so far (0 at the first vertex).
    indirect: u32,
    /// The current vertex.
    v: Vertex,
    /// Direction towards where the path came from.
    wo: Vec3,
    /// The vertex's geometric and shading normals turned towards `wo` ([`Vertex::oriented`]).
    ng: Vec3,
    /// See `ng`.
    ns: Vec3,
}

impl PathState {
    /// A path starting at `v`, seen from `wo`.
    fn new(v: Vertex, wo: Vec3) -> Self {
        let (ng, ns) = v.oriented(wo);
        Self {
            radiance: Vec3::ZERO,
            beta: Vec3::ONE,
            indirect: 0,
            v,
            wo,
            ng,
            ns,
        }
    }
}

/// An environment shadow ray of next-event estimation and the radiance it adds to its path
/// if nothing blocks it.
#[derive(Clone, Copy, Debug)]
struct ShadowRay {
    origin: Vec3,
    dir: Vec3,
    add: Vec3,
}

/// A BRDF-sampled ray that continues a path: its origin (spawned off the surface) and sample.
#[derive(Clone, Copy, Debug)]
struct Scatter {
    origin: Vec3,
    bs: BsdfSample,
}

/// How a vertex samples its material's lobes ([`Renderer::splits_at`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Split {
    /// One lobe chosen at random.
    No,
    /// One sample of each lobe ([`Renderer::split`]).
    Both,
    /// The delta lobe always, the other as the random choice takes it
    /// ([`Renderer::split_delta`]).
    Delta,
}

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

    fn li_path(&self, v: Vertex, wo: Vec3, s: &mut Sampler) -> Vec3 {
        let mut path = PathState::new(v, wo);
        self.continue_path(&mut path, s);
        path.radiance
    }

    /// Follows `path` from its current vertex to its end, one ray at a time (two where a
    /// vertex splits its material's lobes, [`Renderer::split`]).
    fn continue_path(&self, path: &mut PathState, s: &mut Sampler) {
        loop {
            let split = self.splits_at(path);
            if let Some(r) = self.next_event(path, split == Split::Both, s) {
                if !self.accel.occluded(r.origin, r.dir, f32::INFINITY) {
                    path.radiance += r.add;
                }
            }
            match split {
                Split::No => {}
                Split::Both => return self.split(path, s),
                Split::Delta => return self.split_delta(path, s),
            }
            let Some(sc) = self.scatter(path, s) else {
                return;
            };
            if !self.follow(path, &sc, s) {
                return;
            }
        }
    }

    /// Traces the path's BRDF ray `sc`: the environment if it escapes, else the vertex it
    /// hits. Returns whether the path goes on from that vertex.
    fn follow(&self, path: &mut PathState, sc: &Scatter, s: &mut Sampler) -> bool {
        if self.only_escape_matters(path.indirect) {
            // The path ends at this ray's hit whatever it hits, and no surface emits: only
            // whether it escapes matters, which an occlusion query answers (it agrees with
            // `closest_hit` on hit or miss for every ray of unbounded length, so the image is
            // bit-identical).
            if !self.accel.occluded(sc.origin, sc.bs.wi, f32::INFINITY) {
                self.escape(path, sc);
            }
            return false;
        }
        match self.accel.closest_hit(sc.origin, sc.bs.wi, f32::INFINITY) {
            None => {
                self.escape(path, sc);
                false
            }
            Some(hit) => self.arrive(path, sc, &hit, s),
        }
    }

    /// How the path's vertex samples the lobes of its material: more than one lobe
    /// ([`prt_shading::splits`]) where it is one of the materials
    /// [`RenderSettings::split_lobes`] names, within the first
    /// [`RenderSettings::split_depth`] vertices; else one lobe chosen at random.
    ///
    /// [`RenderSettings::split_lobes`]: crate::RenderSettings::split_lobes
    /// [`RenderSettings::split_depth`]: crate::RenderSettings::split_depth
    fn splits_at(&self, path: &PathState) -> Split {
        let how = match self.settings.split_lobes {
            SplitLobes::Mirror if has_delta(&path.v.mat) => Split::Both,
            SplitLobes::Delta if has_delta(&path.v.mat) => Split::Delta,
            SplitLobes::All => Split::Both,
            _ => Split::No,
        };
        if how != Split::No
            && path.indirect < self.settings.split_depth
            && splits(&path.v.mat, path.ns, path.wo)
        {
            how
        } else {
            Split::No
        }
    }

    /// Lobe splitting at the path's vertex (`prt_shading`'s `split` module): one direction
    /// from each lobe, each followed to the end of its own path, their radiance summed. The
    /// vertex moves through the same numbers an unsplit one does (its lobe choice skipped,
    /// not computed) and both lobes use the same direction numbers; each branch then
    /// continues from a copy of the sampler, so both draw the same stratified dimensions.
    /// Each branch's estimate is unbiased on its own, so their sum is.
    fn split(&self, path: &mut PathState, s: &mut Sampler) {
        let u = s.next_3d_tail();
        for lobe in SPLIT_LOBES {
            if let Some(bs) = sample_lobe(&path.v.mat, path.ns, path.wo, lobe, u) {
                self.branch(path, bs, s);
            }
        }
    }

    /// The delta lobe taken out of the lobe choice at the path's vertex: its ray is followed
    /// every time (weight `specular`), and the one-sample choice ([`prt_shading::sample`],
    /// with the lobe number the vertex draws anyway) decides as it would unsplit whether the
    /// diffuse lobe is followed too, with the weight and density it has there. The diffuse
    /// lobe's estimate is then exactly the unsplit one's (so is its MIS weight against
    /// next-event estimation), and the delta lobe's is its expectation over the choice: the
    /// sum is unbiased.
    fn split_delta(&self, path: &mut PathState, s: &mut Sampler) {
        let u = s.next_3d();
        let delta = sample_lobe(
            &path.v.mat,
            path.ns,
            path.wo,
            SplitLobe::Specular,
            [u[1], u[2]],
        );
        let diffuse = sample(&path.v.mat, path.ns, path.wo, u).filter(|bs| !bs.is_delta);
        for bs in [delta, diffuse].into_iter().flatten() {
            self.branch(path, bs, s);
        }
    }

    /// One branch of a split vertex: the path from BRDF sample `bs` of its vertex to its
    /// end, from a copy of the sampler, its radiance added to the path's.
    fn branch(&self, path: &mut PathState, bs: BsdfSample, s: &Sampler) {
        let mut branch = PathState {
            radiance: Vec3::ZERO,
            ..*path
        };
        let mut s = s.clone();
        if let Some(sc) = self.scattered(&mut branch, bs) {
            if self.follow(&mut branch, &sc, &mut s) {
                self.continue_path(&mut branch, &mut s);
            }
        }
        path.radiance += branch.radiance;
    }

    /// Next-event estimation at the path's vertex: one environment sample, and the shadow
    /// ray that decides whether it counts (`None` when it cannot add light). Its MIS weight
    /// is against the BRDF technique the vertex uses: the one-sample mixture, or both lobes
    /// when it splits (`split`). At a pure mirror it would always get a BRDF value of zero,
    /// so it is not drawn (its two numbers are still taken, so the sample mapping and the
    /// image stay the same).
    fn next_event(&self, path: &PathState, split: bool, s: &mut Sampler) -> Option<ShadowRay> {
        let u_env = s.next_2d();
        let (v, ng, ns, wo) = (&path.v, path.ng, path.ns, path.wo);
        if is_pure_delta(&v.mat) {
            return None;
        }
        let es = self.env.sample_at(ns, u_env)?;
        let cos = ns.dot(es.dir);
        if !(es.pdf > 0.0 && cos > 0.0 && ng.dot(es.dir) > 0.0) {
            return None;
        }
        let (f, brdf_pdf) = if split {
            eval_and_split_pdf(&v.mat, ns, wo, es.dir)
        } else {
            eval_and_pdf(&v.mat, ns, wo, es.dir)
        };
        if f == Vec3::ZERO {
            return None;
        }
        let w = mis_weight(self.settings.mis, es.pdf, brdf_pdf);
        Some(ShadowRay {
            origin: v.spawn(ng, es.dir),
            dir: es.dir,
            add: path.beta * f * es.radiance * (cos * w / es.pdf),
        })
    }

    /// BRDF sampling at the path's vertex: the ray that continues it (and hits the
    /// environment with MIS), with the throughput updated; `None` ends the path.
    fn scatter(&self, path: &mut PathState, s: &mut Sampler) -> Option<Scatter> {
        let u = if chooses_lobe(&path.v.mat) {
            s.next_3d()
        } else {
            let [a, b] = s.next_3d_tail();
            [0.0, a, b]
        };
        let bs = sample(&path.v.mat, path.ns, path.wo, u)?;
        self.scattered(path, bs)
    }

    /// The ray of BRDF sample `bs` from the path's vertex, with the throughput updated;
    /// `None` (the path ends) below the geometric surface or at zero throughput.
    fn scattered(&self, path: &mut PathState, bs: BsdfSample) -> Option<Scatter> {
        if path.ng.dot(bs.wi) <= 0.0 {
            return None;
        }
        path.beta *= bs.weight;
        if path.beta == Vec3::ZERO || !path.beta.is_finite() {
            return None;
        }
        Some(Scatter {
            origin: path.v.spawn(path.ng, bs.wi),
            bs,
        })
    }

    /// The path's BRDF ray `sc` left the scene: the environment's contribution.
    fn escape(&self, path: &mut PathState, sc: &Scatter) {
        path.radiance += self.escaped(path.beta, path.ns, &sc.bs);
    }

    /// The path's BRDF ray `sc` hit `hit`: its emission (direct light from an emitter,
    /// counted before the bounce limit, like the environment seen by the same ray), then the
    /// bounce limit or Russian roulette. Returns whether the path goes on, from `hit`.
    fn arrive(&self, path: &mut PathState, sc: &Scatter, hit: &Hit, s: &mut Sampler) -> bool {
        let le = self.emitted(hit);
        path.radiance += path.beta * le;
        path.indirect += 1;
        if self.settings.bounces >= 0 {
            if path.indirect > self.settings.bounces as u32 {
                return false;
            }
        } else if path.indirect >= self.settings.rr_start_bounce {
            let survive = luminance(path.beta).min(self.settings.rr_max_survival);
            if survive.is_nan() || survive <= 0.0 || s.next_f32() >= survive {
                return false;
            }
            path.beta /= survive;
        }
        path.v = self.vertex_emitting(hit, le);
        path.wo = -sc.bs.wi;
        (path.ng, path.ns) = path.v.oriented(path.wo);
        true
    }

    /// Whether a BRDF-sampled ray leaving the vertex after `indirect` reflections is the
    /// path's last one and what it hits cannot add light (no emissive surface in the scene).
    fn only_escape_matters(&self, indirect: u32) -> bool {
        !self.emissive && self.settings.bounces >= 0 && indirect >= self.settings.bounces as u32
    }

    /// The environment's contribution through throughput `beta` of a BRDF-sampled ray that
    /// escapes a vertex of shading normal `ns`: its radiance, MIS-weighted against
    /// environment sampling (at that normal) unless the lobe is a delta.
    fn escaped(&self, beta: Vec3, ns: Vec3, bs: &BsdfSample) -> Vec3 {
        if bs.is_delta {
            // Nothing else samples a delta direction: weight 1, no environment pdf needed.
            return beta * self.env.radiance(bs.wi);
        }
        let (l, env_pdf) = self.env.radiance_and_pdf_at(ns, bs.wi);
        beta * l * mis_weight(self.settings.mis, bs.pdf, env_pdf)
    }

    fn li_unshadowed(&self, v: Vertex, wo: Vec3, s: &mut Sampler) -> Vec3 {
        let h = self.settings.mis;
        let (_, ns) = v.oriented(wo);
        let mut radiance = Vec3::ZERO;
        if let Some(es) = self.env.sample_at(ns, s.next_2d()) {
            let cos = ns.dot(es.dir);
            if es.pdf > 0.0 && cos > 0.0 {
                let (f, brdf_pdf) = eval_and_pdf(&v.mat, ns, wo, es.dir);
                let w = mis_weight(h, es.pdf, brdf_pdf);
                radiance += f * es.radiance * (cos * w / es.pdf);
            }
        }
        if let Some(bs) = sample(&v.mat, ns, wo, s.next_3d()) {
            let w = if bs.is_delta {
                1.0
            } else {
                mis_weight(h, bs.pdf, self.env.pdf_at(ns, bs.wi))
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
