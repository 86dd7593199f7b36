//! Vertex adjacency of a triangle mesh in compressed sparse rows, for the ROI searches.

use crate::error::RelightError;

/// Vertex adjacency (CSR): `neighbours(v)` lists, sorted and without repeats, the vertices that
/// share a triangle edge with `v`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Adjacency {
    offsets: Vec<u32>,
    neighbours: Vec<u32>,
}

impl Adjacency {
    /// Builds the adjacency of `vertex_count` vertices from triangle indices. Repeated
    /// vertices inside a triangle add no self-edge. Errors on an index out of range.
    pub fn from_triangles(
        vertex_count: usize,
        triangles: &[[u32; 3]],
    ) -> Result<Self, RelightError> {
        if vertex_count >= u32::MAX as usize {
            return Err(RelightError::InvalidParameter(format!(
                "{vertex_count} vertices do not fit u32 indices"
            )));
        }
        let mut edges: Vec<(u32, u32)> = Vec::with_capacity(triangles.len() * 6);
        for (t, tri) in triangles.iter().enumerate() {
            for &v in tri {
                if v as usize >= vertex_count {
                    return Err(RelightError::VertexIndex {
                        triangle: t,
                        vertex: v,
                        vertex_count,
                    });
                }
            }
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                if a != b {
                    edges.push((a, b));
                    edges.push((b, a));
                }
            }
        }
        edges.sort_unstable();
        edges.dedup();
        let mut offsets = vec![0u32; vertex_count + 1];
        for &(a, _) in &edges {
            offsets[a as usize + 1] += 1;
        }
        for v in 0..vertex_count {
            offsets[v + 1] += offsets[v];
        }
        let neighbours = edges.into_iter().map(|(_, b)| b).collect();
        Ok(Self {
            offsets,
            neighbours,
        })
    }

    /// Number of vertices.
    #[must_use]
    pub fn vertex_count(&self) -> usize {
        self.offsets.len() - 1
    }

    /// The sorted neighbours of vertex `v` (panics if `v` is out of range).
    #[must_use]
    pub fn neighbours(&self, v: usize) -> &[u32] {
        &self.neighbours[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }

    /// Number of undirected edges.
    #[must_use]
    pub fn edge_count(&self) -> usize {
        self.neighbours.len() / 2
    }

    /// Checks the invariants: monotone offsets, sorted unique in-range neighbours, no self-edges,
    /// symmetry.
    pub fn validate(&self) -> Result<(), RelightError> {
        let n = self.vertex_count();
        let bad = |msg: String| Err(RelightError::InvalidParameter(format!("adjacency: {msg}")));
        if self.offsets.first() != Some(&0)
            || *self.offsets.last().unwrap_or(&0) as usize != self.neighbours.len()
        {
            return bad("offsets do not span the neighbour array".into());
        }
        for v in 0..n {
            if self.offsets[v] > self.offsets[v + 1] {
                return bad(format!("offsets decrease at vertex {v}"));
            }
            let nb = self.neighbours(v);
            for (k, &u) in nb.iter().enumerate() {
                if u as usize >= n || u as usize == v || (k > 0 && nb[k - 1] >= u) {
                    return bad(format!("neighbour list of vertex {v} is not sorted, unique, in range and loop-free"));
                }
                if self
                    .neighbours(u as usize)
                    .binary_search(&(v as u32))
                    .is_err()
                {
                    return bad(format!("edge {v}–{u} is not symmetric"));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_triangles() {
        // Quad 0-1-2-3 split along 0–2: vertex 1 and 3 are not adjacent.
        let adj = Adjacency::from_triangles(5, &[[0, 1, 2], [0, 2, 3], [2, 2, 0]]).unwrap();
        adj.validate().unwrap();
        assert_eq!(adj.neighbours(0), &[1, 2, 3]);
        assert_eq!(adj.neighbours(1), &[0, 2]);
        assert_eq!(adj.neighbours(2), &[0, 1, 3]);
        assert_eq!(adj.neighbours(3), &[0, 2]);
        assert!(adj.neighbours(4).is_empty());
        assert_eq!(adj.edge_count(), 5);
        assert!(matches!(
            Adjacency::from_triangles(3, &[[0, 1, 3]]),
            Err(RelightError::VertexIndex { vertex: 3, .. })
        ));
    }
}
