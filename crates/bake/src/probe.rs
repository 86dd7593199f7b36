//! The cheap transfer probes adaptive subdivision decides with (`subdivide`).
//!
//! A probe estimates the shadowed diffuse transfer of bands 0–2 at any surface point,
//! `T_i = ∫ V(ω) max(0, n·ω) y_i(ω) dω`, from `R` directions `ω_k` spread uniformly over the
//! whole sphere (pdf `1/4π`): `T_i ≈ (4π/R) Σ_{n·ω_k > 0} V(ω_k) (n·ω_k) y_i(ω_k)`. Unlike the
//! bake's cosine-distributed rays in each point's own frame, the directions are the same world
//! directions for every point of an object (common random numbers): two nearby points trace
//! the same directions, so where they see the same sky their probes differ only by the
//! smoothly varying cosine, and a difference between them is what visibility does between
//! them, not sampling noise. Directions below a point's horizon weigh nothing and are not
//! traced (about half of them), and the basis values are computed once per object. A
//! point's rays are traced in packets ordered by the Morton cell of their sample points
//! (`transfer::trace_point`; the sums stay in the sequence's order).

use crate::transfer::{morton_cell, trace_point, TraceScratch};
use crate::BakeError;
use glam::Vec3;
use prt_sh::Basis;
use prt_shading::sample_uniform_sphere;
use prt_tracer::points::SamplePoint;
use prt_tracer::sequence::{SequencePurpose, R2};
use prt_tracer::{point_offset, Accel};
use std::f64::consts::PI;

/// The sequence key of every probe (after every vertex index, so no point of a bake shares
/// it).
const PROBE_KEY: u64 = u64::MAX / 2;

/// The orders a probe estimates: bands 0–2 at most.
const PROBE_ORDER: usize = 3;

/// The probes of one object: its shared directions and their basis values.
pub(crate) struct Probe<'a> {
    accel: &'a Accel,
    /// The object's extent (it sizes the ray offset).
    extent: f32,
    /// The shared directions.
    dirs: Vec<Vec3>,
    /// The Morton cell of each direction's sample point (the order rays are traced in).
    cells: Vec<u8>,
    /// `ys[k * len .. (k + 1) * len]`: the basis at `dirs[k]`.
    ys: Vec<f64>,
    /// Coefficients per probe.
    len: usize,
}

impl<'a> Probe<'a> {
    /// The probes of mesh `mesh` of `accel`'s scene, to order `min(order, 3)`, with `rays`
    /// directions from the stream of (`seed`, `mesh`).
    ///
    /// # Errors
    /// An order the basis refuses (0).
    pub(crate) fn new(
        accel: &'a Accel,
        mesh: usize,
        order: usize,
        rays: u32,
        seed: u64,
    ) -> Result<Self, BakeError> {
        let basis = Basis::new(order.min(PROBE_ORDER))?;
        let len = basis.len();
        let seq = R2::new(seed, SequencePurpose::Visibility, mesh as u64, PROBE_KEY);
        let dirs: Vec<Vec3> = (0..rays)
            .map(|k| sample_uniform_sphere(seq.get(k)).normalize())
            .collect();
        let cells = (0..rays).map(|k| morton_cell(seq.get(k))).collect();
        let mut ys = vec![0.0f64; dirs.len() * len];
        for (d, y) in dirs.iter().zip(ys.chunks_exact_mut(len)) {
            basis.eval_unchecked(d.as_dvec3(), y);
        }
        Ok(Self {
            accel,
            extent: accel.mesh_extent(mesh),
            dirs,
            cells,
            ys,
            len,
        })
    }

    /// The transfer at `p` with normal `n` (normalised; `+Y` if zero), and the rays traced
    /// (the directions above the horizon).
    pub(crate) fn at(&self, p: Vec3, n: Vec3) -> (Vec<f64>, u64) {
        let n = n.normalize_or(Vec3::Y);
        let point = SamplePoint {
            position: p,
            normal: n,
            offset_normal: n,
            offset: point_offset(p, self.extent),
        };
        let cosines: Vec<f64> = self.dirs.iter().map(|d| f64::from(n.dot(*d))).collect();
        let below: Vec<bool> = cosines.iter().map(|&c| c <= 0.0).collect();
        let mut scratch = TraceScratch::default();
        trace_point(
            self.accel,
            &point,
            &self.dirs,
            &self.cells,
            &below,
            &mut scratch,
        );
        let mut sum = vec![0.0f64; self.len];
        let mut traced = 0u64;
        for ((&c, hit), y) in cosines
            .iter()
            .zip(&scratch.out)
            .zip(self.ys.chunks_exact(self.len))
        {
            if c <= 0.0 {
                continue;
            }
            traced += 1;
            if hit.is_some() {
                continue;
            }
            for (s, y) in sum.iter_mut().zip(y) {
                *s += c * y;
            }
        }
        let w = 4.0 * PI / self.dirs.len().max(1) as f64;
        sum.iter_mut().for_each(|s| *s *= w);
        (sum, traced)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use prt_scene::test_util::floor_quad;
    use prt_scene::{Camera, Environment, Material, Scene};

    /// On an open floor the probe estimates the unshadowed transfer of its normal, whose
    /// closed form is `transfer::unshadowed`. Each term `4π (n·ω) y_i(ω)` is at most
    /// `4π · 0.631` = 7.93 in size (`|y_i| ≤ √(5/16π)·2 = 0.631` on bands 0–2), so with
    /// `R = 4096` i.i.d. directions the standard deviation would be at most 7.93/64 = 0.124;
    /// the R2 points are stratified, so every coefficient must be within an eighth of that σ
    /// (0.0155; i.i.d. sampling would miss it on most of them; measured: ≤ 6·10⁻⁴).
    #[test]
    fn an_open_floor_probes_to_the_unshadowed_transfer() {
        let cam = Camera::look_at(DVec3::new(0.0, 2.0, 2.0), DVec3::ZERO, 40.0, 8, 6);
        let mut scene = Scene::new(cam, Environment::uniform([1.0; 3]));
        let m = scene.add_material("w", Material::Lambert { albedo: [0.5; 3] });
        scene.add_mesh(floor_quad(1.0, 0.0), m);
        let accel = Accel::build(&scene).unwrap();
        let probe = Probe::new(&accel, 0, 6, 4096, 0).unwrap();
        let (t, traced) = probe.at(Vec3::new(0.1, 0.0, -0.2), Vec3::Y);
        // Half the sphere is above the horizon: R2 points are within a few of half.
        assert!(traced.abs_diff(2048) < 16, "{traced}");
        let exact = crate::transfer::unshadowed(3, Vec3::Y);
        assert_eq!(t.len(), 9, "bands 0–2 only");
        for (a, b) in t.iter().zip(&exact) {
            assert!((a - b).abs() < 0.0155, "{t:?} vs {exact:?}");
        }
    }

    /// Common random numbers: two points of an open floor trace the same directions and see
    /// the same sky, so their probes are bit-identical (no sampling noise between them).
    #[test]
    fn points_that_see_the_same_sky_probe_identically() {
        let cam = Camera::look_at(DVec3::new(0.0, 2.0, 2.0), DVec3::ZERO, 40.0, 8, 6);
        let mut scene = Scene::new(cam, Environment::uniform([1.0; 3]));
        let m = scene.add_material("w", Material::Lambert { albedo: [0.5; 3] });
        scene.add_mesh(floor_quad(1.0, 0.0), m);
        let accel = Accel::build(&scene).unwrap();
        let probe = Probe::new(&accel, 0, 3, 64, 7).unwrap();
        let a = probe.at(Vec3::new(0.5, 0.0, 0.5), Vec3::Y);
        let b = probe.at(Vec3::new(-0.3, 0.0, 0.1), Vec3::Y);
        assert_eq!(a, b);
    }
}
