//! Per-point rows: transfer accumulated in f64, stored as the f32 blocks of a file object, and
//! the ray statistics of each point.

use crate::transfer::DirectResult;
use prt_bakefile::{RayStats, TransferBlock, TransferKind};

/// The ray statistics of one point that traced `rays` diffuse rays: it started inside
/// geometry when more than half of them hit the back of a surface.
pub(crate) fn point_stats(d: &DirectResult, rays: u32) -> RayStats {
    let inside = 2 * d.backface_hits > rays;
    RayStats {
        object: String::new(),
        points: 1,
        rays: u64::from(rays),
        backface_hits: u64::from(d.backface_hits),
        inside_points: u64::from(inside),
        inside_rays: if inside { u64::from(rays) } else { 0 },
    }
}

/// `dst += weight · src` element-wise.
pub(crate) fn add_scaled(dst: &mut [f64], src: &[f64], weight: f64) {
    dst.iter_mut().zip(src).for_each(|(d, s)| *d += weight * s);
}

/// `dst = src` rounded to f32.
pub(crate) fn store(dst: &mut [f32], src: &[f64]) {
    dst.iter_mut().zip(src).for_each(|(d, s)| *d = *s as f32);
}

/// The blocks of a per-pixel or per-texel object, in block order: its diffuse transfer
/// (interreflected with bounces, else shadowed) and the optional visibility and unshadowed
/// transfer.
pub(crate) fn point_blocks(
    bounces: u32,
    diffuse: Vec<f32>,
    visibility: Option<Vec<f32>>,
    unshadowed: Option<Vec<f32>>,
) -> Vec<TransferBlock> {
    let kind = if bounces > 0 {
        TransferKind::InterreflectedDiffuse { bounces }
    } else {
        TransferKind::ShadowedDiffuse
    };
    let block = |kind, data| TransferBlock {
        cpca: None,
        kind,
        data,
    };
    let mut blocks = vec![block(kind, diffuse)];
    blocks.extend(visibility.map(|v| block(TransferKind::Visibility, v)));
    blocks.extend(unshadowed.map(|u| block(TransferKind::UnshadowedDiffuse, u)));
    blocks.sort_by_key(|b| b.kind);
    blocks
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_point_is_inside_when_more_than_half_its_rays_hit_backfaces() {
        let at = |backface_hits| {
            let d = DirectResult {
                backface_hits,
                ..DirectResult::default()
            };
            point_stats(&d, 10)
        };
        let half = at(5);
        assert_eq!((half.inside_points, half.inside_rays), (0, 0));
        let more = at(6);
        assert_eq!((more.inside_points, more.inside_rays), (1, 10));
        assert_eq!((more.points, more.rays, more.backface_hits), (1, 10, 6));
    }

    #[test]
    fn blocks_come_in_block_order_with_the_diffuse_kind_of_the_bounces() {
        let kinds = |bounces, vis: bool, unsh: bool| {
            point_blocks(
                bounces,
                vec![1.0],
                vis.then(|| vec![2.0]),
                unsh.then(|| vec![3.0]),
            )
            .iter()
            .map(|b| (b.kind, b.data[0]))
            .collect::<Vec<_>>()
        };
        assert_eq!(
            kinds(0, false, false),
            [(TransferKind::ShadowedDiffuse, 1.0)]
        );
        let all = kinds(2, true, true);
        assert_eq!(all.len(), 3);
        assert!(all.windows(2).all(|w| w[0].0 < w[1].0), "{all:?}");
        assert!(all.contains(&(TransferKind::InterreflectedDiffuse { bounces: 2 }, 1.0)));
        assert!(all.contains(&(TransferKind::Visibility, 2.0)));
        assert!(all.contains(&(TransferKind::UnshadowedDiffuse, 3.0)));
    }

    #[test]
    fn accumulation_is_in_f64_and_storage_rounds_to_f32() {
        let mut acc = vec![1.0f64, 2.0];
        add_scaled(&mut acc, &[0.5, 1.0], 0.25);
        assert_eq!(acc, [1.125, 2.25]);
        let mut out = [0.0f32; 2];
        store(&mut out, &[0.1, 1.0 + 1e-12]);
        assert_eq!(out, [0.1f32, 1.0]);
    }
}
