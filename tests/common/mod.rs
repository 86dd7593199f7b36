//! Shared helpers for the workspace-level integration tests in `tests/`.
#![allow(dead_code)]

use std::path::PathBuf;

/// The workspace root (where `Cargo.toml` and `scenes/` live).
#[must_use]
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}
