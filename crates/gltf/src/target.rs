//! Export targets (SPEC §10.2): what a GPU pipeline can bind. A target bounds the vertex
//! attributes of a primitive and the size of a texture; per-vertex transfer that does not fit
//! in the attribute budget goes into a float data texture indexed by vertex id, where engines
//! put large per-vertex data.
//!
//! The limits are the minimums the APIs guarantee, not what one GPU happens to allow:
//! WebGL 2.0 guarantees `MAX_VERTEX_ATTRIBS ≥ 16` and `MAX_TEXTURE_SIZE ≥ 2048`; OpenGL 4.x and
//! Vulkan 1.0 guarantee 16 vertex attributes (`maxVertexInputAttributes`) and Vulkan 1.0 a 2D
//! image of at least 4096 texels a side (`maxImageDimension2D`; OpenGL 4.1 guarantees 16384).

/// Where an export's data must fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Target {
    /// No limits: the transfer as vertex attributes, however many (SPEC §10).
    Raw,
    /// WebGL 2.0: 16 vertex attributes, textures up to 2048 × 2048.
    Webgl2,
    /// Desktop OpenGL 4.x / Vulkan 1.0: 16 vertex attributes, textures up to 4096 × 4096.
    Desktop,
}

impl Target {
    /// The most vertex attributes a primitive may have, or `None` without a limit.
    #[must_use]
    pub fn attribute_budget(self) -> Option<usize> {
        match self {
            Target::Raw => None,
            Target::Webgl2 | Target::Desktop => Some(16),
        }
    }

    /// The largest width and height of a texture.
    #[must_use]
    pub fn max_texture_size(self) -> usize {
        match self {
            Target::Raw | Target::Desktop => 4096,
            Target::Webgl2 => 2048,
        }
    }

    /// The name `prt export --target` takes.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Target::Raw => "raw",
            Target::Webgl2 => "webgl2",
            Target::Desktop => "desktop",
        }
    }
}

/// How a per-vertex object's transfer is laid out in its data texture (SPEC §10.2): vertex
/// `v`'s texels are `v · texels_per_vertex + k`, `k < texels_per_vertex`, row-major in a
/// texture `width` texels wide; texel `k = c · groups + g` holds coefficients `4g … 4g+3` of
/// channel `c`, and `k = visibility + g` those of the visibility transfer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TexturePacking {
    /// `⌈n²/4⌉`: texels per channel (and for the visibility transfer).
    pub groups: usize,
    /// Texels per vertex: `channels · groups`, plus `groups` with visibility.
    pub texels_per_vertex: usize,
    /// The first texel of the visibility transfer, when it is packed.
    pub visibility: Option<usize>,
    /// Texture width.
    pub width: usize,
    /// Texture height.
    pub height: usize,
}

impl TexturePacking {
    /// The packing of `vertices` vertices with `channels` channels of `n2` coefficients (and
    /// the visibility transfer when `visibility`), in a texture at most `max_size` a side;
    /// `None` when it does not fit.
    #[must_use]
    pub fn new(
        vertices: usize,
        channels: usize,
        n2: usize,
        visibility: bool,
        max_size: usize,
    ) -> Option<Self> {
        let groups = n2.div_ceil(4);
        let texels_per_vertex = (channels + usize::from(visibility)) * groups;
        let texels = vertices.checked_mul(texels_per_vertex)?;
        let width = texels.clamp(1, max_size);
        let height = texels.div_ceil(width).max(1);
        (height <= max_size).then_some(Self {
            groups,
            texels_per_vertex,
            visibility: visibility.then_some(channels * groups),
            width,
            height,
        })
    }

    /// The texture's RGBA values, `width × height × 4`, zero past the last vertex: `rows`
    /// holds vertex `p`'s channel `c` at `rows[p · stride + c · n2..][..n2]`, `vis` (one
    /// channel) at `vis[p · vis_stride..][..n2]`.
    #[must_use]
    pub fn pack(
        &self,
        n2: usize,
        rows: &[f32],
        stride: usize,
        channels: usize,
        vis: Option<(&[f32], usize)>,
    ) -> Vec<f32> {
        let mut out = vec![0.0f32; self.width * self.height * 4];
        let vertices = rows.len() / stride;
        for p in 0..vertices {
            let base = p * self.texels_per_vertex * 4;
            for c in 0..channels {
                let src = &rows[p * stride + c * n2..][..n2];
                out[base + c * self.groups * 4..][..n2].copy_from_slice(src);
            }
            if let (Some(at), Some((v, vs))) = (self.visibility, vis) {
                out[base + at * 4..][..n2].copy_from_slice(&v[p * vs..][..n2]);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Order 10, three channels and visibility: 25 groups, 100 texels per vertex; the texture
    /// is as wide as the target allows and just tall enough, and refuses what cannot fit.
    #[test]
    fn packing_sizes_follow_the_limits() {
        let p = TexturePacking::new(14_556, 3, 100, true, 2048).unwrap();
        assert_eq!(
            (p.groups, p.texels_per_vertex, p.visibility),
            (25, 100, Some(75))
        );
        assert_eq!(p.width, 2048);
        assert_eq!(p.height, (14_556 * 100usize).div_ceil(2048));
        let small = TexturePacking::new(3, 1, 9, false, 2048).unwrap();
        assert_eq!(
            (small.width, small.height, small.texels_per_vertex),
            (9, 1, 3)
        );
        assert!(TexturePacking::new(2048 * 2048 / 3 + 1, 3, 4, false, 2048).is_none());
        assert_eq!(Target::Webgl2.attribute_budget(), Some(16));
        assert_eq!(Target::Raw.attribute_budget(), None);
    }

    /// Every coefficient lands at the texel and component the SPEC's formula names, and the
    /// padding is zero.
    #[test]
    fn every_coefficient_is_where_the_formula_says() {
        let (v, c, n2) = (5, 3, 9);
        let rows: Vec<f32> = (0..v * c * n2).map(|i| i as f32 + 1.0).collect();
        let vis: Vec<f32> = (0..v * c * n2).map(|i| -(i as f32) - 1.0).collect();
        let p = TexturePacking::new(v, c, n2, true, 8).unwrap();
        // 60 texels: 8 wide (not a multiple of the 12 per vertex), 8 rows, 4 of padding.
        assert_eq!((p.width, p.height), (8, 8));
        assert!(
            TexturePacking::new(v, c, n2, true, 7).is_none(),
            "9 rows of 7 do not fit"
        );
        let tex = p.pack(n2, &rows, c * n2, c, Some((&vis, c * n2)));
        let mut seen = 0;
        for vert in 0..v {
            for i in 0..n2 {
                for ch in 0..c {
                    let k = vert * p.texels_per_vertex + ch * p.groups + i / 4;
                    let (x, y) = (k % p.width, k / p.width);
                    assert_eq!(
                        tex[(y * p.width + x) * 4 + i % 4],
                        rows[vert * c * n2 + ch * n2 + i]
                    );
                    seen += 1;
                }
                let k = vert * p.texels_per_vertex + p.visibility.unwrap() + i / 4;
                assert_eq!(tex[k * 4 + i % 4], vis[vert * c * n2 + i]);
                seen += 1;
            }
        }
        let nonzero = tex.iter().filter(|x| **x != 0.0).count();
        assert_eq!(nonzero, seen, "everything else is zero padding");
    }
}
