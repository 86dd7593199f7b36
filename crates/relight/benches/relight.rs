//! Benchmarks of full-order and adaptive relighting (placeholder).
fn main() {}
