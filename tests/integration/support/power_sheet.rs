//! Analytic truths for the 2.5-D sheet estimate, independent of tissuefit's code: a **power diagram**
//! (Laguerre tessellation) of random weighted sites is a network of straight walls in exact force
//! balance with line tensions T_ij = |s_i − s_j| (Maxwell–Cremona: the weighted Delaunay triangle
//! dual to each vertex, turned by 90°, closes the force polygon). Conformal maps preserve the angles at
//! the junctions, so the same tensions balance the network's image under a circle inversion (walls
//! become circular arcs) and under the inverse stereographic projection onto a sphere (a curved
//! sheet). Each cell is a fan of triangles around its polygon's centroid; walls are subdivided so
//! that curved images stay smooth. Written as a PLY with a per-face `label`.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;
use std::fmt::Write as _;

type P2 = [f64; 2];

/// How the planar diagram is placed in space.
#[derive(Clone, Copy, Debug)]
pub enum Map {
    /// The plane z = 0, rotated into a general orientation.
    Plane,
    /// Inversion in the circle of radius 0.8 about (0.5, −0.45) (walls become circular arcs).
    Inversion,
    /// Inverse stereographic projection onto a sphere of radius 0.6 about (0.5, 0.5, 0.6) touching the
    /// plane at the square's centre.
    Sphere,
}

/// A generated sheet: points, triangles with their cell label, and the true tension of every wall.
pub struct PowerSheet {
    pub points: Vec<[f64; 3]>,
    pub faces: Vec<([usize; 3], u32)>,
    /// (label a < label b) → |s_a − s_b|, for cells sharing a wall.
    pub tension: BTreeMap<(u32, u32), f64>,
}

/// A constraint bounding a power cell: a neighbour's bisector, or a side of the box.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Side {
    Box(u8),
    Cell(usize),
}

/// `cells` sites in the unit square (minimum spacing 0.4/√cells), weights up to `weight` × spacing²,
/// each wall cut into `subdivisions` segments.
pub fn power_sheet(cells: usize, weight: f64, subdivisions: usize, map: Map, seed: u64) -> PowerSheet {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let spacing = 1.0 / (cells as f64).sqrt();
    let mut sites: Vec<P2> = Vec::new();
    while sites.len() < cells {
        let s = [rng.random::<f64>(), rng.random::<f64>()];
        if sites.iter().all(|q| (q[0] - s[0]).hypot(q[1] - s[1]) > 0.4 * spacing) {
            sites.push(s);
        }
    }
    let weights: Vec<f64> = (0..cells).map(|_| rng.random::<f64>() * weight * spacing * spacing).collect();
    // Half-plane of cell i against j: a·x ≤ b with a = 2(s_j − s_i), b = |s_j|² − |s_i|² − w_j + w_i.
    let line = |i: usize, side: Side| -> (P2, f64) {
        match side {
            Side::Cell(j) => {
                let (si, sj) = (sites[i], sites[j]);
                let a = [2.0 * (sj[0] - si[0]), 2.0 * (sj[1] - si[1])];
                let b = sj[0] * sj[0] + sj[1] * sj[1] - si[0] * si[0] - si[1] * si[1] - weights[j] + weights[i];
                (a, b)
            }
            // Box [−0.05, 1.05]²: x ≥ lo, x ≤ hi, y ≥ lo, y ≤ hi.
            Side::Box(0) => ([-1.0, 0.0], 0.05),
            Side::Box(1) => ([1.0, 0.0], 1.05),
            Side::Box(2) => ([0.0, -1.0], 0.05),
            Side::Box(_) => ([0.0, 1.0], 1.05),
        }
    };
    // A vertex from its canonical key (the sorted sides that meet there, cells by their own lines
    // relative to the smallest cell), so that every cell computes it bit for bit alike.
    let vertex = |key: &[Side; 3]| -> P2 {
        let owner = key.iter().find_map(|s| if let Side::Cell(i) = s { Some(*i) } else { None }).unwrap();
        let others: Vec<Side> = key.iter().copied().filter(|s| *s != Side::Cell(owner)).collect();
        let (a1, b1) = line(owner, others[0]);
        let (a2, b2) = line(owner, others[1]);
        let det = a1[0] * a2[1] - a1[1] * a2[0];
        [(b1 * a2[1] - b2 * a1[1]) / det, (a1[0] * b2 - a2[0] * b1) / det]
    };
    let mut points: Vec<[f64; 3]> = Vec::new();
    let mut index: BTreeMap<Vec<Side>, usize> = BTreeMap::new();
    let mut faces = Vec::new();
    let mut tension = BTreeMap::new();
    let place = |p: P2| -> [f64; 3] {
        match map {
            Map::Plane => {
                // A fixed rotation: about (1, 2, 3)/√14 by 0.7 rad.
                let (axis, angle) = ([1.0, 2.0, 3.0].map(|v: f64| v / 14f64.sqrt()), 0.7f64);
                let v = [p[0], p[1], 0.0];
                let (c, s) = (angle.cos(), angle.sin());
                let dot = axis[0] * v[0] + axis[1] * v[1] + axis[2] * v[2];
                let cross =
                    [axis[1] * v[2] - axis[2] * v[1], axis[2] * v[0] - axis[0] * v[2], axis[0] * v[1] - axis[1] * v[0]];
                [0, 1, 2].map(|k| v[k] * c + cross[k] * s + axis[k] * dot * (1.0 - c))
            }
            Map::Inversion => {
                let (c, r2) = ([0.5, -0.45], 0.64);
                let d = [p[0] - c[0], p[1] - c[1]];
                let n2 = d[0] * d[0] + d[1] * d[1];
                [c[0] + r2 * d[0] / n2, c[1] + r2 * d[1] / n2, 0.0]
            }
            Map::Sphere => {
                // Project from the sphere's top (0.5, 0.5, 2R) through the plane point.
                let r = 0.6;
                let (u, v) = (p[0] - 0.5, p[1] - 0.5);
                let k = 4.0 * r * r / (u * u + v * v + 4.0 * r * r);
                [0.5 + k * u, 0.5 + k * v, 2.0 * r * (1.0 - k)]
            }
        }
    };
    for i in 0..cells {
        // The box, then every neighbour's half-plane (Sutherland–Hodgman), tracking each polygon
        // vertex's two sides.
        let mut poly: Vec<(P2, [Side; 2])> = vec![
            ([-0.05, -0.05], [Side::Box(0), Side::Box(2)]),
            ([1.05, -0.05], [Side::Box(2), Side::Box(1)]),
            ([1.05, 1.05], [Side::Box(1), Side::Box(3)]),
            ([-0.05, 1.05], [Side::Box(3), Side::Box(0)]),
        ];
        for j in (0..cells).filter(|&j| j != i) {
            let (a, b) = line(i, Side::Cell(j));
            let inside = |p: &P2| a[0] * p[0] + a[1] * p[1] <= b;
            let mut next = Vec::new();
            let at = |edge: Side| {
                let mut key = [Side::Cell(i), edge, Side::Cell(j)];
                key.sort();
                vertex(&key)
            };
            for k in 0..poly.len() {
                let (p, sp) = poly[k];
                let (q, sq) = poly[(k + 1) % poly.len()];
                // Each vertex carries [incoming side, outgoing side]: the edge p→q lies on sp[1].
                let edge = sp[1];
                match (inside(&p), inside(&q)) {
                    (true, true) => next.push((q, sq)),
                    (true, false) => next.push((at(edge), [edge, Side::Cell(j)])),
                    (false, true) => {
                        next.push((at(edge), [Side::Cell(j), edge]));
                        next.push((q, sq));
                    }
                    (false, false) => {}
                }
            }
            // Exact positions of the new vertices come from their keys below.
            poly = next;
            if poly.is_empty() {
                break;
            }
        }
        if poly.len() < 3 {
            continue;
        }
        let label = i as u32 + 1;
        // Canonical corner keys and positions.
        let corners: Vec<[Side; 3]> = poly
            .iter()
            .map(|(_, s)| {
                let mut key = [Side::Cell(i), s[0], s[1]];
                key.sort();
                key
            })
            .collect();
        let corner_points: Vec<P2> = corners.iter().map(vertex).collect();
        let centroid = {
            let n = corner_points.len() as f64;
            [corner_points.iter().map(|p| p[0]).sum::<f64>() / n, corner_points.iter().map(|p| p[1]).sum::<f64>() / n]
        };
        let mut id = |key: Vec<Side>, p: P2, points: &mut Vec<[f64; 3]>| {
            *index.entry(key).or_insert_with(|| {
                points.push(place(p));
                points.len() - 1
            })
        };
        let centre = id(vec![Side::Cell(i), Side::Cell(i), Side::Cell(i)], centroid, &mut points);
        // The boundary with each wall subdivided: points from the edge's endpoints in key order.
        let mut ring: Vec<usize> = Vec::new();
        for k in 0..corners.len() {
            let (ka, kb) = (corners[k], corners[(k + 1) % corners.len()]);
            let (pa, pb) = (corner_points[k], corner_points[(k + 1) % corners.len()]);
            ring.push(id(ka.to_vec(), pa, &mut points));
            let forward = ka < kb;
            let (first, last, fp, lp) = if forward { (ka, kb, pa, pb) } else { (kb, ka, pb, pa) };
            let mut inner: Vec<usize> = (1..subdivisions)
                .map(|m| {
                    let t = m as f64 / subdivisions as f64;
                    let p = [fp[0] + t * (lp[0] - fp[0]), fp[1] + t * (lp[1] - fp[1])];
                    let mut key = first.to_vec();
                    key.extend(last);
                    key.push(Side::Box(100 + m as u8));
                    id(key, p, &mut points)
                })
                .collect();
            if !forward {
                inner.reverse();
            }
            ring.extend(inner);
            // The wall's neighbour and its true tension.
            let shared: Vec<Side> = ka.iter().copied().filter(|s| kb.contains(s) && *s != Side::Cell(i)).collect();
            if let [Side::Cell(j)] = shared[..] {
                let t = (sites[i][0] - sites[j][0]).hypot(sites[i][1] - sites[j][1]);
                tension.insert((label.min(j as u32 + 1), label.max(j as u32 + 1)), t);
            }
        }
        for k in 0..ring.len() {
            faces.push(([centre, ring[k], ring[(k + 1) % ring.len()]], label));
        }
    }
    PowerSheet { points, faces, tension }
}

impl PowerSheet {
    /// Moves every point by a random offset of rms `sigma` per axis (seeded).
    pub fn jitter(&mut self, sigma: f64, seed: u64) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for p in &mut self.points {
            for c in p.iter_mut() {
                *c += sigma * 3f64.sqrt() * (2.0 * rng.random::<f64>() - 1.0);
            }
        }
    }

    /// Mean wall segment length.
    pub fn mean_edge(&self) -> f64 {
        let mut sum = 0.0;
        for (f, _) in &self.faces {
            let (a, b) = (self.points[f[1]], self.points[f[2]]);
            sum += ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
        }
        sum / self.faces.len() as f64
    }

    /// ASCII PLY, lengths × `scale`, faces with a `label` property.
    pub fn ply(&self, scale: f64) -> String {
        let mut s = format!(
            "ply\nformat ascii 1.0\ncomment power-diagram sheet (tissuefit test)\nelement vertex {}\nproperty double x\n\
             property double y\nproperty double z\nelement face {}\nproperty list uchar int vertex_indices\n\
             property int label\nend_header\n",
            self.points.len(),
            self.faces.len()
        );
        for p in &self.points {
            writeln!(s, "{:.17e} {:.17e} {:.17e}", p[0] * scale, p[1] * scale, p[2] * scale).unwrap();
        }
        for (f, label) in &self.faces {
            writeln!(s, "3 {} {} {} {label}", f[0], f[1], f[2]).unwrap();
        }
        s
    }
}
