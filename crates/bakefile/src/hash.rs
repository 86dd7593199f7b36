//! The hashes that tie a bake to the mesh it was baked on: the geometry hash (every object)
//! and the UV hash of a per-texel object's lightmap UVs.

const FNV_OFFSET_BASIS: u64 = 0xcbf2_9ce4_8422_2325;
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

fn fnv1a(mut hash: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        hash ^= u64::from(b);
        hash = hash.wrapping_mul(FNV_PRIME);
    }
    hash
}

/// FNV-1a 64 of the mesh: the little-endian bytes of every position component
/// (`x, y, z` of vertex 0, then vertex 1, ...; the IEEE 754 bit pattern, so `-0.0 ≠ 0.0`),
/// followed by the little-endian bytes of every index (triangle 0's three indices, then
/// triangle 1's, ...). No lengths or separators are hashed. SPEC.md has a worked example.
#[must_use]
pub fn geometry_hash(positions: &[[f32; 3]], indices: &[[u32; 3]]) -> u64 {
    let mut hash = FNV_OFFSET_BASIS;
    for p in positions {
        for c in p {
            hash = fnv1a(hash, &c.to_le_bytes());
        }
    }
    for t in indices {
        for i in t {
            hash = fnv1a(hash, &i.to_le_bytes());
        }
    }
    hash
}

/// FNV-1a 64 of a UV set's bytes (the little-endian bytes of `u, v` of vertex 0, then vertex
/// 1, ...): the `uv_hash` of a per-texel bake's `settings.lightmaps` (SPEC §3.9.2).
#[must_use]
pub fn uv_hash(uvs: &[[f32; 2]]) -> u64 {
    uvs.iter()
        .flatten()
        .fold(FNV_OFFSET_BASIS, |h, v| fnv1a(h, &v.to_le_bytes()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_known_vectors() {
        // The published FNV-1a 64 test vectors: "" and "a" and "foobar".
        assert_eq!(fnv1a(FNV_OFFSET_BASIS, b""), 0xcbf29ce484222325);
        assert_eq!(fnv1a(FNV_OFFSET_BASIS, b"a"), 0xaf63dc4c8601ec8c);
        assert_eq!(fnv1a(FNV_OFFSET_BASIS, b"foobar"), 0x85944171f73967e8);
    }

    #[test]
    fn hash_is_over_positions_then_indices() {
        let pos = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let idx = [[0u32, 1, 2]];
        let mut bytes = Vec::new();
        for p in pos {
            for c in p {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
        for i in idx[0] {
            bytes.extend_from_slice(&i.to_le_bytes());
        }
        assert_eq!(geometry_hash(&pos, &idx), fnv1a(FNV_OFFSET_BASIS, &bytes));
        // Worked example of SPEC.md.
        assert_eq!(geometry_hash(&pos, &idx), SPEC_EXAMPLE);
        // Winding matters.
        assert_ne!(geometry_hash(&pos, &[[0, 2, 1]]), SPEC_EXAMPLE);
        // -0.0 is not 0.0.
        let neg = [[-0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert_ne!(geometry_hash(&neg, &idx), SPEC_EXAMPLE);
    }

    #[test]
    fn uv_hash_is_over_the_uv_bytes() {
        let uvs = [[0.25f32, 0.5], [1.0, 0.0]];
        let bytes: Vec<u8> = uvs.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
        assert_eq!(uv_hash(&uvs), fnv1a(FNV_OFFSET_BASIS, &bytes));
        assert_eq!(uv_hash(&[]), FNV_OFFSET_BASIS);
        assert_ne!(uv_hash(&[[0.5, 0.25], [1.0, 0.0]]), uv_hash(&uvs));
    }

    const SPEC_EXAMPLE: u64 = 0x8810_ae12_e1b0_c5a6;
}
