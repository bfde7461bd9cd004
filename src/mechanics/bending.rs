//! Membrane bending: the discrete hinge energy of Wardetzky, Bergou, Harmon, Zorin & Grinspun
//! (2007, "Discrete quadratic curvature energies"), as used by SimuCell3D (Runser et al., Methods,
//! "Membrane bending").
//!
//! Every interior edge e = (i, j), shared by faces a = (i, j, k) and b = (j, i, l), is a hinge with
//! energy (J)
//!
//! U_e = k̄ · |r_j − r_i|² / (A_a + A_b) · |n̂_a − n̂_b|²,    k̄ = (k_b(a) + k_b(b)) / 2,
//!
//! with k_b the bending modulus of each face's type (J), A the face areas (m²) and n̂ the unit
//! outward normals. For unit normals |n̂_a − n̂_b|² = 2(1 − n̂_a·n̂_b) = 4 sin²(φ/2), φ the bend angle
//! between the normals; with the paper's dihedral angle θ = π − φ this is its (2 cos(θ/2))², so U_e
//! is the paper's k̄ (|e_ij|²/A_ij)(2 cos(θ_ij/2))². The energy is scale invariant (|e|²/A is
//! dimensionless): a sphere's total bending energy does not depend on its radius. Edges with one
//! face or more than two carry no bending energy.
//!
//! # Why no arccos
//! The paper evaluates θ with `acos` and a sign test (concave or convex); the energy only needs
//! cos²(θ/2), which is a polynomial in the normals. Written as |n̂_a − n̂_b|², it is smooth
//! everywhere (also at a flat hinge, where `acos` has an infinite derivative, and at a fully folded
//! one), free of cancellation near flat (no 1 − cos), and its gradient is exact and cheap.
//!
//! # Forces
//! Forces are the exact negative gradient of U_e with respect to all four nodes (checked by finite
//! differences in the tests). The reference program's forces are not: its four hinge forces do not
//! sum to zero. With s = A_a + A_b, h = |n̂_a − n̂_b|², d = n̂_a − n̂_b and q = k̄|e|²/s = ∂U/∂h:
//!
//! * the edge term gives −2 (k̄ h / s) e on j and the opposite on i;
//! * a face (p, p′, p″) with N = (p′ − p) × (p″ − p) = 2A n̂ changes by dN = δ × (p′ − p″) when its
//!   corner p moves by δ (cyclically for p′, p″), and dU = m · dN with
//!   m_a = q (d/A_a − h (1/(2A_a) + 1/(2s)) n̂_a) and m_b = q (−d/A_b − h (1/(2A_b) + 1/(2s)) n̂_b)
//!   (from dn̂ = (I − n̂n̂ᵀ) dN/|N| and dA = n̂ · dN/2), so ∇_p U = (p′ − p″) × m.
//!
//! That is four cross products per hinge; normals and areas are the caller's, computed once per
//! configuration. The gradient reads each face's winding from the triangle list, so it is exact
//! whatever the order of a hinge's nodes. A face of zero area makes its hinges' forces non-finite
//! (unless their k̄ is zero), which the caller reports as a degenerate mesh.

use super::CellTypeParams;
use super::cell_geometry::CellGeometry;
use crate::geometry::{Real, Vec3};
use crate::mesh::{Adjacency, Cell, CellMesh, FaceType};

/// One interior edge and its two faces: nodes [i, j, k, l] with edge i–j, k the third node of face a, l of face b.
///
/// [`build_hinges`] orders the nodes so that face a (`faces[0]`) runs i → j, i.e. it is wound
/// (i, j, k); on a consistently oriented mesh face b is then wound (j, i, l).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hinge {
    pub nodes: [u32; 4],
    pub faces: [u32; 2],
}

/// Hinges of every edge shared by exactly two faces (other edges carry no bending energy).
pub fn build_hinges(mesh: &CellMesh) -> Vec<Hinge> {
    let adjacency = Adjacency::new(mesh);
    let triangles = mesh.triangles();
    let mut hinges = Vec::with_capacity(adjacency.edges().len());
    for e in 0..adjacency.edges().len() {
        let &[fa, fb] = adjacency.edge_faces(e) else { continue };
        if fa == fb {
            continue;
        }
        let Some(side) = adjacency.face_edges(fa as usize).iter().position(|&s| s as usize == e) else {
            continue;
        };
        let ta = triangles[fa as usize];
        let (i, j, k) = (ta[side], ta[(side + 1) % 3], ta[(side + 2) % 3]);
        let Some(&l) = triangles[fb as usize].iter().find(|&&n| n != i && n != j) else { continue };
        hinges.push(Hinge { nodes: [i, j, k, l], faces: [fa, fb] });
    }
    hinges
}

/// The term's per-cell state and its own pass (bending does not act through the face areas, so it
/// is not in the shared face pass of `forces.rs`): the hinges of the cell's current topology.
#[derive(Clone, Debug, Default)]
pub(super) struct BendingCache {
    hinges: Vec<Hinge>,
    /// The mesh's topology generation the hinges were built for.
    generation: u64,
}

impl BendingCache {
    /// Adds the bending forces of `cell` (whose `geometry` is current) to `forces` and returns the
    /// bending energy (J). With k_b = 0 on every face type (as in the growth benchmark) bending
    /// contributes exactly nothing: no hinges are built and nothing is added; the hinges are
    /// rebuilt lazily once it acts and whenever the topology changed.
    pub(super) fn add_forces(
        &mut self,
        cell: &Cell,
        p: &CellTypeParams,
        geometry: &CellGeometry,
        forces: &mut [Vec3],
    ) -> Real {
        let kb = FaceType::ALL.map(|t| p.faces.get(t).bending_modulus);
        if !kb.iter().any(|&k| k != 0.0) {
            return 0.0;
        }
        let mesh = cell.mesh();
        if self.generation != mesh.topology_generation() {
            self.hinges = build_hinges(mesh);
            self.generation = mesh.topology_generation();
        }
        add_bending_forces(
            mesh.positions(),
            mesh.triangles(),
            &geometry.normals,
            &geometry.areas,
            cell.face_types(),
            kb,
            &self.hinges,
            forces,
        )
    }
}

/// +1 when triangle `t` runs from `i` to `j`, −1 otherwise (it runs from `j` to `i`).
#[inline(always)]
fn winding(t: [u32; 3], i: u32, j: u32) -> Real {
    if (t[0] == i && t[1] == j) || (t[1] == i && t[2] == j) || (t[2] == i && t[0] == j) { 1.0 } else { -1.0 }
}

/// Adds bending forces to `forces` and returns the bending energy (J).
/// `face_normals`/`face_areas`: unit normals and areas of every face (precomputed by the caller for this configuration);
/// `face_types` and `bending_modulus` (J, indexed by FaceType::code()) give each face's k_b.
/// Hinges whose k̄ is zero are skipped (exactly zero energy and force).
#[allow(clippy::too_many_arguments)] // the hot loop takes flat, precomputed per-face arrays
pub fn add_bending_forces(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    face_normals: &[Vec3],
    face_areas: &[Real],
    face_types: &[FaceType],
    bending_modulus: [Real; 3],
    hinges: &[Hinge],
    forces: &mut [Vec3],
) -> Real {
    let mut energy = 0.0;
    for hinge in hinges {
        let [fa, fb] = hinge.faces.map(|f| f as usize);
        let kbar =
            0.5 * (bending_modulus[face_types[fa].code() as usize] + bending_modulus[face_types[fb].code() as usize]);
        if kbar == 0.0 {
            continue;
        }
        let [i, j, k, l] = hinge.nodes;
        let (ri, rj, rk, rl) =
            (positions[i as usize], positions[j as usize], positions[k as usize], positions[l as usize]);
        let (na, nb) = (face_normals[fa], face_normals[fb]);
        let (area_a, area_b) = (face_areas[fa], face_areas[fb]);

        let e = rj - ri;
        let d = na - nb;
        let bend = d.norm_squared(); // 2(1 − n̂a·n̂b) = 4 sin²(φ/2)
        let inv_s = 1.0 / (area_a + area_b);
        let q = kbar * e.norm_squared() * inv_s; // ∂U/∂bend
        energy += q * bend;

        // Edge-length term: −∇_j = −2 (k̄ bend / s) e, −∇_i the opposite.
        let f_edge = (-2.0 * kbar * bend * inv_s) * e;
        // Face terms dU = m · dN, signed by each face's winding relative to i → j.
        let half_bend_s = 0.5 * bend * inv_s;
        let inv_a = 1.0 / area_a;
        let inv_b = 1.0 / area_b;
        let m_a = (q * winding(triangles[fa], i, j)) * (d * inv_a - na * (0.5 * bend * inv_a + half_bend_s));
        let m_b = (q * winding(triangles[fb], i, j)) * (-d * inv_b - nb * (0.5 * bend * inv_b + half_bend_s));
        // For a face wound (i, j, x): ∇_i = (r_j − r_x) × m, ∇_j = (r_x − r_i) × m, ∇_x = −(∇_i + ∇_j).
        let gai = (rj - rk).cross(&m_a);
        let gaj = (rk - ri).cross(&m_a);
        let gbi = (rj - rl).cross(&m_b);
        let gbj = (rl - ri).cross(&m_b);

        forces[i as usize] -= f_edge + gai + gbi;
        forces[j as usize] += f_edge - gaj - gbj;
        forces[k as usize] += gai + gaj;
        forces[l as usize] += gbi + gbj;
    }
    energy
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::triangle_area_vector;
    use crate::mesh::shapes::icosphere;

    const MODULI: [Real; 3] = [2e-18, 5e-19, 1e-18];

    /// Minimal seeded generator (Knuth's MMIX LCG), uniform in [−1, 1).
    struct Lcg(u64);

    impl Lcg {
        fn next(&mut self) -> Real {
            self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (self.0 >> 11) as Real / (1u64 << 52) as Real - 1.0
        }

        fn vec(&mut self) -> Vec3 {
            Vec3::new(self.next(), self.next(), self.next())
        }
    }

    /// A cell with positions, triangles, face types and hinges.
    struct Setup {
        positions: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
        types: Vec<FaceType>,
        hinges: Vec<Hinge>,
    }

    impl Setup {
        fn from_mesh(mesh: &CellMesh, types: Vec<FaceType>) -> Self {
            Self {
                positions: mesh.positions().to_vec(),
                triangles: mesh.triangles().to_vec(),
                types,
                hinges: build_hinges(mesh),
            }
        }

        /// Energy and forces at `positions`, normals and areas computed from them.
        fn evaluate_at(&self, positions: &[Vec3], moduli: [Real; 3], hinges: &[Hinge]) -> (Real, Vec<Vec3>) {
            let area_vectors: Vec<Vec3> = self
                .triangles
                .iter()
                .map(|t| {
                    triangle_area_vector(
                        &positions[t[0] as usize],
                        &positions[t[1] as usize],
                        &positions[t[2] as usize],
                    )
                })
                .collect();
            let areas: Vec<Real> = area_vectors.iter().map(|v| v.norm()).collect();
            let normals: Vec<Vec3> =
                area_vectors.iter().map(|v| v.try_normalize(0.0).unwrap_or_else(Vec3::zeros)).collect();
            let mut forces = vec![Vec3::zeros(); positions.len()];
            let energy = add_bending_forces(
                positions,
                &self.triangles,
                &normals,
                &areas,
                &self.types,
                moduli,
                hinges,
                &mut forces,
            );
            (energy, forces)
        }

        fn evaluate(&self, moduli: [Real; 3]) -> (Real, Vec<Vec3>) {
            self.evaluate_at(&self.positions, moduli, &self.hinges)
        }

        fn mean_edge_length(&self) -> Real {
            let p = &self.positions;
            let sum: Real = self.hinges.iter().map(|h| (p[h.nodes[1] as usize] - p[h.nodes[0] as usize]).norm()).sum();
            sum / self.hinges.len() as Real
        }
    }

    /// Icosphere of radius 5 µm centred off the origin, nodes moved by up to ~10 % of the edge
    /// length, face types cycling pseudo-randomly.
    fn random_cell(subdivisions: u32, seed: u64) -> Setup {
        let mut rng = Lcg(seed);
        let mut mesh = icosphere(5e-6, subdivisions, Vec3::new(3e-6, -2e-6, 1e-6));
        let edge = mesh.edge_length_stats().unwrap().mean;
        for p in mesh.positions_mut() {
            *p += (0.1 * edge / 3f64.sqrt()) * rng.vec();
        }
        let types = (0..mesh.face_count()).map(|_| FaceType::ALL[((rng.next() + 1.0) * 1.5) as usize % 3]).collect();
        Setup::from_mesh(&mesh, types)
    }

    /// Two triangles a = (0, 1, 2) and b = (1, 0, 3) on an edge along x (µm scale), bent by `bend`
    /// radians between their normals (0 = flat, π = folded onto each other).
    fn single_hinge(bend: Real, types: [FaceType; 2]) -> Setup {
        let s = 1e-6;
        let positions = vec![
            Vec3::new(0.0, 0.0, 0.0) * s,
            Vec3::new(1.0, 0.0, 0.0) * s,
            Vec3::new(0.4, 0.9, 0.0) * s,
            Vec3::new(0.7, -1.1 * bend.cos(), 1.1 * bend.sin()) * s,
        ];
        let mesh = CellMesh::from_triangles(positions, vec![[0, 1, 2], [1, 0, 3]]).unwrap();
        Setup::from_mesh(&mesh, types.to_vec())
    }

    /// Asserts forces = −∇U by central differences with step 1e-6 × the mean edge length, to 1e-6
    /// relative to the largest force component. Truncation error is O(step²) ≈ 1e-12 relative and
    /// round-off ≈ ε·U/step ≈ 1e-10 relative, so 1e-6 leaves a wide margin while any wrong term
    /// (typically O(1) relative) fails.
    fn assert_gradient(setup: &Setup, moduli: [Real; 3]) {
        let (_, forces) = setup.evaluate(moduli);
        let step = 1e-6 * setup.mean_edge_length();
        let scale = forces.iter().flat_map(|f| f.iter().map(|c| c.abs())).fold(0.0, Real::max);
        assert!(scale > 0.0, "no force to check");
        let mut worst: Real = 0.0;
        let mut moved = setup.positions.clone();
        for n in 0..moved.len() {
            for c in 0..3 {
                let original = moved[n][c];
                moved[n][c] = original + step;
                let (up, _) = setup.evaluate_at(&moved, moduli, &setup.hinges);
                moved[n][c] = original - step;
                let (down, _) = setup.evaluate_at(&moved, moduli, &setup.hinges);
                moved[n][c] = original;
                let numeric = -(up - down) / (2.0 * step);
                worst = worst.max((numeric - forces[n][c]).abs());
            }
        }
        assert!(worst <= 1e-6 * scale, "max force error {worst:e} vs largest force {scale:e}");
    }

    #[test]
    fn build_hinges_orders_nodes_by_face_winding() {
        let mesh = icosphere(1.0, 1, Vec3::zeros());
        let hinges = build_hinges(&mesh);
        assert_eq!(hinges.len(), 3 * mesh.face_count() / 2);
        for h in &hinges {
            let [i, j, k, l] = h.nodes;
            let [ta, tb] = h.faces.map(|f| mesh.triangles()[f as usize]);
            assert_eq!(winding(ta, i, j), 1.0);
            assert_eq!(winding(tb, j, i), 1.0);
            assert!(ta.contains(&k) && tb.contains(&l) && k != l && ![i, j].contains(&k) && ![i, j].contains(&l));
        }
        // An open surface: the three edges of a removed face border one face each.
        let mut triangles = mesh.triangles().to_vec();
        triangles.pop();
        let open = CellMesh::from_triangles(mesh.positions().to_vec(), triangles).unwrap();
        assert_eq!(build_hinges(&open).len(), hinges.len() - 3);
    }

    #[test]
    fn forces_are_the_exact_negative_gradient_on_perturbed_icospheres() {
        for (subdivisions, seed) in [(1, 1), (2, 7)] {
            let setup = random_cell(subdivisions, seed);
            let codes: Vec<u32> = setup.types.iter().map(|t| t.code()).collect();
            assert!((0..3).all(|c| codes.contains(&c)), "all face types present");
            assert_gradient(&setup, MODULI);
        }
    }

    #[test]
    fn forces_are_the_exact_negative_gradient_on_single_hinges() {
        let types = [FaceType::Apical, FaceType::Basal];
        for bend in [1e-3, 0.3, -0.7, 2.0, 2.5, 3.0, 3.1] {
            let setup = single_hinge(bend, types);
            assert_gradient(&setup, MODULI);
            // The energy is the paper's k̄ |e|²/(A_a + A_b) (2 cos(θ/2))² with θ = π − |bend|.
            let (energy, _) = setup.evaluate(MODULI);
            let p = &setup.positions;
            let area = |t: [usize; 3]| triangle_area_vector(&p[t[0]], &p[t[1]], &p[t[2]]).norm();
            let theta = std::f64::consts::PI - bend.abs();
            let kbar = (MODULI[0] + MODULI[2]) / 2.0;
            let expected = kbar * (p[1] - p[0]).norm_squared() / (area([0, 1, 2]) + area([1, 0, 3]))
                * (2.0 * (theta / 2.0).cos()).powi(2);
            assert!((energy - expected).abs() <= 1e-12 * expected, "bend {bend}: {energy:e} vs {expected:e}");
        }
    }

    #[test]
    fn gradient_is_exact_whatever_the_node_order_and_face_winding() {
        let types = [FaceType::Lateral, FaceType::Basal];
        // Hinge given as (j, i, k, l): face a then runs against i → j.
        let mut setup = single_hinge(0.8, types);
        let (energy, forces) = setup.evaluate(MODULI);
        setup.hinges[0].nodes.swap(0, 1);
        let (swapped_energy, swapped_forces) = setup.evaluate(MODULI);
        assert_eq!(swapped_energy, energy);
        for (f, g) in forces.iter().zip(&swapped_forces) {
            assert!((f - g).norm() <= 1e-12 * f.norm());
        }
        assert_gradient(&setup, MODULI);
        // Face b wound like face a (an inconsistently oriented pair): normals as the triangles say.
        let mut setup = single_hinge(0.8, types);
        setup.triangles[1] = [0, 1, 3];
        assert_gradient(&setup, MODULI);
    }

    #[test]
    fn hinge_forces_sum_to_zero_with_zero_torque() {
        let setup = random_cell(2, 3);
        let (_, forces) = setup.evaluate(MODULI);
        let total: Vec3 = forces.iter().sum();
        let magnitude: Real = forces.iter().map(|f| f.norm()).sum();
        assert!(total.norm() <= 1e-13 * magnitude, "net force {total:?} vs Σ|F| {magnitude:e}");
        let torque: Vec3 = setup.positions.iter().zip(&forces).map(|(r, f)| r.cross(f)).sum();
        let moment: Real = setup.positions.iter().zip(&forces).map(|(r, f)| r.norm() * f.norm()).sum();
        assert!(torque.norm() <= 1e-13 * moment, "net torque {torque:?} vs Σ|r||F| {moment:e}");
        // And hinge by hinge.
        for h in 0..setup.hinges.len() {
            let (_, forces) = setup.evaluate_at(&setup.positions, MODULI, &setup.hinges[h..h + 1]);
            let nodes = setup.hinges[h].nodes.map(|n| n as usize);
            let total: Vec3 = nodes.iter().map(|&n| forces[n]).sum();
            let torque: Vec3 = nodes.iter().map(|&n| setup.positions[n].cross(&forces[n])).sum();
            let magnitude: Real = nodes.iter().map(|&n| forces[n].norm()).sum();
            assert!(magnitude > 0.0);
            assert!(total.norm() <= 1e-14 * magnitude, "hinge {h}: net force {total:?}");
            assert!(torque.norm() <= 1e-14 * magnitude * 1e-5, "hinge {h}: net torque {torque:?}");
        }
    }

    #[test]
    fn planar_surface_has_no_bending_energy() {
        // A 5 × 5 grid of squares split into triangles, in a tilted plane.
        let (u, v) = (Vec3::new(1.0, 0.5, -0.2).normalize() * 1e-6, Vec3::new(-0.3, 0.4, 1.0).normalize() * 1e-6);
        let v = (v - u * (u.dot(&v) / u.norm_squared())).normalize() * 1e-6;
        let positions: Vec<Vec3> =
            (0..36).map(|n| Vec3::new(2e-6, 1e-6, -3e-6) + (n % 6) as Real * u + (n / 6) as Real * v).collect();
        let mut triangles = Vec::new();
        for y in 0..5u32 {
            for x in 0..5u32 {
                let c = y * 6 + x;
                triangles.extend([[c, c + 1, c + 7], [c, c + 7, c + 6]]);
            }
        }
        let mesh = CellMesh::from_triangles(positions, triangles).unwrap();
        let types = (0..mesh.face_count()).map(|f| FaceType::ALL[f % 3]).collect();
        let setup = Setup::from_mesh(&mesh, types);
        assert_eq!(setup.hinges.len(), 5 * 4 * 2 + 5 * 5);
        let (energy, forces) = setup.evaluate(MODULI);
        // A unit fold would carry ~k_b; round-off in the normals gives ~k_b·ε².
        assert!(energy.abs() <= 1e-24, "planar energy {energy:e}");
        let max_force = forces.iter().map(|f| f.norm()).fold(0.0, Real::max);
        assert!(max_force <= 1e-10 * MODULI[0] / 1e-6, "planar force {max_force:e}");
    }

    #[test]
    fn energy_is_invariant_under_rigid_motion_and_forces_rotate_with_the_body() {
        let setup = random_cell(2, 11);
        let (energy, forces) = setup.evaluate(MODULI);
        assert!(energy > 0.0);
        // Rodrigues rotation about an oblique axis, then a translation.
        let axis = Vec3::new(0.3, -0.5, 0.8).normalize();
        let angle: Real = 1.1;
        let rotate =
            |p: &Vec3| p * angle.cos() + axis.cross(p) * angle.sin() + axis * axis.dot(p) * (1.0 - angle.cos());
        let shift = Vec3::new(-4e-6, 7e-6, 2e-6);
        let moved: Vec<Vec3> = setup.positions.iter().map(|p| rotate(p) + shift).collect();
        let (moved_energy, moved_forces) = setup.evaluate_at(&moved, MODULI, &setup.hinges);
        assert!((moved_energy - energy).abs() <= 1e-12 * energy, "{moved_energy:e} vs {energy:e}");
        let scale = forces.iter().map(|f| f.norm()).fold(0.0, Real::max);
        for (f, g) in forces.iter().zip(&moved_forces) {
            assert!((rotate(f) - g).norm() <= 1e-9 * scale);
        }
    }

    #[test]
    fn sphere_bending_energy_is_independent_of_radius() {
        // Continuum limit: Σ_e |e|² φ_e²/(A_a + A_b) ≈ (1/3)∫(2H)² dA = 16π/3 on any sphere.
        let mut per_modulus = Vec::new();
        for subdivisions in [4, 5] {
            let energy_at = |radius: Real| {
                let mesh = icosphere(radius, subdivisions, Vec3::new(1e-6, 0.0, -2e-6));
                let setup = Setup::from_mesh(&mesh, vec![FaceType::Lateral; mesh.face_count()]);
                setup.evaluate(MODULI).0
            };
            let (small, large) = (energy_at(5e-6), energy_at(10e-6));
            assert!((small - large).abs() <= 1e-9 * small, "U(R) = {small:e}, U(2R) = {large:e}");
            per_modulus.push(small / MODULI[1]);
            println!(
                "icosphere {subdivisions}: U/k_b = {:.6} (16π/3 = {:.6})",
                small / MODULI[1],
                16.0 * std::f64::consts::PI / 3.0
            );
        }
        for u in per_modulus {
            assert!((u / (16.0 * std::f64::consts::PI / 3.0) - 1.0).abs() < 0.05, "U/k_b = {u}");
        }
    }

    #[test]
    fn hinges_without_stiffness_give_exactly_zero_force() {
        // Apical faces (z > centre) have k_b = 0: nodes touched only by apical–apical hinges feel
        // exactly nothing.
        let setup = {
            let mut setup = random_cell(2, 5);
            let p = &setup.positions;
            setup.types = setup
                .triangles
                .iter()
                .map(|t| {
                    let z = t.iter().map(|&n| p[n as usize].z).sum::<Real>() / 3.0;
                    if z > 1e-6 { FaceType::Apical } else { FaceType::Basal }
                })
                .collect();
            setup
        };
        let moduli = [0.0, 5e-19, 1e-18];
        let (energy, forces) = setup.evaluate(moduli);
        assert!(energy > 0.0);
        let mut stiff_node = vec![false; setup.positions.len()];
        for h in &setup.hinges {
            if h.faces.iter().any(|&f| setup.types[f as usize] != FaceType::Apical) {
                h.nodes.iter().for_each(|&n| stiff_node[n as usize] = true);
            }
        }
        let free = stiff_node.iter().filter(|&&s| !s).count();
        assert!(free > 10, "test needs nodes without stiff hinges");
        for (n, f) in forces.iter().enumerate() {
            if !stiff_node[n] {
                assert_eq!(*f, Vec3::zeros(), "node {n}");
            }
        }

        // Zero modulus everywhere: nothing at all, even on a degenerate (zero-area) hinge.
        let (energy, forces) = setup.evaluate([0.0; 3]);
        assert_eq!(energy, 0.0);
        assert!(forces.iter().all(|f| *f == Vec3::zeros()));
        let mut flat = single_hinge(0.5, [FaceType::Apical, FaceType::Apical]);
        flat.positions[2] = flat.positions[0];
        let (energy, forces) = flat.evaluate(moduli);
        assert_eq!(energy, 0.0);
        assert!(forces.iter().all(|f| *f == Vec3::zeros()));
    }

    #[test]
    fn forces_are_added_not_overwritten() {
        let setup = single_hinge(1.0, [FaceType::Lateral, FaceType::Lateral]);
        let (_, forces) = setup.evaluate(MODULI);
        let p = &setup.positions;
        let area_vectors: Vec<Vec3> = setup
            .triangles
            .iter()
            .map(|t| triangle_area_vector(&p[t[0] as usize], &p[t[1] as usize], &p[t[2] as usize]))
            .collect();
        let areas: Vec<Real> = area_vectors.iter().map(|v| v.norm()).collect();
        let normals: Vec<Vec3> = area_vectors.iter().map(|v| v.normalize()).collect();
        let offset = Vec3::new(1e-9, -2e-9, 3e-9);
        let mut accumulated = vec![offset; 4];
        add_bending_forces(
            p,
            &setup.triangles,
            &normals,
            &areas,
            &setup.types,
            MODULI,
            &setup.hinges,
            &mut accumulated,
        );
        for (a, f) in accumulated.iter().zip(&forces) {
            assert!((a - offset - f).norm() <= 1e-12 * f.norm());
        }
    }
}
