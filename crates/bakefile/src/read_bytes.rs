//! The reader's primitives: little-endian fields (SPEC.md §1), section payloads by index, and
//! the shapes shared by several sections — table headers, strings in `STRS` (§3.2), packed
//! f64 arrays — each checked against its payload's length before it is used (§4 rule 8).

use crate::error::{inconsistent, invalid, BakeFileError};
use crate::layout::{Tag, TABLE_HEADER_SIZE};
use crate::located::SectionEntry;
use crate::model::check_finite64;

/// The u32 at byte `off` of `b`.
pub(crate) fn rd_u32(b: &[u8], off: usize) -> u32 {
    u32::from_le_bytes(b[off..off + 4].try_into().expect("4 bytes"))
}

/// The u64 at byte `off` of `b`.
pub(crate) fn rd_u64(b: &[u8], off: usize) -> u64 {
    u64::from_le_bytes(b[off..off + 8].try_into().expect("8 bytes"))
}

/// The f64 at byte `off` of `b`.
pub(crate) fn rd_f64(b: &[u8], off: usize) -> f64 {
    f64::from_bits(rd_u64(b, off))
}

/// How errors name section `index` of the table: `TAG#index`.
pub(crate) fn section_name(tag: Tag, index: usize) -> String {
    format!("{tag}#{index}")
}

/// The file's bytes and its section table, checked under SPEC.md §4 rule 6 (every entry's
/// payload lies inside the file): payloads by section index.
#[derive(Clone, Copy)]
pub(crate) struct Payloads<'a, 's> {
    pub(crate) bytes: &'a [u8],
    pub(crate) sections: &'s [SectionEntry],
}

impl<'a> Payloads<'a, '_> {
    /// The payload of section `i`.
    pub(crate) fn get(&self, i: usize) -> &'a [u8] {
        let s = &self.sections[i];
        &self.bytes[s.offset as usize..(s.offset + s.length) as usize]
    }
}

/// Reads a table section's 16-byte header and checks its length; returns (count, record size).
pub(crate) fn table(
    payload: &[u8],
    name: &str,
    min_record: usize,
) -> Result<(usize, usize), BakeFileError> {
    if payload.len() < TABLE_HEADER_SIZE {
        return Err(inconsistent(
            format!("{name} length"),
            TABLE_HEADER_SIZE as u64,
            payload.len() as u64,
        ));
    }
    let count = rd_u32(payload, 0) as usize;
    let record = rd_u32(payload, 4) as usize;
    if record < min_record {
        return Err(invalid(
            format!("{name} record size"),
            format!("{record} < {min_record}"),
        ));
    }
    let records_end = (count as u64) * (record as u64) + TABLE_HEADER_SIZE as u64;
    if records_end > payload.len() as u64 {
        return Err(inconsistent(
            format!("{name} length for {count} records"),
            records_end,
            payload.len() as u64,
        ));
    }
    Ok((count, record))
}

/// The string at `off`, `len` of the string pool `strs` (SPEC.md §3.2): inside it and UTF-8.
pub(crate) fn string(
    strs: &[u8],
    off: u32,
    len: u32,
    field: &str,
) -> Result<String, BakeFileError> {
    let end = u64::from(off) + u64::from(len);
    if end > strs.len() as u64 {
        return Err(invalid(
            field,
            format!("string {off}+{len} beyond the {}-byte pool", strs.len()),
        ));
    }
    std::str::from_utf8(&strs[off as usize..end as usize])
        .map(str::to_owned)
        .map_err(|e| invalid(field, format!("not UTF-8: {e}")))
}

/// Reads `count` f64 at byte `off` of `payload`, which must be exactly `expected_off`.
pub(crate) fn f64s(
    payload: &[u8],
    off: u64,
    expected_off: u64,
    count: u64,
    name: &str,
) -> Result<Vec<f64>, BakeFileError> {
    if off != expected_off {
        return Err(inconsistent(format!("{name} offset"), expected_off, off));
    }
    let end = count
        .checked_mul(8)
        .and_then(|n| n.checked_add(off))
        .filter(|&e| e <= payload.len() as u64)
        .ok_or_else(|| {
            inconsistent(
                format!("{name}: bytes for {count} f64 at offset {off}"),
                count.saturating_mul(8).saturating_add(off),
                payload.len() as u64,
            )
        })?;
    let v: Vec<f64> = payload[off as usize..end as usize]
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
        .collect();
    check_finite64(name, &v)?;
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table_bytes(count: u32, record: u32, records: usize) -> Vec<u8> {
        let mut b = Vec::new();
        b.extend_from_slice(&count.to_le_bytes());
        b.extend_from_slice(&record.to_le_bytes());
        b.extend_from_slice(&[0; 8]);
        b.resize(16 + records, 0);
        b
    }

    #[test]
    fn a_table_header_is_checked_against_its_payload() {
        assert_eq!(table(&table_bytes(2, 40, 80), "T", 32).unwrap(), (2, 40));
        let short = table(&[0; 15], "T", 32).unwrap_err();
        assert_eq!(
            short.to_string(),
            "inconsistent counts: T length: expected 16, found 15"
        );
        let small = table(&table_bytes(1, 8, 8), "T", 32).unwrap_err();
        assert_eq!(small.to_string(), "invalid T record size: 8 < 32");
        // u32::MAX records of u32::MAX bytes: no overflow, and refused.
        let huge = table(&table_bytes(u32::MAX, u32::MAX, 0), "T", 32).unwrap_err();
        assert!(
            huge.to_string().contains("T length for 4294967295 records"),
            "{huge}"
        );
    }

    #[test]
    fn strings_lie_inside_the_pool_and_are_utf8() {
        let pool = "floor名".as_bytes();
        assert_eq!(string(pool, 5, 3, "s").unwrap(), "名");
        assert!(string(pool, 5, 4, "s").is_err());
        assert!(string(pool, u32::MAX, u32::MAX, "s").is_err());
        assert!(string(pool, 5, 1, "s")
            .unwrap_err()
            .to_string()
            .contains("not UTF-8"));
    }

    #[test]
    fn packed_f64_arrays_sit_exactly_where_expected_and_are_finite() {
        let mut p = vec![0u8; 8];
        p.extend_from_slice(&1.5f64.to_le_bytes());
        p.extend_from_slice(&(-2.0f64).to_le_bytes());
        assert_eq!(f64s(&p, 8, 8, 2, "v").unwrap(), [1.5, -2.0]);
        assert!(f64s(&p, 0, 8, 2, "v")
            .unwrap_err()
            .to_string()
            .contains("v offset"));
        assert!(f64s(&p, 8, 8, 3, "v").is_err());
        assert!(f64s(&p, 8, 8, u64::MAX, "v").is_err());
        p[16..24].copy_from_slice(&f64::NAN.to_le_bytes());
        assert!(matches!(
            f64s(&p, 8, 8, 2, "v"),
            Err(BakeFileError::NonFinite { index: 1, .. })
        ));
    }
}
