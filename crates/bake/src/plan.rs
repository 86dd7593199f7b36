//! What each object needs: its order and its transfer kinds, decided from its material and
//! written down with the reason (the "model only what the scene needs" rule).

use crate::settings::BakeSettings;
use prt_bakefile::Decision;
use prt_scene::{Material, Scene};
use prt_sh::zonal;
use prt_shading::projection::{glossy_table, lobe_energy_beyond};

/// The baker's plan for one object (mesh).
#[derive(Clone, Debug)]
pub struct ObjectPlan {
    /// Index into `scene.meshes`.
    pub mesh: usize,
    /// Unique object name.
    pub name: String,
    /// Order (bands) of every block of this object.
    pub order: usize,
    /// Whether the material has a glossy lobe that relighting multiplies by visibility.
    pub needs_visibility: bool,
}

/// Smallest order whose truncation keeps all but `target` of a zonal lobe's energy.
fn order_for_zonal(g: &[f64], target: f64) -> Option<usize> {
    (1..=g.len()).find(|&o| zonal::energy_beyond(g, o) <= target)
}

/// Order needed by the diffuse (clamped-cosine) lobe.
#[must_use]
pub fn lambert_order(target: f64) -> usize {
    let g = zonal::bands_to_zonal(&zonal::clamped_cosine_bands(64).expect("order 64 is valid"));
    order_for_zonal(&g, target).unwrap_or(64)
}

/// Plans every object. Returns the plans and the decisions log.
pub fn plan(scene: &Scene, settings: &BakeSettings) -> (Vec<ObjectPlan>, Vec<Decision>) {
    let mut plans = Vec::new();
    let mut log = Vec::new();
    let mut names = std::collections::BTreeMap::<String, usize>::new();
    let diffuse_order = lambert_order(settings.error_target);
    for (i, mesh) in scene.meshes.iter().enumerate() {
        let base = if mesh.name.is_empty() {
            format!("object{i}")
        } else {
            mesh.name.clone()
        };
        let count = names.entry(base.clone()).or_insert(0);
        let name = if *count == 0 {
            base.clone()
        } else {
            format!("{base}#{count}")
        };
        *count += 1;
        let material = &scene.materials[mesh.material];
        let mut say = |decision: String, reason: String| {
            log.push(Decision {
                object: Some(name.clone()),
                decision,
                reason,
            });
        };
        let (wanted, needs_visibility) = match material {
            Material::Lambert { .. } => (diffuse_order, false),
            Material::Phong { exponent, .. } => {
                let o = zonal::phong_order_for_energy(f64::from(*exponent), settings.error_target);
                match o {
                    Some(o) => (o.max(diffuse_order), true),
                    None => {
                        say(
                            "specular lobe truncated".into(),
                            format!(
                                "a Phong lobe of exponent {exponent} keeps more than {} of its energy beyond order {}",
                                settings.error_target,
                                prt_sh::MAX_ORDER
                            ),
                        );
                        (prt_sh::MAX_ORDER, true)
                    }
                }
            }
            Material::BlinnPhong { .. }
            | Material::Ward { .. }
            | Material::CookTorrance { .. }
            | Material::Pbr { .. } => {
                // For `pbr` the D·V table: its lobe is the sharpest of the three components.
                let t = glossy_table(material, settings.max_order.max(diffuse_order));
                let o = t
                    .projection_error
                    .iter()
                    .position(|e| e * e <= settings.error_target)
                    .map(|k| k + 1);
                match o {
                    Some(o) => (o.max(diffuse_order), true),
                    // Beyond the table, which stops at the maximum order.
                    None => (usize::MAX, true),
                }
            }
            Material::Mirror { .. } => {
                say(
                    "mirror lobe not baked".into(),
                    "a perfect mirror is a delta lobe: no finite SH order represents it; only its diffuse part (albedo/π) is baked"
                        .into(),
                );
                (diffuse_order, false)
            }
        };
        let order = match settings.order {
            Some(o) => {
                say(format!("order {o}"), "fixed by the user".into());
                o
            }
            None if wanted > settings.max_order => {
                let needs = if wanted == usize::MAX {
                    format!("more than order {}", settings.max_order)
                } else {
                    format!("order {wanted}")
                };
                say(
                    format!("order {}", settings.max_order),
                    format!(
                        "the material needs {needs} to lose at most {} of its lobe energy; capped at the maximum {} (--max-order)",
                        settings.error_target, settings.max_order
                    ),
                );
                settings.max_order
            }
            None => {
                say(
                    format!("order {wanted}"),
                    format!(
                        "smallest order losing at most {} of the material lobe's energy",
                        settings.error_target
                    ),
                );
                wanted
            }
        };
        // A lobe without a zonal form baked below the order it needs (capped or fixed): the
        // same test relighting's `--glossy auto` applies (`prt_scene_relight::sharp_lobe`).
        let loss = (needs_visibility && wanted > order)
            .then(|| lobe_energy_beyond(material, order))
            .flatten()
            .filter(|&l| l > settings.error_target);
        if let Some(loss) = loss {
            say(
                "glossy lobe: relight with an SHRM".into(),
                format!(
                    "the lobe loses {loss:.2e} of its energy beyond the baked order {order}, more than the error target {}: `prt relight --glossy auto` (or `shrm`) shades it from a spherical harmonic reflection map prefiltered to the order it needs, with the lobe's own traced occlusion",
                    settings.error_target
                ),
            );
        }
        if needs_visibility {
            say(
                "visibility transfer".into(),
                "the material has a glossy lobe, relit as (L ⊛ V) convolved with the lobe".into(),
            );
        } else {
            say(
                "no visibility transfer".into(),
                "the material is diffuse only (glossy relighting not needed)".into(),
            );
        }
        plans.push(ObjectPlan {
            mesh: i,
            name,
            order,
            needs_visibility,
        });
    }
    (plans, log)
}

#[cfg(test)]
mod tests {
    use super::*;
    use prt_scene::test_util::icosphere;
    use prt_scene::{Camera, Environment};

    /// A unit icosphere in a `pbr` metal of `roughness`.
    fn metal_sphere(roughness: f32) -> Scene {
        let cam = Camera::look_at(
            glam::DVec3::new(0.0, 0.0, 4.0),
            glam::DVec3::ZERO,
            40.0,
            8,
            8,
        );
        let mut scene = Scene::new(cam, Environment::uniform([1.0; 3]));
        let m = scene.add_material(
            "m",
            Material::Pbr {
                base_color: [0.8; 3],
                metallic: 1.0,
                roughness,
                base_color_texture: None,
                metallic_roughness_texture: None,
            },
        );
        scene.add_mesh(icosphere(1), m);
        scene
    }

    /// The order of a `pbr` object follows its roughness: the sharper the lobe, the more bands
    /// its `D·V` table needs for the same share of its energy (measured: 14, 6, 6 bands for
    /// roughness 0.6, 0.8, 1 at a 1 % target).
    #[test]
    fn pbr_order_follows_roughness() {
        let orders: Vec<usize> = [0.6f32, 0.8, 1.0]
            .iter()
            .map(|&roughness| {
                let settings = BakeSettings {
                    max_order: 20,
                    error_target: 0.01,
                    ..BakeSettings::default()
                };
                let (plans, _) = plan(&metal_sphere(roughness), &settings);
                assert!(plans[0].needs_visibility);
                plans[0].order
            })
            .collect();
        assert!(
            orders[0] >= orders[1] && orders[1] >= orders[2] && orders[0] > orders[2],
            "{orders:?}"
        );
        assert!(orders[2] >= lambert_order(0.01));
    }

    /// A lobe baked below the order it needs gets the decision to relight it from an SHRM; one
    /// baked at what it needs, or a lobe that needs no more (roughness 1 at a 1 % target: 6
    /// bands, as measured above), does not.
    #[test]
    fn a_lobe_baked_below_its_order_is_sent_to_the_shrm() {
        let says_shrm = |roughness: f32, order: usize| {
            let settings = BakeSettings {
                order: Some(order),
                error_target: 0.01,
                ..BakeSettings::default()
            };
            let (_, log) = plan(&metal_sphere(roughness), &settings);
            log.iter().any(|d| d.decision.contains("SHRM"))
        };
        assert!(says_shrm(0.6, 6));
        assert!(!says_shrm(0.6, 14));
        assert!(!says_shrm(1.0, 6));
    }
}
