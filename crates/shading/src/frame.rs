//! Orthonormal frames around a normal.

use glam::Vec3;

/// Orthonormal frame around a unit normal (Duff et al. 2017 branchless ONB).
///
/// `t × b = n` (right-handed). Local coordinates have the normal as `+z`, so in the local frame
/// `cos θ = v.z`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// First tangent.
    pub t: Vec3,
    /// Second tangent (bitangent).
    pub b: Vec3,
    /// The unit normal.
    pub n: Vec3,
}

impl Frame {
    /// Builds the frame of Duff, Burgess, Christensen, Hery, Kensler, Liani and Villemin,
    /// "Building an Orthonormal Basis, Revisited" (JCGT 2017). `n` must be unit length.
    #[must_use]
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let bxy = n.x * n.y * a;
        let t = Vec3::new(1.0 + sign * n.x * n.x * a, sign * bxy, -sign * n.x);
        let b = Vec3::new(bxy, sign + n.y * n.y * a, -n.y);
        Self { t, b, n }
    }

    /// Local coordinates `(x, y, z)` (z along the normal) to world space.
    #[must_use]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.t * v.x + self.b * v.y + self.n * v.z
    }

    /// World-space vector to local coordinates (z along the normal).
    #[must_use]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn frames_are_orthonormal_and_right_handed() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
        let mut normals = vec![
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::Y,
            Vec3::new(0.0, 0.0, -0.0),
        ];
        normals[4] = Vec3::new(1e-8, 0.0, -1.0).normalize();
        for _ in 0..10_000 {
            let v = Vec3::new(
                rng.random::<f32>() - 0.5,
                rng.random::<f32>() - 0.5,
                rng.random::<f32>() - 0.5,
            );
            if v.length() > 1e-3 {
                normals.push(v.normalize());
            }
        }
        for n in normals {
            let f = Frame::from_normal(n);
            assert!((f.t.length() - 1.0).abs() < 1e-5, "{n}");
            assert!((f.b.length() - 1.0).abs() < 1e-5, "{n}");
            assert!(
                f.t.dot(f.b).abs() < 1e-5 && f.t.dot(f.n).abs() < 1e-5 && f.b.dot(f.n).abs() < 1e-5
            );
            assert!((f.t.cross(f.b) - f.n).length() < 1e-5, "{n}");
            let v = Vec3::new(0.3, -0.5, 0.8);
            assert!((f.to_local(f.to_world(v)) - v).length() < 1e-5);
            assert!((f.to_world(Vec3::Z) - n).length() < 1e-6);
        }
    }
}
