//! The reference-precision relighting of a bake's diffuse transfer, in f64.

use crate::error::BakeError;
use prt_bakefile::Bake;

/// Diffuse radiance of every point of object `object` relit in f64 from the bake's own
/// environment coefficients: `(albedo/π) Σ_{i<order²} L_i T_i` per channel, with `T` the
/// object's interreflected (or else shadowed) diffuse transfer and `order` at most the baked
/// one (`None`: the baked order). A reference-precision check of a bake; the fast f32 path is
/// `prt-relight`.
pub fn relit_diffuse(
    bake: &Bake,
    object: usize,
    albedo: [f32; 3],
    order: Option<usize>,
) -> Result<Vec<[f64; 3]>, BakeError> {
    let bad = |m: String| BakeError::InvalidSettings(m);
    let obj = bake
        .objects
        .get(object)
        .ok_or_else(|| bad(format!("the bake has no object {object}")))?;
    let env = bake
        .environment
        .as_ref()
        .ok_or_else(|| bad("the bake has no environment coefficients".into()))?;
    let n2 = (obj.order * obj.order) as usize;
    let en2 = (env.order * env.order) as usize;
    let k = order.map_or(n2, |o| o * o);
    if k == 0 || k > n2 || k > en2 {
        return Err(bad(format!(
            "relighting order {order:?} exceeds the object's order {} or the environment's {}",
            obj.order, env.order
        )));
    }
    let block = obj
        .diffuse_block()
        .ok_or_else(|| bad(format!("object {} has no diffuse transfer", obj.name)))?;
    let ch = obj.channels as usize;
    Ok((0..obj.points_in_file as usize)
        .map(|p| {
            let mut rgb = [0.0; 3];
            for (c, out) in rgb.iter_mut().enumerate() {
                let t = &block.data[(p * ch + c.min(ch - 1)) * n2..][..k];
                let l = &env.values[c * en2..][..k];
                *out = f64::from(albedo[c]) / std::f64::consts::PI
                    * t.iter().zip(l).map(|(a, b)| f64::from(*a) * b).sum::<f64>();
            }
            rgb
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use prt_bakefile::{EnvCoefficients, EnvPrecision, ObjectBake, TransferBlock, TransferKind};

    /// A bake of one order-2 object of two one-channel points under an order-2 environment
    /// whose channel `c` has coefficients `[c + 1, 1, 0, 0]`.
    fn tiny() -> Bake {
        let env: Vec<f64> = (0..3)
            .flat_map(|c| [f64::from(c) + 1.0, 1.0, 0.0, 0.0])
            .collect();
        Bake {
            objects: vec![ObjectBake {
                name: "o".into(),
                order: 2,
                channels: 1,
                points_in_file: 2,
                point_count: 2,
                blocks: vec![TransferBlock {
                    cpca: None,
                    kind: TransferKind::ShadowedDiffuse,
                    data: vec![1.0, 2.0, 5.0, 5.0, 0.5, 0.0, 0.0, 0.0],
                }],
                ..ObjectBake::default()
            }],
            environment: Some(EnvCoefficients {
                order: 2,
                precision: EnvPrecision::F64,
                values: env,
            }),
            ..Bake::default()
        }
    }

    #[test]
    fn relights_as_the_dot_product_of_light_and_transfer_times_albedo_over_pi() {
        let pi = std::f64::consts::PI;
        let close = |got: [f64; 3], want: [f64; 3]| {
            assert!(
                got.iter()
                    .zip(want)
                    .all(|(g, w)| (g - w).abs() <= 1e-12 * w.abs()),
                "{got:?} vs {want:?}"
            );
        };
        let rgb = relit_diffuse(&tiny(), 0, [1.0, 0.5, 2.0], None).unwrap();
        // Point 0: T = [1, 2, 5, 5], L_c = [c + 1, 1, 0, 0] → (c + 1) + 2.
        close(rgb[0], [3.0 / pi, 0.5 * 4.0 / pi, 2.0 * 5.0 / pi]);
        // Point 1: T = [0.5, 0, 0, 0].
        close(rgb[1], [0.5 / pi, 0.5 * 1.0 / pi, 2.0 * 1.5 / pi]);
        // Order 1 keeps the DC term only.
        let dc = relit_diffuse(&tiny(), 0, [1.0; 3], Some(1)).unwrap();
        close(dc[0], [1.0 / pi, 2.0 / pi, 3.0 / pi]);
    }

    #[test]
    fn refuses_missing_objects_environments_and_orders_beyond_the_bake() {
        let err = |b: &Bake, o, order| {
            relit_diffuse(b, o, [1.0; 3], order)
                .unwrap_err()
                .to_string()
        };
        assert!(err(&tiny(), 1, None).contains("no object 1"));
        assert!(err(&tiny(), 0, Some(3)).contains("exceeds"));
        assert!(err(&tiny(), 0, Some(0)).contains("exceeds"));
        let no_env = Bake {
            environment: None,
            ..tiny()
        };
        assert!(err(&no_env, 0, None).contains("no environment"));
        let mut no_diffuse = tiny();
        no_diffuse.objects[0].blocks[0].kind = TransferKind::Visibility;
        assert!(err(&no_diffuse, 0, None).contains("no diffuse transfer"));
    }
}
