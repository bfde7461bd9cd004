//! Repair of face winding: make every face agree with its neighbours and point outward.
//!
//! Image-tool meshes wind some triangles arbitrarily, and some SimuCell3D fixtures have polygon faces
//! wound both ways. A breadth-first walk over manifold edges (shared by exactly two faces) flips each
//! face whose shared edge runs the same way as in the face it was reached from; then each connected
//! piece whose signed volume is negative is turned inside out. Edges with one or three-plus faces are
//! not crossed, so defects elsewhere do not spread; `check()` still reports them.

use super::{Adjacency, CellMesh, FaceId, validate::face_components_of};
use std::collections::VecDeque;

impl CellMesh {
    /// Orients faces consistently and outward; returns how many faces were flipped.
    pub fn orient_outward(&mut self) -> usize {
        let adj = Adjacency::new(self);
        let faces = self.face_count();
        let mut flip = vec![false; faces];
        let mut seen = vec![false; faces];
        let mut queue = VecDeque::new();
        let tris = self.triangles().to_vec();
        // The winding of side s of face f after the pending flips: (from, to).
        let side = |f: usize, s: usize, flipped: bool| {
            let (a, b) = (tris[f][s], tris[f][(s + 1) % 3]);
            if flipped { (b, a) } else { (a, b) }
        };
        for start in 0..faces {
            if seen[start] {
                continue;
            }
            seen[start] = true;
            queue.push_back(start);
            while let Some(f) = queue.pop_front() {
                for s in 0..3 {
                    let e = adj.face_edges(f)[s] as usize;
                    let fs = adj.edge_faces(e);
                    if fs.len() != 2 {
                        continue;
                    }
                    let g = if fs[0] as usize == f { fs[1] } else { fs[0] } as usize;
                    if seen[g] || g == f {
                        continue;
                    }
                    let (a, b) = side(f, s, flip[f]);
                    // g must traverse the edge from b to a.
                    let gs = (0..3).find(|&k| adj.face_edges(g)[k] as usize == e).expect("edge of g");
                    let (c, _) = side(g, gs, false);
                    flip[g] = c != b;
                    debug_assert!(side(g, gs, flip[g]) == (b, a));
                    seen[g] = true;
                    queue.push_back(g);
                }
            }
        }
        // Turn inside-out pieces around: the final state of a face is its BFS flip, toggled when its
        // connected piece encloses negative volume.
        let (labels, count) = face_components_of(&adj, faces);
        let mut volume = vec![0.0; count];
        let p = self.positions();
        let o = p.first().copied().unwrap_or_default();
        for (f, t) in tris.iter().enumerate() {
            let [a, b, c] = t.map(|i| p[i as usize] - o);
            let det = a.dot(&b.cross(&c));
            volume[labels[f]] += if flip[f] { -det } else { det };
        }
        let mut flipped = 0;
        for f in 0..faces {
            if flip[f] != (volume[labels[f]] < 0.0) {
                self.flip_face(FaceId(f as u32));
                flipped += 1;
            }
        }
        flipped
    }
}
