//! Writes the fuzzing seed corpus (run on request: `cargo test -p prt-bakefile --test corpus
//! -- --ignored`), and checks that the seeds are valid files.

mod common;

use common::*;
use prt_bakefile::*;

#[test]
#[ignore = "writes files into fuzz/corpus; run on request"]
fn write_fuzz_seed_corpus() {
    let dir =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus/bake_reader");
    std::fs::create_dir_all(&dir).unwrap();
    let mut r = rng(99);
    let mut bakes = vec![sample_bake(), Bake::default()];
    bakes.extend((0..12).map(|_| random_bake(&mut r)));
    for (i, bake) in bakes.iter().enumerate() {
        for scalar in [ScalarType::F32, ScalarType::F16] {
            let bytes = encode(bake, scalar).unwrap();
            if bytes.len() > 16_384 {
                continue;
            }
            decode(&bytes).unwrap();
            std::fs::write(dir.join(format!("seed-{i:02}-{}", scalar.name())), bytes).unwrap();
        }
    }
}
