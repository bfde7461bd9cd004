//! Far-field contact angles: the external angle between two cells' free surfaces where they meet,
//! read from the shapes away from the rim instead of from the rim's own faces.
//!
//! The rim angle ([`super::rim_angle`]) reads the faces next to the contact line, which a mesh rounds
//! over one or two edge lengths (remeshing, the spring contact's gap, the voxels of a segmentation),
//! so it is biased: −2.6…+1.1° on coupled doublets and +6…+22° on spring doublets (issue 20). Here
//! each cell's free surface is fitted by a sphere through the centroids of its free faces farther
//! than a margin from any of its contact faces (a free surface of uniform tension at equilibrium is a
//! sphere cap), and the interface by the least-squares plane through the contact faces of both
//! sides. A cap of centre c and radius ρ meets the plane at the angle ψ with cos ψ = h/ρ, h the
//! distance from c to the plane on the cell's own side; the external angle is ψ_a + ψ_b (Young–Dupré
//! for an equal doublet: cos(θ/2) = 1 − w/(2γ)).
//!
//! A cell whose free faces are not one sphere (several caps in a cluster, an irregular segmented
//! cell: rms distance to the fitted sphere above [`MAX_SPHERE_RMS`] of its radius), too few faces on
//! either side, or an interface that is not flat (rms distance from the plane above
//! [`MAX_PLANE_RMS`] of the interface's extent: unequal pressures curve it) gets no far-field angle:
//! it is left empty rather than guessed.

use super::face_contacts::{FREE, FaceContacts};
use crate::geometry::{Real, Vec3};
use crate::mesh::CellMesh;

/// Fewest faces behind a sphere or plane fit.
pub const MIN_FIT_FACES: usize = 12;
/// Largest rms distance of the free faces from their sphere, as a fraction of its radius.
pub const MAX_SPHERE_RMS: Real = 0.02;
/// Largest rms distance of the interface faces from their plane, as a fraction of the interface's
/// rms radius.
pub const MAX_PLANE_RMS: Real = 0.05;

/// A sphere fitted to a cell's free surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FreeCap {
    pub centre: Vec3,
    pub radius: Real,
}

fn centroids(mesh: &CellMesh, keep: impl Fn(usize) -> bool) -> Vec<Vec3> {
    let p = mesh.positions();
    mesh.triangles()
        .iter()
        .enumerate()
        .filter(|(f, _)| keep(*f))
        .map(|(_, t)| (p[t[0] as usize] + p[t[1] as usize] + p[t[2] as usize]) / 3.0)
        .collect()
}

/// Least-squares sphere through points (|x|² = 2c·x + (ρ² − |c|²), linear in c and ρ² − |c|², on
/// coordinates relative to the points' mean for conditioning) and its rms distance; `None` when the
/// points fix no sphere.
pub fn fit_sphere(points: &[Vec3]) -> Option<(FreeCap, Real)> {
    let mean = points.iter().sum::<Vec3>() / points.len() as Real;
    let mut a = nalgebra::DMatrix::<Real>::zeros(points.len(), 4);
    let mut b = nalgebra::DVector::<Real>::zeros(points.len());
    for (i, p) in points.iter().enumerate() {
        let q = p - mean;
        a[(i, 0)] = 2.0 * q.x;
        a[(i, 1)] = 2.0 * q.y;
        a[(i, 2)] = 2.0 * q.z;
        a[(i, 3)] = 1.0;
        b[i] = q.norm_squared();
    }
    let x = a.svd(true, true).solve(&b, 1e-14).ok()?;
    let c = Vec3::new(x[0], x[1], x[2]);
    let r2 = x[3] + c.norm_squared();
    if !(r2.is_finite() && r2 > 0.0) {
        return None;
    }
    let radius = r2.sqrt();
    let centre = c + mean;
    let rms =
        (points.iter().map(|p| ((p - centre).norm() - radius).powi(2)).sum::<Real>() / points.len() as Real).sqrt();
    Some((FreeCap { centre, radius }, rms))
}

/// The sphere of a cell's free surface: faces free of contact whose centroid lies farther than
/// `margin` from every contact face's centroid. `None` when fewer than [`MIN_FIT_FACES`] remain or
/// they are not one sphere ([`MAX_SPHERE_RMS`]).
pub fn free_cap(mesh: &CellMesh, contacts: &FaceContacts, margin: Real) -> Option<FreeCap> {
    let touching = centroids(mesh, |f| contacts.partner[f] != FREE);
    let free: Vec<Vec3> = centroids(mesh, |f| contacts.partner[f] == FREE)
        .into_iter()
        .filter(|p| touching.iter().all(|q| (p - q).norm_squared() > margin * margin))
        .collect();
    if free.len() < MIN_FIT_FACES {
        return None;
    }
    let (cap, rms) = fit_sphere(&free)?;
    (rms <= MAX_SPHERE_RMS * cap.radius).then_some(cap)
}

/// Least-squares plane through points: (centroid, unit normal); `None` when fewer than
/// [`MIN_FIT_FACES`] points or they are not flat ([`MAX_PLANE_RMS`]).
pub fn interface_plane(points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    if points.len() < MIN_FIT_FACES {
        return None;
    }
    let plane = least_squares_plane(points)?;
    (plane.off_plane_ms.sqrt() <= MAX_PLANE_RMS * plane.spread_ms.sqrt()).then_some((plane.centroid, plane.normal))
}

/// The least-squares plane through points (smallest principal axis of their scatter).
#[derive(Copy, Clone, Debug)]
pub struct LeastSquaresPlane {
    pub centroid: Vec3,
    /// Unit normal (sign arbitrary).
    pub normal: Vec3,
    /// Mean squared distance of the points from the plane.
    pub off_plane_ms: Real,
    /// Mean squared distance of the points from their centroid.
    pub spread_ms: Real,
}

/// [`LeastSquaresPlane`] through `points`; `None` for an empty set or a degenerate normal.
pub fn least_squares_plane(points: &[Vec3]) -> Option<LeastSquaresPlane> {
    if points.is_empty() {
        return None;
    }
    let n = points.len() as Real;
    let centroid = points.iter().sum::<Vec3>() / n;
    let mut cov = nalgebra::Matrix3::<Real>::zeros();
    for p in points {
        let q = p - centroid;
        cov += q * q.transpose();
    }
    let eigen = cov.symmetric_eigen();
    let k = eigen.eigenvalues.imin();
    let normal = eigen.eigenvectors.column(k).into_owned().try_normalize(0.0)?;
    Some(LeastSquaresPlane {
        centroid,
        normal,
        off_plane_ms: eigen.eigenvalues[k].max(0.0) / n,
        spread_ms: eigen.eigenvalues.sum().max(0.0) / n,
    })
}

/// External far-field angle (radians) between two cells' caps meeting at the plane (`point`,
/// `normal`); `a_side` is any point inside cell a (its centroid), which orients the plane.
pub fn far_field_angle(cap_a: &FreeCap, cap_b: &FreeCap, point: Vec3, normal: Vec3, a_side: Vec3) -> Real {
    // n points from a's side into b's.
    let n = if (point - a_side).dot(&normal) >= 0.0 { normal } else { -normal };
    let psi = |cap: &FreeCap, own: Vec3| ((point - cap.centre).dot(&own) / cap.radius).clamp(-1.0, 1.0).acos();
    psi(cap_a, n) + psi(cap_b, -n)
}

/// The far-field angle of the contact between cells a and b (tissue indices `ia`, `ib`), or `None`
/// where it cannot be read (see the module doc).
#[allow(clippy::too_many_arguments)]
pub fn contact_far_field_angle(
    mesh_a: &CellMesh,
    contacts_a: &FaceContacts,
    ia: u32,
    mesh_b: &CellMesh,
    contacts_b: &FaceContacts,
    ib: u32,
    centroid_a: Vec3,
    margin: Real,
) -> Option<Real> {
    let cap_a = free_cap(mesh_a, contacts_a, margin)?;
    let cap_b = free_cap(mesh_b, contacts_b, margin)?;
    let mut interface = centroids(mesh_a, |f| contacts_a.partner[f] == ib);
    interface.extend(centroids(mesh_b, |f| contacts_b.partner[f] == ia));
    let (point, normal) = interface_plane(&interface)?;
    Some(far_field_angle(&cap_a, &cap_b, point, normal, centroid_a))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::icosphere;

    /// A unit-free check of the geometry: caps of radius ρ whose centres lie h = ρ·cos ψ from the
    /// plane give ψ each, whatever the plane's orientation sign.
    #[test]
    fn caps_meeting_a_plane_give_the_sum_of_their_half_angles() {
        let (r, psi_a, psi_b) = (2.0, 0.6_f64, 0.9_f64);
        let a = FreeCap { centre: Vec3::new(-r * psi_a.cos(), 0.0, 0.0), radius: r };
        let b = FreeCap { centre: Vec3::new(r * psi_b.cos(), 0.0, 0.0), radius: r };
        for normal in [Vec3::x(), -Vec3::x()] {
            let theta = far_field_angle(&a, &b, Vec3::zeros(), normal, Vec3::new(-1.0, 0.0, 0.0));
            assert!((theta - (psi_a + psi_b)).abs() < 1e-12, "{theta}");
        }
    }

    /// The sphere fit recovers a sphere from points on part of it, and refuses points that are not
    /// one sphere.
    #[test]
    fn the_free_cap_fit_recovers_a_sphere_and_refuses_a_non_sphere() {
        let mesh = icosphere(3e-6, 3, Vec3::new(1e-6, 2e-6, -1e-6));
        let contacts = FaceContacts {
            partner: mesh
                .triangles()
                .iter()
                .map(|t| if mesh.positions()[t[0] as usize].x > 2e-6 { 1 } else { FREE })
                .collect(),
            distance: vec![0.0; mesh.face_count()],
        };
        let cap = free_cap(&mesh, &contacts, 2e-7).unwrap();
        // Face centroids lie inside the sphere by the chord sag (≈ h²/(8R)·… ≈ 0.3 % here).
        assert!((cap.radius / 3e-6 - 1.0).abs() < 0.01, "{cap:?}");
        assert!((cap.centre - Vec3::new(1e-6, 2e-6, -1e-6)).norm() < 3e-8, "{cap:?}");
        let mut squashed = mesh.clone();
        for p in squashed.positions_mut() {
            p.z *= 0.6;
        }
        assert_eq!(free_cap(&squashed, &contacts, 2e-7), None);
    }
}
