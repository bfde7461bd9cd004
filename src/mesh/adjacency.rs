//! Edge and vertex adjacency of a triangle mesh, in compressed (CSR) arrays.
//!
//! Built in O(F log F) from the triangle list, and tolerant of defective input: an edge may have one
//! face (a hole) or more than two (non-manifold), which `validate()` reports.

use super::CellMesh;

/// Undirected edges with their faces, and per-node incident faces and neighbours.
#[derive(Clone, Debug)]
pub struct Adjacency {
    /// Unique undirected edges `[a, b]` with `a < b`, sorted.
    edges: Vec<[u32; 2]>,
    edge_face_offsets: Vec<u32>,
    edge_faces: Vec<u32>,
    /// For each face, the edge index of each side `(t[i], t[(i+1)%3])`.
    face_edges: Vec<[u32; 3]>,
    node_face_offsets: Vec<u32>,
    node_faces: Vec<u32>,
    node_neighbour_offsets: Vec<u32>,
    node_neighbours: Vec<u32>,
}

impl Adjacency {
    /// Builds the adjacency of `mesh`.
    pub fn new(mesh: &CellMesh) -> Self {
        let tris = mesh.triangles();
        let nodes = mesh.node_count();
        let sides = sorted_sides(tris, nodes);
        let mut edges = Vec::with_capacity(sides.len() / 2 + 1);
        let mut edge_face_offsets = vec![0u32];
        let mut edge_faces = Vec::with_capacity(sides.len());
        let mut face_edges = vec![[u32::MAX; 3]; tris.len()];
        for (k, &(a, b, f, s)) in sides.iter().enumerate() {
            if k == 0 || (sides[k - 1].0, sides[k - 1].1) != (a, b) {
                if k > 0 {
                    edge_face_offsets.push(edge_faces.len() as u32);
                }
                edges.push([a, b]);
            }
            edge_faces.push(f);
            face_edges[f as usize][s as usize] = (edges.len() - 1) as u32;
        }
        if !sides.is_empty() {
            edge_face_offsets.push(edge_faces.len() as u32);
        }

        let (node_face_offsets, node_faces) =
            csr(nodes, tris.iter().enumerate().flat_map(|(f, t)| t.map(|n| (n, f as u32))));
        let (node_neighbour_offsets, node_neighbours) = csr(nodes, edges.iter().flat_map(|&[a, b]| [(a, b), (b, a)]));
        Self {
            edges,
            edge_face_offsets,
            edge_faces,
            face_edges,
            node_face_offsets,
            node_faces,
            node_neighbour_offsets,
            node_neighbours,
        }
    }

    /// Unique undirected edges `[a, b]`, `a < b`, sorted.
    pub fn edges(&self) -> &[[u32; 2]] {
        &self.edges
    }

    /// Faces bordering edge `e` (two on a closed manifold surface).
    pub fn edge_faces(&self, e: usize) -> &[u32] {
        &self.edge_faces[self.edge_face_offsets[e] as usize..self.edge_face_offsets[e + 1] as usize]
    }

    /// Edge index of each side of face `f`; side `i` joins corners `i` and `i + 1`.
    pub fn face_edges(&self, f: usize) -> [u32; 3] {
        self.face_edges[f]
    }

    /// Faces incident to node `n`.
    pub fn node_faces(&self, n: usize) -> &[u32] {
        &self.node_faces[self.node_face_offsets[n] as usize..self.node_face_offsets[n + 1] as usize]
    }

    /// Nodes joined to node `n` by an edge (its one-ring), in increasing order.
    pub fn node_neighbours(&self, n: usize) -> &[u32] {
        &self.node_neighbours[self.node_neighbour_offsets[n] as usize..self.node_neighbour_offsets[n + 1] as usize]
    }
}

/// Groups `(key, value)` pairs by key into CSR arrays, values in encounter order per key.
/// Every side of every face as (a, b, face, side) with a ≤ b, in lexicographic order (so by edge,
/// then by face): a counting sort by `a` (stable, and the sides are generated in (face, side)
/// order), then a stable sort by `b` within each bucket of a few sides. Same result as sorting the
/// tuples, without comparing them all.
fn sorted_sides(tris: &[[u32; 3]], nodes: usize) -> Vec<(u32, u32, u32, u8)> {
    let keys = tris.iter().flat_map(|t| t.iter()).map(|&i| i as usize + 1).max().unwrap_or(0).max(nodes);
    let mut offsets = vec![0u32; keys + 1];
    for t in tris {
        for s in 0..3 {
            offsets[t[s].min(t[(s + 1) % 3]) as usize + 1] += 1;
        }
    }
    for i in 0..keys {
        offsets[i + 1] += offsets[i];
    }
    let mut fill = offsets.clone();
    let mut sides = vec![(0u32, 0u32, 0u32, 0u8); tris.len() * 3];
    for (f, t) in tris.iter().enumerate() {
        for s in 0..3 {
            let (a, b) = (t[s], t[(s + 1) % 3]);
            let k = a.min(b) as usize;
            sides[fill[k] as usize] = (a.min(b), a.max(b), f as u32, s as u8);
            fill[k] += 1;
        }
    }
    for k in 0..keys {
        let bucket = &mut sides[offsets[k] as usize..offsets[k + 1] as usize];
        if bucket.len() <= 16 {
            // Stable insertion sort by b.
            for i in 1..bucket.len() {
                let mut j = i;
                while j > 0 && bucket[j - 1].1 > bucket[j].1 {
                    bucket.swap(j - 1, j);
                    j -= 1;
                }
            }
        } else {
            bucket.sort_by_key(|x| x.1);
        }
    }
    sides
}

fn csr(keys: usize, pairs: impl Iterator<Item = (u32, u32)> + Clone) -> (Vec<u32>, Vec<u32>) {
    let mut offsets = vec![0u32; keys + 1];
    for (k, _) in pairs.clone() {
        offsets[k as usize + 1] += 1;
    }
    for i in 0..keys {
        offsets[i + 1] += offsets[i];
    }
    let mut fill = offsets.clone();
    let mut values = vec![0u32; offsets[keys] as usize];
    for (k, v) in pairs {
        values[fill[k as usize] as usize] = v;
        fill[k as usize] += 1;
    }
    for k in 0..keys {
        values[offsets[k] as usize..offsets[k + 1] as usize].sort_unstable();
    }
    (offsets, values)
}

#[cfg(test)]
mod tests {
    use super::sorted_sides;

    /// The bucketed sort must give exactly the order of sorting the tuples (edge, then face, side),
    /// also for arbitrary (invalid, high-valence) triangle lists.
    #[test]
    fn sorted_sides_match_a_full_sort() {
        let mut state = 12345u64;
        let mut next = |n: u32| {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 33) % u64::from(n)) as u32
        };
        for (faces, nodes) in [(0, 0), (1, 3), (50, 6), (400, 40), (2000, 300)] {
            let tris: Vec<[u32; 3]> = (0..faces).map(|_| [next(nodes), next(nodes), next(nodes)]).collect();
            let mut expected: Vec<(u32, u32, u32, u8)> = Vec::new();
            for (f, t) in tris.iter().enumerate() {
                for s in 0..3 {
                    let (a, b) = (t[s], t[(s + 1) % 3]);
                    expected.push((a.min(b), a.max(b), f as u32, s as u8));
                }
            }
            expected.sort_unstable();
            assert_eq!(sorted_sides(&tris, nodes as usize), expected, "{faces} faces on {nodes} nodes");
        }
    }
}
