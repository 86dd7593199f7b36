//! SPEC.md §4 rules 8–10 for the sections that belong to the whole bake rather than to one
//! object: `RFLD` (§3.14), `ENVL` (§3.6), `BRDF` (§3.7) and `GLSY` (§3.8) — each length
//! before the structure it bounds, each array's finiteness as it is read.

use crate::error::{inconsistent, invalid, BakeFileError};
use crate::field::{first_breaking, FieldValues, Rule};
use crate::layout::{BRDF_RECORD, ENVL_HEADER, GLSY_RECORD, RFLD_HEADER, TABLE_HEADER_SIZE};
use crate::located::FieldLocation;
use crate::model::{
    check_finite64, BrdfLobe, BrdfProjection, EnvCoefficients, EnvPrecision, GlossyBrdfTable,
    ScalarType,
};
use crate::read_bytes::{f64s, rd_f64, rd_u32, rd_u64, string, table};

/// Reads an RFLD payload (SPEC.md §3.14) that starts at byte `offset` of the file: lengths
/// checked before anything is allocated, values finite and non-negative (checked in place, on
/// their bits: nothing is decoded).
pub(crate) fn read_reflectance(
    p: &[u8],
    scalar: ScalarType,
    offset: usize,
) -> Result<FieldLocation, BakeFileError> {
    if p.len() < RFLD_HEADER {
        return Err(inconsistent(
            "RFLD length (at least its header)",
            RFLD_HEADER as u64,
            p.len() as u64,
        ));
    }
    let (w, h, channels, n) = (rd_u32(p, 0), rd_u32(p, 4), rd_u32(p, 8), rd_u64(p, 16));
    if channels != 3 || w < 2 || h < 1 || u64::from(w) * u64::from(h) > 1 << 24 {
        return Err(invalid(
            "RFLD",
            format!("{w}×{h} directions of {channels} channels (3 channels, at least 2×1, at most 2^24 directions)"),
        ));
    }
    let values = n.checked_mul(3 * u64::from(w) * u64::from(h));
    let expected = values
        .and_then(|v| v.checked_mul(scalar.size() as u64))
        .and_then(|v| v.checked_add(RFLD_HEADER as u64))
        .and_then(|v| v.checked_add(n.checked_mul(4)?));
    if expected != Some(p.len() as u64) {
        return Err(inconsistent(
            "RFLD length (32 + 4 × pixels + scalars × 3 × W × H × pixels)",
            expected.unwrap_or(u64::MAX),
            p.len() as u64,
        ));
    }
    let n = n as usize;
    let pixels: Vec<u32> = p[RFLD_HEADER..RFLD_HEADER + 4 * n]
        .chunks_exact(4)
        .map(|c| rd_u32(c, 0))
        .collect();
    let data = &p[RFLD_HEADER + 4 * n..];
    if let Some(i) = first_breaking(scalar, data, Rule::Valid) {
        let s = scalar.size();
        let v = FieldValues::from_le_bytes(scalar, data[i * s..(i + 1) * s].to_vec());
        return Err(invalid(
            "RFLD",
            format!(
                "value {i} is {} (finite and non-negative)",
                v.get(0).unwrap_or(f32::NAN)
            ),
        ));
    }
    let start = offset + RFLD_HEADER + 4 * n;
    Ok(FieldLocation {
        directions: [w, h],
        pixels,
        values: start..start + data.len(),
    })
}

/// Reads an `ENVL` payload (SPEC.md §3.6): a known precision, 3 channels, order 1 … 65535,
/// exactly `16 + 3n² × size` bytes, finite values.
pub(crate) fn read_environment(p: &[u8]) -> Result<EnvCoefficients, BakeFileError> {
    if p.len() < ENVL_HEADER {
        return Err(inconsistent(
            "ENVL length",
            ENVL_HEADER as u64,
            p.len() as u64,
        ));
    }
    let order = rd_u32(p, 0);
    let channels = rd_u32(p, 4);
    let (precision, size) = match rd_u32(p, 8) {
        1 => (EnvPrecision::F32, 4),
        3 => (EnvPrecision::F64, 8),
        c => return Err(invalid("ENVL precision", format!("unknown code {c}"))),
    };
    if channels != 3 || order == 0 || order > u32::from(u16::MAX) {
        return Err(invalid(
            "ENVL",
            format!("order {order}, {channels} channels"),
        ));
    }
    let n = 3 * u64::from(order) * u64::from(order);
    let expected = ENVL_HEADER as u64 + n * size;
    if expected != p.len() as u64 {
        return Err(inconsistent("ENVL length", expected, p.len() as u64));
    }
    let values: Vec<f64> = match precision {
        EnvPrecision::F32 => p[ENVL_HEADER..]
            .chunks_exact(4)
            .map(|c| f64::from(f32::from_bits(rd_u32(c, 0))))
            .collect(),
        EnvPrecision::F64 => p[ENVL_HEADER..]
            .chunks_exact(8)
            .map(|c| rd_f64(c, 0))
            .collect(),
    };
    check_finite64("ENVL", &values)?;
    Ok(EnvCoefficients {
        order,
        precision,
        values,
    })
}

/// Reads a `BRDF` payload (SPEC.md §3.7), material names from `strs`: per record a known
/// lobe and its values packed after the records, which end exactly at the section's end.
pub(crate) fn read_brdfs(p: &[u8], strs: &[u8]) -> Result<Vec<BrdfProjection>, BakeFileError> {
    let mut brdfs = Vec::new();
    let (count, rec) = table(p, "BRDF", BRDF_RECORD)?;
    let mut off = (TABLE_HEADER_SIZE + count * rec) as u64;
    for i in 0..count {
        let r = &p[TABLE_HEADER_SIZE + i * rec..][..rec];
        let what = format!("BRDF record {i}");
        let material = string(
            strs,
            rd_u32(r, 0),
            rd_u32(r, 4),
            &format!("{what} material"),
        )?;
        let exponent = rd_f64(r, 16);
        let lobe = match rd_u32(r, 8) {
            1 if exponent == 0.0 => BrdfLobe::ClampedCosine,
            2 if exponent.is_finite() && exponent >= 0.0 => BrdfLobe::Phong { exponent },
            c => {
                return Err(invalid(
                    format!("{what} lobe"),
                    format!("code {c}, exponent {exponent}"),
                ))
            }
        };
        let order = rd_u32(r, 12);
        let values = f64s(p, rd_u64(r, 24), off, order.into(), &what)?;
        off += 8 * u64::from(order);
        brdfs.push(BrdfProjection {
            material,
            lobe,
            order,
            values,
        });
    }
    if off != p.len() as u64 {
        return Err(inconsistent("BRDF length", off, p.len() as u64));
    }
    Ok(brdfs)
}

/// Reads a `GLSY` payload (SPEC.md §3.8), material names from `strs`: per record its
/// elevations, values and errors packed after the records, in record order, ending exactly at
/// the section's end.
pub(crate) fn read_glossy(p: &[u8], strs: &[u8]) -> Result<Vec<GlossyBrdfTable>, BakeFileError> {
    let mut glossy = Vec::new();
    let (count, rec) = table(p, "GLSY", GLSY_RECORD)?;
    let mut off = (TABLE_HEADER_SIZE + count * rec) as u64;
    for i in 0..count {
        let r = &p[TABLE_HEADER_SIZE + i * rec..][..rec];
        let what = format!("GLSY record {i}");
        let material = string(
            strs,
            rd_u32(r, 0),
            rd_u32(r, 4),
            &format!("{what} material"),
        )?;
        let n_elev = u64::from(rd_u32(r, 8));
        let order = rd_u32(r, 12);
        let elevations = f64s(p, rd_u64(r, 16), off, n_elev, &format!("{what} elevations"))?;
        off += 8 * n_elev;
        let n_values = n_elev
            .checked_mul(u64::from(order) * u64::from(order))
            .ok_or_else(|| invalid(what.clone(), "too many values"))?;
        let values = f64s(p, rd_u64(r, 24), off, n_values, &format!("{what} values"))?;
        off += 8 * n_values;
        let projection_error = f64s(
            p,
            rd_u64(r, 32),
            off,
            order.into(),
            &format!("{what} errors"),
        )?;
        off += 8 * u64::from(order);
        glossy.push(GlossyBrdfTable {
            material,
            order,
            elevations,
            values,
            projection_error,
        });
    }
    if off != p.len() as u64 {
        return Err(inconsistent("GLSY length", off, p.len() as u64));
    }
    Ok(glossy)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn envl(order: u32, precision: u32, values: &[f64]) -> Vec<u8> {
        let mut p = Vec::new();
        for v in [order, 3, precision, 0] {
            p.extend_from_slice(&v.to_le_bytes());
        }
        for &v in values {
            if precision == 1 {
                p.extend_from_slice(&(v as f32).to_le_bytes());
            } else {
                p.extend_from_slice(&v.to_le_bytes());
            }
        }
        p
    }

    #[test]
    fn environment_payloads_read_in_either_precision() {
        let v: Vec<f64> = (0..12).map(|i| f64::from(i) * 0.5).collect();
        for precision in [1, 3] {
            let e = read_environment(&envl(2, precision, &v)).unwrap();
            assert_eq!((e.order, e.values.clone()), (2, v.clone()));
        }
        assert!(read_environment(&envl(2, 3, &v[..11])).is_err());
        assert_eq!(
            read_environment(&envl(2, 2, &v)).unwrap_err().to_string(),
            "invalid ENVL precision: unknown code 2"
        );
        let mut nan = v.clone();
        nan[5] = f64::NAN;
        assert!(matches!(
            read_environment(&envl(2, 3, &nan)),
            Err(BakeFileError::NonFinite { index: 5, .. })
        ));
    }

    /// A BRDF payload of one record, `values` packed after it at `values_off`.
    fn brdf(code: u32, exponent: f64, values: &[f64], values_off: u64) -> Vec<u8> {
        let mut p = Vec::new();
        for v in [
            1u32,
            BRDF_RECORD as u32,
            0,
            0,
            0,
            4,
            code,
            values.len() as u32,
        ] {
            p.extend_from_slice(&v.to_le_bytes());
        }
        p.extend_from_slice(&exponent.to_le_bytes());
        p.extend_from_slice(&values_off.to_le_bytes());
        values
            .iter()
            .for_each(|v| p.extend_from_slice(&v.to_le_bytes()));
        p
    }

    #[test]
    fn brdf_records_and_their_packed_values() {
        let strs = b"matt";
        let b = read_brdfs(&brdf(2, 8.0, &[1.0, 0.5], 48), strs).unwrap();
        assert_eq!(b[0].material, "matt");
        assert_eq!(b[0].lobe, BrdfLobe::Phong { exponent: 8.0 });
        assert_eq!(b[0].values, [1.0, 0.5]);
        assert!(read_brdfs(&brdf(1, 1.0, &[1.0], 48), strs)
            .unwrap_err()
            .to_string()
            .contains("BRDF record 0 lobe"));
        assert!(read_brdfs(&brdf(2, 8.0, &[1.0], 56), strs).is_err());
        let mut trailing = brdf(1, 0.0, &[1.0], 48);
        trailing.extend_from_slice(&[0; 8]);
        assert_eq!(
            read_brdfs(&trailing, strs).unwrap_err().to_string(),
            "inconsistent counts: BRDF length: expected 56, found 64"
        );
    }
}
