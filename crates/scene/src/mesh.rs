//! Mesh clean-up shared by the OBJ and glTF readers, and [`Mesh`] helpers.
//!
//! Every mesh that leaves a loader went through [`finish_mesh`]:
//! 1. positions must be finite and indices in range (else an error naming the file);
//! 2. degenerate triangles are dropped: two equal indices, or a cross product of the edges,
//!    computed in f64 from the file's f32 positions before any transform, that is exactly zero
//!    (zero area: repeated or collinear points). A mesh left with no triangle is an error;
//! 3. positions are transformed to world space; a transform with a negative determinant
//!    (a mirror) also reverses the winding, so that the triangles' geometric normals keep their
//!    side (as glTF requires);
//! 4. normals from the file are transformed by the inverse transpose and renormalised; a
//!    zero, NaN or infinite one is replaced by the computed normal (one warning counts them);
//!    without normals in the file, angle-weighted vertex normals are computed.

use crate::{Mesh, SceneError};
use glam::{DMat3, DMat4, DVec3, Vec3};
use std::path::Path;

/// Geometry as read from a file, in the file's (or node's) own space.
#[derive(Clone, Debug, Default)]
pub(crate) struct RawMesh {
    /// Name for messages.
    pub name: String,
    /// Positions in file space.
    pub positions: Vec<Vec3>,
    /// Normals in file space, when the file has one per position.
    pub normals: Option<Vec<Vec3>>,
    /// Triangles (not yet checked).
    pub indices: Vec<[u32; 3]>,
    /// UV sets, one value per position each.
    pub texcoords: Vec<Vec<[f32; 2]>>,
    /// Vertex colours (linear RGB), one per position, or empty.
    pub colors: Vec<[f32; 3]>,
}

/// What [`finish_mesh`] had to repair, summed over a file for one warning each.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Repairs {
    /// Triangles in the file.
    pub triangles: usize,
    /// Degenerate triangles dropped.
    pub degenerate: usize,
    /// File normals that were zero or not finite and were replaced.
    pub bad_normals: usize,
    /// Vertices whose normals were computed because the file had none.
    pub computed_normals: usize,
}

impl Repairs {
    /// Adds another mesh's counts.
    pub fn add(&mut self, other: Repairs) {
        self.triangles += other.triangles;
        self.degenerate += other.degenerate;
        self.bad_normals += other.bad_normals;
        self.computed_normals += other.computed_normals;
    }

    /// The warnings these repairs call for (none when nothing was repaired).
    pub fn warnings(&self, path: &Path) -> Vec<String> {
        let mut w = Vec::new();
        if self.degenerate > 0 {
            w.push(format!(
                "{}: dropped {} of {} triangles as degenerate (zero area or a repeated index)",
                path.display(),
                self.degenerate,
                self.triangles
            ));
        }
        if self.bad_normals > 0 {
            w.push(format!(
                "{}: replaced {} zero or non-finite vertex normals by computed angle-weighted ones",
                path.display(),
                self.bad_normals
            ));
        }
        w
    }
}

/// Checks, cleans and transforms `raw` into a world-space [`Mesh`] (see the module docs).
pub(crate) fn finish_mesh(
    path: &Path,
    raw: RawMesh,
    to_world: &DMat4,
    material: usize,
) -> Result<(Mesh, Repairs), SceneError> {
    let RawMesh {
        name,
        positions,
        normals,
        indices,
        texcoords,
        colors,
    } = raw;
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(SceneError::mesh(
            path,
            format!(
                "{name}: vertex {i} has a non-finite position {:?}",
                positions[i]
            ),
        ));
    }
    let n = positions.len();
    let mut repairs = Repairs {
        triangles: indices.len(),
        ..Repairs::default()
    };
    let mut kept = Vec::with_capacity(indices.len());
    for (t, tri) in indices.iter().enumerate() {
        if let Some(&bad) = tri.iter().find(|&&i| i as usize >= n) {
            return Err(SceneError::mesh(
                path,
                format!("{name}: triangle {t} uses vertex index {bad}, but there are {n} vertices"),
            ));
        }
        let [a, b, c] = tri.map(|i| positions[i as usize].as_dvec3());
        let degenerate = tri[0] == tri[1]
            || tri[1] == tri[2]
            || tri[0] == tri[2]
            || (b - a).cross(c - a) == DVec3::ZERO;
        if degenerate {
            repairs.degenerate += 1;
        } else {
            kept.push(*tri);
        }
    }
    if kept.is_empty() {
        return Err(SceneError::mesh(
            path,
            format!(
                "{name}: no triangles left ({} in the file, {} degenerate)",
                repairs.triangles, repairs.degenerate
            ),
        ));
    }
    let mut mesh = Mesh {
        name,
        positions,
        normals: Vec::new(),
        indices: kept,
        material,
        texcoords,
        colors,
    };
    let file_normals = normals.filter(|v| v.len() == n);
    mesh.transform_positions(to_world);
    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(SceneError::mesh(
            path,
            format!(
                "{}: vertex {i} is not finite after the transform (overflow)",
                mesh.name
            ),
        ));
    }
    let computed = angle_weighted_normals(&mesh.positions, &mesh.indices);
    match file_normals {
        Some(file) => {
            let normal_matrix = normal_matrix(to_world);
            mesh.normals = file
                .iter()
                .zip(&computed)
                .map(|(nf, nc)| {
                    let t = (normal_matrix * nf.as_dvec3())
                        .normalize_or_zero()
                        .as_vec3();
                    if t == Vec3::ZERO || !t.is_finite() {
                        repairs.bad_normals += 1;
                        *nc
                    } else {
                        t
                    }
                })
                .collect();
        }
        None => {
            repairs.computed_normals = n;
            mesh.normals = computed;
        }
    }
    Ok((mesh, repairs))
}

/// The matrix that transforms normals under `m`: the inverse transpose of its linear part.
#[must_use]
pub fn normal_matrix(m: &DMat4) -> DMat3 {
    DMat3::from_mat4(*m).inverse().transpose()
}

/// Angle-weighted vertex normals (Thürmer & Wüthrich 1998): each triangle adds its unit normal
/// times its corner angle at the vertex. A vertex whose sum cancels takes the normal of its
/// first triangle; a vertex used by no triangle gets +Y. Degenerate triangles add nothing.
#[must_use]
pub fn angle_weighted_normals(positions: &[Vec3], indices: &[[u32; 3]]) -> Vec<Vec3> {
    let mut sum = vec![DVec3::ZERO; positions.len()];
    let mut first = vec![DVec3::ZERO; positions.len()];
    for tri in indices {
        let p = tri.map(|i| positions[i as usize].as_dvec3());
        let face = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
        if face == DVec3::ZERO {
            continue;
        }
        for k in 0..3 {
            let e1 = (p[(k + 1) % 3] - p[k]).normalize_or_zero();
            let e2 = (p[(k + 2) % 3] - p[k]).normalize_or_zero();
            let angle = e1.dot(e2).clamp(-1.0, 1.0).acos();
            let v = tri[k] as usize;
            sum[v] += face * angle;
            if first[v] == DVec3::ZERO {
                first[v] = face;
            }
        }
    }
    sum.iter()
        .zip(&first)
        .map(|(s, f)| {
            let n = s.normalize_or_zero();
            if n != DVec3::ZERO {
                n.as_vec3()
            } else if *f != DVec3::ZERO {
                f.as_vec3()
            } else {
                Vec3::Y
            }
        })
        .collect()
}

/// FNV-1a 64-bit offset basis.
const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
/// FNV-1a 64-bit prime.
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

/// Streaming FNV-1a 64.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Fnv1a(pub u64);

impl Fnv1a {
    /// A fresh hash (the offset basis).
    pub fn new() -> Self {
        Self(FNV_OFFSET)
    }

    /// Feeds bytes.
    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(FNV_PRIME);
        }
    }
}

impl Mesh {
    /// A stable 64-bit hash of the geometry (positions and triangles; not normals, name or
    /// material), for bake files to check that they belong to a mesh.
    ///
    /// Exactly: FNV-1a 64 (offset basis `0xcbf29ce484222325`, prime `0x100000001b3`, each byte
    /// XORed in then multiplied) over the byte string made of the vertex count as u64
    /// little-endian, the triangle count as u64 little-endian, then every position's x, y, z
    /// as the little-endian bytes of their f32 bit patterns, then every triangle's three
    /// indices as u32 little-endian.
    #[must_use]
    pub fn geometry_hash(&self) -> u64 {
        let mut h = Fnv1a::new();
        self.hash_into(&mut h);
        h.0
    }

    pub(crate) fn hash_into(&self, h: &mut Fnv1a) {
        h.write(&(self.positions.len() as u64).to_le_bytes());
        h.write(&(self.indices.len() as u64).to_le_bytes());
        for p in &self.positions {
            for c in p.to_array() {
                h.write(&c.to_bits().to_le_bytes());
            }
        }
        for t in &self.indices {
            for i in t {
                h.write(&i.to_le_bytes());
            }
        }
    }

    /// Axis-aligned bounds `(min, max)` of the vertices; `None` for a mesh without vertices.
    #[must_use]
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))),
        )
    }

    /// Unit geometric normal of triangle `t` (right-handed winding), zero if degenerate.
    #[must_use]
    pub fn face_normal(&self, t: usize) -> Vec3 {
        let [a, b, c] = self.indices[t].map(|i| self.positions[i as usize].as_dvec3());
        (b - a).cross(c - a).normalize_or_zero().as_vec3()
    }

    /// Total surface area (computed in f64).
    #[must_use]
    pub fn surface_area(&self) -> f64 {
        self.indices
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.positions[i as usize].as_dvec3());
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    /// Applies an affine transform in place: positions by `m`, normals by its inverse transpose
    /// (renormalised), winding reversed when `m` mirrors (negative determinant).
    pub fn transform(&mut self, m: &DMat4) {
        self.transform_positions(m);
        let nm = normal_matrix(m);
        for n in &mut self.normals {
            *n = (nm * n.as_dvec3()).normalize_or_zero().as_vec3();
        }
    }

    /// Positions and winding only (normals untouched).
    fn transform_positions(&mut self, m: &DMat4) {
        if *m == DMat4::IDENTITY {
            return;
        }
        for p in &mut self.positions {
            *p = m.transform_point3(p.as_dvec3()).as_vec3();
        }
        if DMat3::from_mat4(*m).determinant() < 0.0 {
            for t in &mut self.indices {
                t.swap(1, 2);
            }
        }
    }
}

/// The object transform of the scene file: `v' = T + Rz·Ry·Rx·(S·v)`, angles in degrees.
#[must_use]
pub fn object_transform(translate: DVec3, rotate_deg: DVec3, scale: DVec3) -> DMat4 {
    let r = DMat3::from_rotation_z(rotate_deg.z.to_radians())
        * DMat3::from_rotation_y(rotate_deg.y.to_radians())
        * DMat3::from_rotation_x(rotate_deg.x.to_radians());
    DMat4::from_translation(translate) * DMat4::from_mat3(r) * DMat4::from_scale(scale)
}
