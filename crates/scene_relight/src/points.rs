//! The points an object is relit at: their surface points (vertices, the hits of a per-pixel
//! bake's pixels, or the texels of a lightmap) with their normals (normal-mapped where the
//! material has a normal map, except at vertices, which cannot hold one) and, where the material
//! varies over the surface, its value at each point; and the rows of their transfer, picked
//! for a subset of points and truncated to the order relit at.

use glam::Vec3;
use prt_scene::lightmap::Lightmap;
use prt_scene::{Material, Scene};
use prt_tracer::points::PixelFootprints;
use std::borrow::Cow;

/// The surface points of one object relit (all of them, or a subset's, in its order).
pub(crate) struct PointSet {
    /// Positions.
    pub(crate) positions: Vec<[f32; 3]>,
    /// Unit normals.
    pub(crate) normals: Vec<[f32; 3]>,
    /// The material resolved per point, when it varies over the surface (textures, vertex
    /// colours).
    pub(crate) materials: Option<Vec<Material>>,
}

impl PointSet {
    /// The points of object `o`: its lightmap's texels, the pixels of a per-pixel bake
    /// (`footprints`), or its vertices; only those of `subset` if given.
    pub(crate) fn new(
        scene: &Scene,
        o: usize,
        footprints: Option<&PixelFootprints>,
        lightmap: Option<&Lightmap>,
        eye: [f32; 3],
        subset: Option<&[u32]>,
    ) -> Self {
        let (positions, normals) = surface_points(scene, o, footprints, lightmap, eye);
        let materials = point_materials(scene, o, footprints, lightmap, subset);
        let (positions, normals) = match subset {
            Some(sub) => (
                sub.iter().map(|&i| positions[i as usize]).collect(),
                sub.iter().map(|&i| normals[i as usize]).collect(),
            ),
            None => (positions, normals),
        };
        Self {
            positions,
            normals,
            materials,
        }
    }
}

/// Surface points of object `o`: vertices, or pixel hits for per-pixel bakes, or texels.
fn surface_points(
    scene: &Scene,
    o: usize,
    footprints: Option<&PixelFootprints>,
    lightmap: Option<&Lightmap>,
    eye: [f32; 3],
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let mesh = &scene.meshes[o];
    if let Some(lm) = lightmap {
        // Texels: their surface points; empty texels a placeholder facing away from the
        // camera (their transfer is zero).
        let away = (
            (Vec3::from_array(eye) + Vec3::Y).to_array(),
            Vec3::Y.to_array(),
        );
        // A normal-mapped texel: the map's normal, on the lightmap normal's side (as the bake
        // shaded its transfer with).
        let mapped = scene.has_normal_map(o);
        lm.texels
            .iter()
            .map(|t| {
                t.map_or(away, |t| {
                    let n = if mapped {
                        let n = scene.shading_normal(o, t.triangle, t.bary[1], t.bary[2]);
                        if n.dot(t.normal) < 0.0 {
                            -n
                        } else {
                            n
                        }
                    } else {
                        t.normal
                    };
                    (t.position.to_array(), n.to_array())
                })
            })
            .unzip()
    } else if let Some(fp) = footprints {
        crate::footprint::pixel_surface(scene, fp, o)
            .into_iter()
            .unzip()
    } else {
        (
            mesh.positions.iter().map(|p| p.to_array()).collect(),
            mesh.normals
                .iter()
                .map(|n| n.normalize_or(Vec3::Y).to_array())
                .collect(),
        )
    }
}

/// Materials that vary over the surface (textures, vertex colours): resolved per point (of
/// `subset` if given); `None` for a uniform material.
fn point_materials(
    scene: &Scene,
    o: usize,
    footprints: Option<&PixelFootprints>,
    lightmap: Option<&Lightmap>,
    subset: Option<&[u32]>,
) -> Option<Vec<Material>> {
    let mesh = &scene.meshes[o];
    let material = &scene.materials[mesh.material];
    scene.material_varies(o).then(|| {
        let all = match (footprints, lightmap) {
            (_, Some(lm)) => lm
                .texels
                .iter()
                .map(|t| match t {
                    Some(t) => scene.material_at(
                        o,
                        prt_scene::SurfacePoint::Triangle {
                            tri: t.triangle,
                            u: t.bary[1],
                            v: t.bary[2],
                        },
                    ),
                    None => *material,
                })
                .collect(),
            (Some(fp), None) => crate::footprint::pixel_materials(scene, fp, o),
            (None, None) => (0..mesh.positions.len() as u32)
                .map(|v| scene.material_at(o, prt_scene::SurfacePoint::Vertex(v)))
                .collect(),
        };
        match subset {
            Some(sub) => sub.iter().map(|&i| all[i as usize]).collect(),
            None => all,
        }
    })
}

/// How an object's transfer rows are read: from the baked order to the order relit at, of a
/// subset of its points or of all of them.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Rows<'s> {
    /// The baked order.
    pub(crate) baked: usize,
    /// The order relit at (≤ `baked`).
    pub(crate) order: usize,
    /// Channels per point in the bake.
    pub(crate) channels: usize,
    /// The points relit (`None`: all).
    pub(crate) subset: Option<&'s [u32]>,
}

impl Rows<'_> {
    /// The rows of `data` (`[point][channel][coeff]` at the baked order), the first
    /// `channels_out` channels at the relit order ([`select`]): `data` itself when that is
    /// all of it (every point, channel and band: relighting at the baked order, as each of
    /// inverse lighting's basis images does), else a copy.
    pub(crate) fn select<'d>(&self, data: &'d [f32], channels_out: usize) -> Cow<'d, [f32]> {
        if self.subset.is_none() && self.order == self.baked && self.channels == channels_out {
            return Cow::Borrowed(data);
        }
        Cow::Owned(self.select_owned(data, channels_out))
    }

    /// [`Rows::select`], always a copy.
    fn select_owned(&self, data: &[f32], channels_out: usize) -> Vec<f32> {
        select(
            data,
            self.baked,
            self.order,
            self.channels,
            channels_out,
            self.subset,
        )
    }
}

/// [`truncate`] of the points listed in `subset` only (in that order), or of all of them
/// without a subset; the listed rows are picked before truncating, so a small subset costs
/// little.
fn select(
    data: &[f32],
    from: usize,
    to: usize,
    channels: usize,
    channels_out: usize,
    subset: Option<&[u32]>,
) -> Vec<f32> {
    match subset {
        None => truncate(data, from, to, channels, channels_out),
        Some(sub) => {
            let stride = channels * from * from;
            let rows: Vec<f32> = sub
                .iter()
                .flat_map(|&i| &data[i as usize * stride..(i as usize + 1) * stride])
                .copied()
                .collect();
            truncate(&rows, from, to, channels, channels_out)
        }
    }
}

/// Repacks `[point][channel][coeff]` data from order `from` to order `to ≤ from`, keeping
/// `channels_out` channels (the first ones).
fn truncate(
    data: &[f32],
    from: usize,
    to: usize,
    channels: usize,
    channels_out: usize,
) -> Vec<f32> {
    if from == to && channels == channels_out {
        return data.to_vec();
    }
    let (f2, t2) = (from * from, to * to);
    let points = data.len() / (channels * f2);
    let mut out = Vec::with_capacity(points * channels_out * t2);
    for p in 0..points {
        for c in 0..channels_out {
            let s = (p * channels + c) * f2;
            out.extend_from_slice(&data[s..s + t2]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn select_picks_the_subset_rows_then_truncates() {
        // Three points of order 3 with 2 channels: value = 100·point + 10·channel + coeff.
        let (from, channels) = (3usize, 2usize);
        let data: Vec<f32> = (0..3)
            .flat_map(|p| {
                (0..channels)
                    .flat_map(move |c| (0..from * from).map(move |i| (100 * p + 10 * c + i) as f32))
            })
            .collect();
        // Order 2, first channel only, points 2 and 0 in that order.
        let got = select(&data, from, 2, channels, 1, Some(&[2, 0]));
        assert_eq!(got, [200.0, 201.0, 202.0, 203.0, 0.0, 1.0, 2.0, 3.0]);
        // Both channels of every point at the full order: the data itself.
        assert_eq!(select(&data, from, from, channels, channels, None), data);
        // All points, order 1, both channels.
        let got = select(&data, from, 1, channels, channels, None);
        assert_eq!(got, [0.0, 10.0, 100.0, 110.0, 200.0, 210.0]);
    }
}
