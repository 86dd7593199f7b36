//! What several subcommands do the same way.

use anyhow::{bail, Result};
use prt_scene::Scene;
use std::path::Path;

/// Loads a scene file, printing its warnings to stderr.
pub fn load_scene(path: &Path) -> Result<Scene> {
    let loaded = prt_scene::load_scene(path)?;
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    Ok(loaded.scene)
}

/// The bounce count of a bake: the option if given, else the scene's `[render] bounces`
/// (a bake cannot hold unlimited bounces).
pub fn bake_bounces(option: Option<u32>, scene: &Scene, path: &Path) -> Result<u32> {
    match option {
        Some(b) => Ok(b),
        None if scene.render.bounces >= 0 => Ok(scene.render.bounces as u32),
        None => bail!(
            "{}: [render] bounces = -1 (unlimited) cannot be baked; pass --bounces B",
            path.display()
        ),
    }
}

/// `--phong-model` values (see [`prt_scene_relight::PhongModel`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum PhongArg {
    /// The light's cosine taken out of the integral at the lobe's centre.
    FrozenCosine,
    /// The cosine inside, fitted per view elevation like the glossy lobes.
    Fitted,
}

impl From<PhongArg> for prt_scene_relight::PhongModel {
    fn from(a: PhongArg) -> Self {
        match a {
            PhongArg::FrozenCosine => Self::FrozenCosine,
            PhongArg::Fitted => Self::Fitted,
        }
    }
}
