//! Shared helpers of the prt-compare tests.
#![allow(dead_code)]

use std::path::PathBuf;

/// A file of `tests/data/`.
pub fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("data")
        .join(name)
}

/// `expected.json`, written by `tools/compare_reference.py`.
pub fn expected() -> serde_json::Value {
    let text = std::fs::read_to_string(data("expected.json")).expect("read expected.json");
    serde_json::from_str(&text).expect("parse expected.json")
}

/// Asserts `|actual − expected| ≤ tol` with a message.
#[track_caller]
pub fn assert_close(actual: f64, expected: f64, tol: f64, what: &str) {
    assert!(
        (actual - expected).abs() <= tol,
        "{what}: {actual} vs expected {expected} (tolerance {tol})"
    );
}
