//! Fuzz target: `decode` and `BakeView` on arbitrary bytes must return, never panic, and
//! agree with each other. Each input is tried twice: as given, and with every CRC-32
//! recomputed (per SPEC.md) so that mutations reach the checks behind the checksums.
#![no_main]

use libfuzzer_sys::fuzz_target;

fn check(data: &[u8]) {
    let decoded = prt_bakefile::decode(data);
    match prt_bakefile::BakeView::new(data) {
        Ok(view) => {
            let bake = decoded.expect("view accepted what decode refused");
            assert_eq!(view.to_bake().expect("validated view"), bake);
            let _ = view.summary();
            // What was read must re-encode, and re-read to the same bake.
            let again = prt_bakefile::encode(&bake, view.scalar_type()).expect("re-encode");
            assert_eq!(prt_bakefile::decode(&again).expect("re-decode"), bake);
        }
        Err(_) => assert!(decoded.is_err(), "decode accepted what the view refused"),
    }
}

fn u32_at(b: &[u8], o: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(o..o + 4)?.try_into().ok()?))
}

fn u64_at(b: &[u8], o: usize) -> Option<u64> {
    Some(u64::from_le_bytes(b.get(o..o + 8)?.try_into().ok()?))
}

/// Recomputes the section CRCs and the header CRC where the table can be located.
fn fix_crcs(b: &mut [u8]) -> Option<()> {
    let table = usize::try_from(u64_at(b, 32)?).ok()?;
    let count = u32_at(b, 40)? as usize;
    let table_end = table.checked_add(count.checked_mul(32)?)?;
    if table < 64 || table_end > b.len() {
        return None;
    }
    for i in 0..count {
        let e = table + 32 * i;
        let off = usize::try_from(u64_at(b, e + 8)?).ok()?;
        let len = usize::try_from(u64_at(b, e + 16)?).ok()?;
        if let Some(p) = off.checked_add(len).and_then(|end| b.get(off..end)) {
            let crc = crc32fast::hash(p);
            b[e + 24..e + 28].copy_from_slice(&crc.to_le_bytes());
        }
    }
    let mut h = crc32fast::Hasher::new();
    h.update(&b[..60]);
    h.update(&b[table..table_end]);
    let crc = h.finalize();
    b[60..64].copy_from_slice(&crc.to_le_bytes());
    Some(())
}

fuzz_target!(|data: &[u8]| {
    check(data);
    let mut fixed = data.to_vec();
    if fix_crcs(&mut fixed).is_some() {
        check(&fixed);
    }
});
