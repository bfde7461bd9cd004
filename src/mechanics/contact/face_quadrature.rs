//! Exact face means of the spring model's energy density for a distance that is linear on a face.
//!
//! The vertex quadrature Σ_p a_p·Φ(d_p) samples the adhesion well at the nodes. Across a contact
//! rim the well switches on within one element, so that energy changes when nodes slide along an
//! unchanged surface, and the tangential forces it makes move the contact line off Young–Dupré and
//! keep the remesher busy (docs: design note "Spring contacts and Young–Dupré"). Integrating Φ over
//! each face instead, with d interpolated linearly between the face's corners, gives an energy that
//! depends on where the surface is, not on where its nodes sit, wherever d is linear on the face
//! (a flat face over a flat partner surface): the integral is exact.
//!
//! Φ is a piecewise quadratic of d ([`super::spring`]), so it is a sum of truncated powers
//! (d − t)₊^m, m ≤ 2, and the mean of a truncated power over a triangle on which d is linear has a
//! closed form ([`truncated_power_mean`]) that is stable for every ordering and coincidence of the
//! corner values.

use super::{CellTopology, Pair, combine_face_wells};
use crate::geometry::Real;
use crate::mechanics::CellTypeParams;
use crate::mesh::Cell;

/// Mean over a triangle of (e)₊^m, m = 1 or 2, where e is linear on the triangle with corner values
/// `e`, and its gradient with respect to those values.
///
/// With the values sorted e₁ ≤ e₂ ≤ e₃ and K = 2/((m+1)(m+2)): all ≥ 0, it is the mean of e^m,
/// K·h_m(e) (h_m the complete homogeneous symmetric polynomial); all ≤ 0, zero; one negative, the
/// mean of e^m minus the corner triangle at e₁ where e < 0, K·e₁^{m+2}/((e₂ − e₁)(e₃ − e₁)); two
/// negative, only the corner at e₃: K·e₃^{m+2}/((e₃ − e₁)(e₃ − e₂)). Every denominator is at least
/// the square of the corner value in its numerator, so nothing cancels.
pub fn truncated_power_mean(e: [Real; 3], m: u32) -> (Real, [Real; 3]) {
    debug_assert!(m == 1 || m == 2);
    let mut order = [0usize, 1, 2];
    order.sort_unstable_by(|&a, &b| e[a].total_cmp(&e[b]));
    let [e1, e2, e3] = order.map(|k| e[k]);
    let k = 2.0 / (((m + 1) * (m + 2)) as Real);
    let mut sorted_grad = [0.0; 3];
    let value;
    if e3 <= 0.0 {
        return (0.0, [0.0; 3]);
    } else if e1 >= 0.0 || e2 >= 0.0 {
        // The mean of e^m over the whole triangle.
        let (full, full_grad) = power_mean([e1, e2, e3], m, k);
        if e1 >= 0.0 {
            value = full;
            sorted_grad = full_grad;
        } else {
            // Minus the corner at e₁ where e < 0.
            let (d2, d3) = (e2 - e1, e3 - e1);
            let p = e1.powi(m as i32 + 1);
            let t = k * p * e1 / (d2 * d3);
            value = full - t;
            let dt1 = k * ((m + 2) as Real * p / (d2 * d3) + p * e1 * (1.0 / (d2 * d2 * d3) + 1.0 / (d2 * d3 * d3)));
            let dt2 = -k * p * e1 / (d2 * d2 * d3);
            let dt3 = -k * p * e1 / (d2 * d3 * d3);
            sorted_grad = [full_grad[0] - dt1, full_grad[1] - dt2, full_grad[2] - dt3];
        }
    } else {
        // Only the corner at e₃ where e > 0.
        let (f1, f2) = (e3 - e1, e3 - e2);
        let p = e3.powi(m as i32 + 1);
        value = k * p * e3 / (f1 * f2);
        sorted_grad[2] = k * ((m + 2) as Real * p / (f1 * f2) - p * e3 * (1.0 / (f1 * f1 * f2) + 1.0 / (f1 * f2 * f2)));
        sorted_grad[0] = k * p * e3 / (f1 * f1 * f2);
        sorted_grad[1] = k * p * e3 / (f1 * f2 * f2);
    }
    let mut grad = [0.0; 3];
    for (s, &o) in order.iter().enumerate() {
        grad[o] = sorted_grad[s];
    }
    (value, grad)
}

/// Mean of e^m (m = 1, 2) over the triangle, K·h_m(e), and its gradient.
fn power_mean(e: [Real; 3], m: u32, k: Real) -> (Real, [Real; 3]) {
    let h1 = e[0] + e[1] + e[2];
    if m == 1 {
        (k * h1, [k; 3])
    } else {
        let h2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2] + e[0] * e[1] + e[0] * e[2] + e[1] * e[2];
        (k * h2, e.map(|x| k * (x + h1)))
    }
}

/// Adds `scale`·mean((s·d − t)₊^m) and its gradient with respect to d (s = ±1).
fn add_term(d: [Real; 3], s: Real, t: Real, m: u32, scale: Real, value: &mut Real, grad: &mut [Real; 3]) {
    if scale == 0.0 {
        return;
    }
    let (v, g) = truncated_power_mean(d.map(|x| s * x - t), m);
    *value += scale * v;
    for k in 0..3 {
        grad[k] += scale * s * g[k];
    }
}

/// Face mean of the adhesion well A(d) ([`super::adhesion_energy_density`]) for d linear on the
/// face with corner values `d`, and its gradient: A = −W + (ω/2)(d)₊² − ω(d − c/2)₊² + (ω/2)(d − c)₊²,
/// W = ωc²/4.
pub fn adhesion_face_mean(d: [Real; 3], cutoff: Real, adhesion: Real) -> (Real, [Real; 3]) {
    let (c, w) = (cutoff, adhesion);
    let mut value = -0.25 * w * c * c;
    let mut grad = [0.0; 3];
    if w == 0.0 {
        return (0.0, grad);
    }
    add_term(d, 1.0, 0.0, 2, 0.5 * w, &mut value, &mut grad);
    add_term(d, 1.0, 0.5 * c, 2, -w, &mut value, &mut grad);
    add_term(d, 1.0, c, 2, 0.5 * w, &mut value, &mut grad);
    (value, grad)
}

/// Face mean of the repulsion R(d) ([`super::repulsion_energy_density`]) for d linear on the face,
/// and its gradient: R = (ξ/2)[(−d)₊² − (−d − c)₊²] − ξc(−d − c)₊.
pub fn repulsion_face_mean(d: [Real; 3], cutoff: Real, repulsion: Real) -> (Real, [Real; 3]) {
    let (c, x) = (cutoff, repulsion);
    let mut value = 0.0;
    let mut grad = [0.0; 3];
    add_term(d, -1.0, 0.0, 2, 0.5 * x, &mut value, &mut grad);
    add_term(d, -1.0, c, 2, -0.5 * x, &mut value, &mut grad);
    add_term(d, -1.0, c, 1, -x * c, &mut value, &mut grad);
    (value, grad)
}

/// The face quadrature of one cell: for every face with a corner within the cutoff of another
/// body, the face mean Φ_f of the energy density (into `density`, J/m²) and, on each of its corner
/// pairs, the sum over faces of A_f·∂Φ_f/∂d (into [`Pair::coefficient`], J/m).
///
/// A face's ω and ξ are its own face type's. Several partners at one face combine like the vertex
/// quadrature's nodes ([`combine_face_wells`]): repulsions add up, the wells saturate at one well of
/// the face's depth ωc²/4, with each partner's well fraction the face mean of its well. With one
/// partner Φ_f is the exact mean of Eq. 2's Φ. A partner is skipped at a face if one corner has no
/// distance to it, which happens only for a corner deeper inside it than the search radius.
pub(super) fn assemble(
    cell: &Cell,
    params: &CellTypeParams,
    areas: &[Real],
    topology: &CellTopology,
    cutoff: Real,
    pairs: &mut [Pair],
    density: &mut Vec<Real>,
) {
    let mesh = cell.mesh();
    density.clear();
    density.resize(mesh.face_count(), 0.0);
    if pairs.is_empty() {
        return;
    }
    // Pairs are recorded node by node (ascending), partners ascending within a node.
    let mut offsets = vec![0usize; mesh.node_count() + 1];
    for p in pairs.iter() {
        offsets[p.node as usize + 1] += 1;
    }
    for k in 0..mesh.node_count() {
        offsets[k + 1] += offsets[k];
    }
    debug_assert!(pairs.windows(2).all(|w| (w[0].node, w[0].other) < (w[1].node, w[1].other)));
    let mut visit: Vec<u32> = Vec::new();
    for p in pairs.iter().filter(|p| p.distance < cutoff) {
        visit.extend_from_slice(topology.faces_of(p.node));
    }
    visit.sort_unstable();
    visit.dedup();
    let find = |pairs: &[Pair], node: u32, other: u32| {
        let range = offsets[node as usize]..offsets[node as usize + 1];
        range.into_iter().find(|&i| pairs[i].other == other)
    };
    let mut partners: Vec<(u32, [usize; 3])> = Vec::new();
    let mut terms: Vec<FaceTerm> = Vec::new();
    for &f in &visit {
        let tri = mesh.triangles()[f as usize];
        partners.clear();
        for &node in &tri {
            for i in offsets[node as usize]..offsets[node as usize + 1] {
                let other = pairs[i].other;
                if pairs[i].distance >= cutoff || partners.iter().any(|&(o, _)| o == other) {
                    continue;
                }
                if let [Some(x), Some(y), Some(z)] = tri.map(|n| find(pairs, n, other)) {
                    partners.push((other, [x, y, z]));
                }
            }
        }
        if partners.is_empty() {
            continue;
        }
        let fp = params.faces.get(cell.face_types()[f as usize]);
        terms.clear();
        for &(_, idx) in &partners {
            let d = idx.map(|i| pairs[i].distance);
            let omega = fp.adhesion.min(pairs[idx[0]].adhesion_cap);
            let (repulsion, repulsion_grad) = repulsion_face_mean(d, cutoff, fp.repulsion);
            let (well, well_grad) = adhesion_face_mean(d, cutoff, omega);
            terms.push(FaceTerm { repulsion, repulsion_grad, well, well_grad });
        }
        let (phi, slopes) = combine_face_wells(&terms, 0.25 * fp.adhesion * cutoff * cutoff);
        density[f as usize] = phi;
        let area = areas[f as usize];
        for (&(_, idx), slope) in partners.iter().zip(slopes) {
            for k in 0..3 {
                pairs[idx[k]].coefficient += area * slope[k];
            }
        }
    }
}

/// One partner's face means at a face: repulsion R̄ and well Ā with their gradients.
pub(super) struct FaceTerm {
    pub repulsion: Real,
    pub repulsion_grad: [Real; 3],
    pub well: Real,
    pub well_grad: [Real; 3],
}

#[cfg(test)]
mod tests {
    use super::super::{adhesion_energy_density, repulsion_energy_density};
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Uniform};

    /// Mean of f(d) over the triangle by the midpoint rule on n² sub-triangles (both orientations).
    fn brute_mean(d: [Real; 3], f: impl Fn(Real) -> Real, n: usize) -> Real {
        let mut sum = 0.0;
        let h = 1.0 / n as Real;
        for i in 0..n {
            for j in 0..n - i {
                let (a, b) = (i as Real * h, j as Real * h);
                // Upright sub-triangle centroid.
                let (u, v) = (a + h / 3.0, b + h / 3.0);
                sum += f(d[0] * (1.0 - u - v) + d[1] * u + d[2] * v);
                if i + j + 1 < n {
                    let (u, v) = (a + 2.0 * h / 3.0, b + 2.0 * h / 3.0);
                    sum += f(d[0] * (1.0 - u - v) + d[1] * u + d[2] * v);
                }
            }
        }
        sum / (n * n) as Real
    }

    #[test]
    fn face_means_match_a_fine_quadrature_and_the_point_law_at_equal_corners() {
        let (c, w, x) = (2e-7, 1e9, 3e10);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for trial in 0..400 {
            // Corners spread over every piece of the law, with ties and near-ties.
            let u = Uniform::new(-1.6 * c, 1.6 * c).unwrap();
            let mut d = [0.0; 3].map(|_| u.sample(&mut rng));
            if trial % 5 == 0 {
                d[1] = d[0];
            }
            if trial % 7 == 0 {
                d[2] = d[0] + 1e-12 * c;
            }
            let (a, _) = adhesion_face_mean(d, c, w);
            let (r, _) = repulsion_face_mean(d, c, x);
            let a_ref = brute_mean(d, |s| adhesion_energy_density(s, c, w), 400);
            let r_ref = brute_mean(d, |s| repulsion_energy_density(s, c, x), 400);
            // The midpoint rule's error is O(h²·|Φ''|) ≈ (1/400)²·ω·(spread)²: below 1e-4 of the scale.
            assert!((a - a_ref).abs() <= 1e-4 * w * c * c, "adhesion, d = {d:?}: {a:e} vs {a_ref:e}");
            assert!((r - r_ref).abs() <= 1e-4 * x * c * c, "repulsion, d = {d:?}: {r:e} vs {r_ref:e}");
            let s = d[0];
            let (a, _) = adhesion_face_mean([s; 3], c, w);
            let (r, _) = repulsion_face_mean([s; 3], c, x);
            assert!((a - adhesion_energy_density(s, c, w)).abs() <= 1e-12 * w * c * c);
            assert!((r - repulsion_energy_density(s, c, x)).abs() <= 1e-12 * x * c * c);
        }
    }

    #[test]
    fn face_mean_gradients_match_finite_differences() {
        let (c, w, x) = (2e-7, 1e9, 3e10);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let h = 1e-6 * c;
        for _ in 0..400 {
            let u = Uniform::new(-1.6 * c, 1.6 * c).unwrap();
            let d = [0.0; 3].map(|_| u.sample(&mut rng));
            for f in [
                &(|d: [Real; 3]| adhesion_face_mean(d, c, w)) as &dyn Fn([Real; 3]) -> (Real, [Real; 3]),
                &|d: [Real; 3]| repulsion_face_mean(d, c, x),
            ] {
                let (_, g) = f(d);
                for k in 0..3 {
                    let (mut up, mut down) = (d, d);
                    up[k] += h;
                    down[k] -= h;
                    let fd = (f(up).0 - f(down).0) / (2.0 * h);
                    // Central differences of a C¹ piecewise quartic: O(h²·Φ''') plus a kink
                    // within h of a corner crossing a knot; 1e-5 of the stress scale ω·c covers both.
                    let scale = w.max(x) * c;
                    assert!((fd - g[k]).abs() <= 1e-5 * scale, "d = {d:?}, corner {k}: {fd:e} vs {:e}", g[k]);
                }
            }
        }
    }
}
