//! Fuzzing without cargo-fuzz: thousands of seeded random mutations of valid files must
//! decode to a result (mostly an error), never panic, and the view must agree with decode.
//! Half the mutants get their CRCs recomputed so that the checks behind the checksums run.

mod common;

use common::*;
use prt_bakefile::*;
use rand::Rng;

fn mutate(r: &mut impl Rng, b: &mut Vec<u8>) {
    for _ in 0..r.random_range(1..4) {
        if b.is_empty() {
            return;
        }
        let i = r.random_range(0..b.len());
        match r.random_range(0..6) {
            0 => b[i] ^= 1 << r.random_range(0..8),
            1 => b[i] = r.random(),
            2 => {
                // Overwrite an aligned u32/u64 field with an extreme value.
                let i = i & !7;
                let v: u64 = [0, 1, u64::MAX, u64::from(u32::MAX), 1 << 40, r.random()]
                    [r.random_range(0..6)];
                let n = if r.random_bool(0.5) { 4 } else { 8 }.min(b.len() - i);
                b[i..i + n].copy_from_slice(&v.to_le_bytes()[..n]);
            }
            3 => b.truncate(i),
            4 => b.insert(i, r.random()),
            _ => {
                b.remove(i);
            }
        }
    }
}

#[test]
fn test01_random_mutations_never_panic() {
    let mut r = rng(31337);
    let mut bases: Vec<Vec<u8>> = vec![
        encode(&sample_bake(), ScalarType::F32).unwrap(),
        encode(&sample_bake(), ScalarType::F16).unwrap(),
    ];
    for _ in 0..6 {
        bases.push(encode(&random_bake(&mut r), ScalarType::F16).unwrap());
    }
    let (mut accepted, mut total) = (0, 0);
    for i in 0..6000 {
        let mut b = bases[i % bases.len()].clone();
        mutate(&mut r, &mut b);
        if i % 2 == 0 && b.len() >= 64 {
            // Only when the table lies inside the file.
            let table = u64::from_le_bytes(b[32..40].try_into().unwrap());
            let count = u64::from(u32::from_le_bytes(b[40..44].try_into().unwrap()));
            if table >= 64 && table.saturating_add(count.saturating_mul(32)) <= b.len() as u64 {
                fix_crcs(&mut b);
            }
        }
        total += 1;
        let d = decode(&b);
        let v = BakeView::new(&b);
        assert_eq!(d.is_ok(), v.is_ok(), "mutant {i}");
        if let (Ok(bake), Ok(view)) = (d, v) {
            accepted += 1;
            assert_eq!(view.to_bake().unwrap(), bake);
            let again = encode(&bake, view.scalar_type()).unwrap();
            assert_eq!(decode(&again).unwrap(), bake, "mutant {i}");
        }
    }
    // Most mutants are refused; a few (e.g. a changed data value with fixed CRCs) are valid.
    assert!(
        accepted > 0 && accepted < total / 2,
        "{accepted} of {total} accepted"
    );
}
