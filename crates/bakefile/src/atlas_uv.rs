//! Generated lightmap atlases in `settings.lightmaps` (SPEC §3.9.3): per-corner UVs stored as
//! integers `n`, UV = `n / 2²⁴`, exact in f32, f64 and JSON.

/// The denominator of an atlas UV: `2²⁴`, so every `n / ATLAS_UV_QUANTUM` in `[0, 1]` is an
/// exact f32.
pub const ATLAS_UV_QUANTUM: u32 = 1 << 24;

/// The `atlas` array of an entry: `[triangle][corner][u, v]` flattened, each UV times `2²⁴`.
/// UVs that are not multiples of `2⁻²⁴` in `[0, 1]` are rounded (prt's atlases are exact).
#[must_use]
pub fn atlas_integers(corner_uvs: &[[[f32; 2]; 3]]) -> Vec<u32> {
    corner_uvs
        .iter()
        .flatten()
        .flatten()
        .map(|&c| (f64::from(c).clamp(0.0, 1.0) * f64::from(ATLAS_UV_QUANTUM)).round() as u32)
        .collect()
}

/// The per-corner UVs of an entry's `atlas` array, which MUST hold `6 × triangles` integers in
/// `[0, 2²⁴]` (any triangle count when `triangles` is `None`).
///
/// # Errors
/// What is wrong with the array, as a sentence.
pub fn atlas_corner_uvs(
    atlas: &serde_json::Value,
    triangles: Option<usize>,
) -> Result<Vec<[[f32; 2]; 3]>, String> {
    let a = atlas
        .as_array()
        .ok_or("`atlas` is not an array of integers")?;
    if a.len() % 6 != 0 || triangles.is_some_and(|t| a.len() != 6 * t) {
        return Err(format!(
            "`atlas` has {} integers, not 6 per triangle{}",
            a.len(),
            triangles.map_or(String::new(), |t| format!(" ({t} triangles)"))
        ));
    }
    let mut uv = Vec::with_capacity(a.len());
    for (i, v) in a.iter().enumerate() {
        match v.as_u64() {
            Some(n) if n <= u64::from(ATLAS_UV_QUANTUM) => {
                uv.push((n as f64 / f64::from(ATLAS_UV_QUANTUM)) as f32);
            }
            _ => return Err(format!("`atlas[{i}]` is {v}, not an integer in [0, 2^24]")),
        }
    }
    Ok(uv
        .chunks_exact(6)
        .map(|c| [[c[0], c[1]], [c[2], c[3]], [c[4], c[5]]])
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atlas_uvs_round_trip_exactly_and_bad_arrays_are_refused() {
        let c = vec![[[0.0, 1.0], [0.5, 0.25], [3.0 / 16_777_216.0, 0.75]]];
        let ints = atlas_integers(&c);
        assert_eq!(ints, vec![0, 1 << 24, 1 << 23, 1 << 22, 3, 3 << 22]);
        let json = serde_json::to_value(&ints).unwrap();
        assert_eq!(atlas_corner_uvs(&json, Some(1)).unwrap(), c);
        assert!(atlas_corner_uvs(&json, Some(2))
            .unwrap_err()
            .contains("6 per triangle"));
        let over = serde_json::json!([0, 0, 0, 0, 0, 16_777_217]);
        assert!(atlas_corner_uvs(&over, None)
            .unwrap_err()
            .contains("atlas[5]"));
    }
}
