//! SPEC.md §4 rules 1–7, each completely before the next: the file header (§2.1), the
//! section table (§2.2) with its checksums (§2.3), and which sections of §3 are present.
//! Each step trusts what the earlier ones vouch for.

use std::ops::Range;

use crate::encode::header_crc;
use crate::error::{inconsistent, invalid, BakeFileError};
use crate::layout::{
    Tag, HEADER_SIZE, MAGIC, MUST_UNDERSTAND_FLAGS, SECTION_ENTRY_SIZE, SECTION_FLAG_REQUIRED,
    VERSION_MAJOR,
};
use crate::located::SectionEntry;
use crate::model::ScalarType;
use crate::read_bytes::{rd_u32, rd_u64, section_name};

/// Rule 1: the file opens with (a prefix of) the magic, so that every prefix of a valid file
/// is reported as truncated (rule 2) rather than as a stranger.
pub(crate) fn check_magic(bytes: &[u8]) -> Result<(), BakeFileError> {
    let head = &bytes[..bytes.len().min(8)];
    if head != &MAGIC[..head.len()] {
        return Err(BakeFileError::BadMagic {
            found: head.to_vec(),
        });
    }
    Ok(())
}

/// Rule 2: a whole header, and a major version this reader knows (whatever follows);
/// returns `(major, minor)`.
pub(crate) fn check_size_and_version(bytes: &[u8]) -> Result<(u32, u32), BakeFileError> {
    if bytes.len() < HEADER_SIZE {
        return Err(BakeFileError::Truncated {
            needed: HEADER_SIZE as u64,
            available: bytes.len() as u64,
        });
    }
    let (major, minor) = (rd_u32(bytes, 8), rd_u32(bytes, 12));
    if major != VERSION_MAJOR {
        return Err(BakeFileError::UnsupportedVersion {
            major,
            minor,
            supported: VERSION_MAJOR,
        });
    }
    Ok((major, minor))
}

/// Rule 3: the header's `file_size` is the file's length (§2.1).
pub(crate) fn check_file_size(bytes: &[u8]) -> Result<(), BakeFileError> {
    let len = bytes.len() as u64;
    let file_size = rd_u64(bytes, 24);
    if len < file_size {
        return Err(BakeFileError::Truncated {
            needed: file_size,
            available: len,
        });
    }
    if len > file_size {
        return Err(inconsistent("file size (trailing bytes)", file_size, len));
    }
    Ok(())
}

/// Rule 4: the section table lies inside the file, after the header, 8-aligned, and the
/// header CRC (§2.3) covers the header and the table as written; returns the table's byte
/// range.
pub(crate) fn locate_section_table(bytes: &[u8]) -> Result<Range<u64>, BakeFileError> {
    let len = bytes.len() as u64;
    let table_off = rd_u64(bytes, 32);
    let section_count = rd_u32(bytes, 40) as u64;
    let table_end = section_count
        .checked_mul(SECTION_ENTRY_SIZE as u64)
        .and_then(|n| n.checked_add(table_off))
        .filter(|&e| table_off >= HEADER_SIZE as u64 && table_off % 8 == 0 && e <= len)
        .ok_or_else(|| BakeFileError::OutOfBounds {
            section: "section table".into(),
            offset: table_off,
            length: section_count.saturating_mul(SECTION_ENTRY_SIZE as u64),
            file_size: len,
        })?;
    let table_bytes = &bytes[table_off as usize..table_end as usize];
    let stored = rd_u32(bytes, 60);
    let computed = header_crc(&bytes[..HEADER_SIZE], table_bytes);
    if stored != computed {
        return Err(BakeFileError::ChecksumMismatch {
            section: "header".into(),
            stored,
            computed,
        });
    }
    Ok(table_off..table_end)
}

/// Rule 5: the header's fields (§2.1), in this order: header size, entry size, flags, payload
/// alignment, scalar type; returns the alignment and the scalar type.
pub(crate) fn check_header_fields(bytes: &[u8]) -> Result<(u64, ScalarType), BakeFileError> {
    let header_size = rd_u32(bytes, 16);
    if header_size as usize != HEADER_SIZE {
        return Err(inconsistent(
            "header size",
            HEADER_SIZE as u64,
            header_size.into(),
        ));
    }
    let entry_size = rd_u32(bytes, 44);
    if entry_size as usize != SECTION_ENTRY_SIZE {
        return Err(inconsistent(
            "section entry size",
            SECTION_ENTRY_SIZE as u64,
            entry_size.into(),
        ));
    }
    let flags = rd_u32(bytes, 20);
    if flags & MUST_UNDERSTAND_FLAGS != 0 {
        return Err(BakeFileError::UnsupportedFlags {
            location: "header".into(),
            flags: flags & MUST_UNDERSTAND_FLAGS,
        });
    }
    let alignment = u64::from(rd_u32(bytes, 48));
    if !alignment.is_power_of_two() || !(16..=4096).contains(&alignment) {
        return Err(invalid(
            "payload alignment",
            format!("{alignment} is not a power of two in 16..=4096"),
        ));
    }
    let scalar_code = rd_u32(bytes, 52);
    let scalar = ScalarType::from_code(scalar_code)
        .ok_or_else(|| invalid("scalar type", format!("unknown code {scalar_code}")))?;
    Ok((alignment, scalar))
}

/// Rule 6: the section table at `table` (§2.2) — each entry's tag, flags, alignment and
/// bounds; then no overlap and zero padding over the whole file; then each payload's CRC.
pub(crate) fn read_section_table(
    bytes: &[u8],
    table: &Range<u64>,
    alignment: u64,
) -> Result<Vec<SectionEntry>, BakeFileError> {
    let sections = read_section_entries(bytes, table, alignment)?;
    check_regions(bytes, table, &sections)?;
    check_section_checksums(bytes, &sections)?;
    Ok(sections)
}

/// Rule 6 (a)–(d), entry by entry in table order.
fn read_section_entries(
    bytes: &[u8],
    table: &Range<u64>,
    alignment: u64,
) -> Result<Vec<SectionEntry>, BakeFileError> {
    let len = bytes.len() as u64;
    let table_bytes = &bytes[table.start as usize..table.end as usize];
    let mut sections = Vec::with_capacity(table_bytes.len() / SECTION_ENTRY_SIZE);
    for (i, e) in table_bytes.chunks_exact(SECTION_ENTRY_SIZE).enumerate() {
        let s = SectionEntry {
            tag: Tag(e[0..4].try_into().expect("4 bytes")),
            flags: rd_u32(e, 4),
            offset: rd_u64(e, 8),
            length: rd_u64(e, 16),
            crc32: rd_u32(e, 24),
        };
        let name = section_name(s.tag, i);
        // Printable ASCII, no space: a zeroed entry (a `section_count` one too many, over
        // the padding) is not read as an empty optional section.
        if !s.tag.0.iter().all(|b| (0x21..=0x7e).contains(b)) {
            return Err(invalid(
                format!("section table entry {i}"),
                format!(
                    "tag bytes {:02x?} are not four printable ASCII characters",
                    s.tag.0
                ),
            ));
        }
        let unknown = s.flags & MUST_UNDERSTAND_FLAGS & !SECTION_FLAG_REQUIRED;
        if unknown != 0 {
            return Err(BakeFileError::UnsupportedFlags {
                location: name,
                flags: unknown,
            });
        }
        if s.offset % alignment != 0 {
            return Err(BakeFileError::Misaligned {
                section: name,
                offset: s.offset,
                alignment,
            });
        }
        if s.offset.checked_add(s.length).is_none_or(|end| end > len) {
            return Err(BakeFileError::OutOfBounds {
                section: name,
                offset: s.offset,
                length: s.length,
                file_size: len,
            });
        }
        sections.push(s);
    }
    Ok(sections)
}

/// Rule 6, regions (§2): the header, the table and every non-empty payload, sorted by start,
/// do not overlap, and every byte outside them is zero.
fn check_regions(
    bytes: &[u8],
    table: &Range<u64>,
    sections: &[SectionEntry],
) -> Result<(), BakeFileError> {
    let mut regions: Vec<(u64, u64, String)> = vec![
        (0, HEADER_SIZE as u64, "file header".into()),
        (table.start, table.end, "section table".into()),
    ];
    for (i, s) in sections.iter().enumerate() {
        if s.length > 0 {
            regions.push((s.offset, s.offset + s.length, section_name(s.tag, i)));
        }
    }
    regions.sort();
    let mut covered = 0u64;
    let mut last = String::new();
    for (start, end, name) in &regions {
        if *start < covered {
            return Err(BakeFileError::Overlap {
                first: last,
                second: name.clone(),
            });
        }
        if bytes[covered as usize..*start as usize]
            .iter()
            .any(|&b| b != 0)
        {
            return Err(invalid(
                "padding",
                format!("non-zero byte between offsets {covered} and {start}"),
            ));
        }
        covered = *end;
        last.clone_from(name);
    }
    if bytes[covered as usize..].iter().any(|&b| b != 0) {
        return Err(invalid("padding", "non-zero byte after the last section"));
    }
    Ok(())
}

/// Rule 6, last: each payload's CRC-32 (§2.3), in table order.
fn check_section_checksums(bytes: &[u8], sections: &[SectionEntry]) -> Result<(), BakeFileError> {
    for (i, s) in sections.iter().enumerate() {
        let computed = crc32fast::hash(&bytes[s.offset as usize..(s.offset + s.length) as usize]);
        if computed != s.crc32 {
            return Err(BakeFileError::ChecksumMismatch {
                section: section_name(s.tag, i),
                stored: s.crc32,
                computed,
            });
        }
    }
    Ok(())
}

/// The indices of the sections that appear at most once (SPEC.md §3's table), found under
/// rule 7: the mandatory ones are present.
#[derive(Debug, Clone, Copy)]
pub(crate) struct FoundSections {
    pub(crate) binf: usize,
    pub(crate) strs: usize,
    pub(crate) objt: usize,
    pub(crate) blkt: usize,
    pub(crate) meta: usize,
    pub(crate) envl: Option<usize>,
    pub(crate) brdf: Option<usize>,
    pub(crate) glsy: Option<usize>,
    pub(crate) rfld: Option<usize>,
}

/// The sections that may appear several times (each counted under rule 9).
const REPEATED: [Tag; 5] = [Tag::XFER, Tag::MESH, Tag::CVRG, Tag::PASS, Tag::CPCA];

/// Rule 7: no second section of a tag that appears once, no unknown REQUIRED section (in
/// table order); then the mandatory sections present; then the REQUIRED flag on every known
/// section but MESH and CVRG.
pub(crate) fn find_sections(sections: &[SectionEntry]) -> Result<FoundSections, BakeFileError> {
    let mut single: [(Tag, Option<usize>, bool); 9] = [
        (Tag::BINF, None, true),
        (Tag::STRS, None, true),
        (Tag::OBJT, None, true),
        (Tag::BLKT, None, true),
        (Tag::META, None, true),
        (Tag::ENVL, None, false),
        (Tag::BRDF, None, false),
        (Tag::GLSY, None, false),
        (Tag::RFLD, None, false),
    ];
    for (i, s) in sections.iter().enumerate() {
        if let Some(slot) = single.iter_mut().find(|(t, _, _)| *t == s.tag) {
            if slot.1.is_some() {
                return Err(BakeFileError::DuplicateSection(s.tag.to_string()));
            }
            slot.1 = Some(i);
        } else if !REPEATED.contains(&s.tag) && s.flags & SECTION_FLAG_REQUIRED != 0 {
            return Err(BakeFileError::UnknownRequiredSection(section_name(
                s.tag, i,
            )));
        }
    }
    for (tag, index, required) in &single {
        if *required && index.is_none() {
            return Err(BakeFileError::MissingSection(tag.to_string()));
        }
    }
    // Every section of §3's table but MESH and CVRG is REQUIRED: a reader that skipped
    // an unmarked PASS, CPCA or RFLD would misread the file and not know it.
    for (i, s) in sections.iter().enumerate() {
        let known = single.iter().any(|(t, _, _)| *t == s.tag)
            || [Tag::XFER, Tag::PASS, Tag::CPCA].contains(&s.tag);
        if known && s.flags & SECTION_FLAG_REQUIRED == 0 {
            return Err(invalid(
                section_name(s.tag, i),
                format!(
                    "a {} section without the REQUIRED flag (every section of SPEC §3's table but MESH and CVRG carries it)",
                    s.tag
                ),
            ));
        }
    }
    let [binf, strs, objt, blkt, meta, envl, brdf, glsy, rfld] = single.map(|(_, i, _)| i);
    let present = "checked present above";
    Ok(FoundSections {
        binf: binf.expect(present),
        strs: strs.expect(present),
        objt: objt.expect(present),
        blkt: blkt.expect(present),
        meta: meta.expect(present),
        envl,
        brdf,
        glsy,
        rfld,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(tag: &[u8; 4], flags: u32) -> SectionEntry {
        SectionEntry {
            tag: Tag(*tag),
            flags,
            offset: 0,
            length: 0,
            crc32: 0,
        }
    }

    #[test]
    fn every_prefix_of_the_magic_passes_rule_1() {
        for n in 0..=8 {
            check_magic(&MAGIC[..n]).unwrap();
        }
        assert!(matches!(
            check_magic(b"PRTBAKX"),
            Err(BakeFileError::BadMagic { found }) if found == b"PRTBAKX"
        ));
        assert!(matches!(
            check_size_and_version(&MAGIC),
            Err(BakeFileError::Truncated {
                needed: 64,
                available: 8
            })
        ));
    }

    #[test]
    fn sections_are_found_and_their_flags_checked_in_rule_7_order() {
        let required = SECTION_FLAG_REQUIRED;
        let mut table: Vec<SectionEntry> = [b"BINF", b"STRS", b"OBJT", b"BLKT", b"META"]
            .into_iter()
            .map(|t| entry(t, required))
            .collect();
        table.push(entry(b"XFER", required));
        table.push(entry(b"MESH", 0));
        table.push(entry(b"ZZZZ", 0));
        table.push(entry(b"GLSY", required));
        let found = find_sections(&table).unwrap();
        assert_eq!((found.binf, found.meta, found.glsy), (0, 4, Some(8)));
        assert_eq!((found.envl, found.rfld), (None, None));

        let mut twice = table.clone();
        twice.push(entry(b"GLSY", required));
        assert_eq!(
            find_sections(&twice).unwrap_err().to_string(),
            "section GLSY appears more than once"
        );
        // A missing section is found before an unflagged one.
        let mut missing = table.clone();
        missing[5].flags = 0;
        missing.remove(3);
        assert!(matches!(
            find_sections(&missing),
            Err(BakeFileError::MissingSection(t)) if t == "BLKT"
        ));
        let mut unflagged = table.clone();
        unflagged[5].flags = 0;
        assert!(find_sections(&unflagged)
            .unwrap_err()
            .to_string()
            .starts_with("invalid XFER#5: a XFER section without the REQUIRED flag"));
        let mut unknown = table;
        unknown[7].flags = required;
        assert!(matches!(
            find_sections(&unknown),
            Err(BakeFileError::UnknownRequiredSection(s)) if s == "ZZZZ#7"
        ));
    }
}
