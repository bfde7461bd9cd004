//! How far cells overlap at the end of a run, and whether the spring repulsion can hold their
//! pressure.

use super::Simulation;
use crate::geometry::Real;
use crate::mechanics::ContactModel;
use crate::mesh::FaceType;

/// Overlap (fraction of a cell's volume) above which a run warns at its end.
pub const OVERLAP_WARNING: Real = 5e-3;
/// How many times the Laplace pressure the largest repulsive stress ξ·c must be
/// ([`Simulation::repulsion_shortfalls`]): then the equilibrium depth p/ξ stays below c/4.
pub const REPULSION_MARGIN: Real = 4.0;
/// The spring repulsion [`derived_repulsion`] takes at least: ξ·c this many times the Laplace
/// pressure, so that a contact at that pressure sinks c/25 (a few nanometres at c = 0.2 µm) and two
/// cells overlap by well under 0.5 % of their volume at c/R ≤ 0.2.
pub const REPULSION_PER_PRESSURE: Real = 25.0;
/// And at least this many times the adhesion ω, so that the repulsion's barrier ξc²/2 at depth c is
/// 40 times the well's depth ωc²/4: at w/(2γ) = 0.5 on an R = 2 µm doublet (ω = 5e10 Pa/m),
/// ξ = 2.5·ω let the contact collapse under FIRE (far-field angle 19° off Young–Dupré) where 20·ω
/// reached it within 2° (docs: design note "Spring contacts and Young–Dupré").
pub const REPULSION_PER_ADHESION: Real = 20.0;

/// The spring repulsion ξ (Pa/m) that holds cells of mean tension γ̄ (N/m), radius `radius` (m) and
/// adhesion ω (Pa/m) with contact cutoff c (m): the larger of ξ·c = [`REPULSION_PER_PRESSURE`] × 2γ̄/R
/// and [`REPULSION_PER_ADHESION`] × ω. Stiffer costs relaxation speed: the stiffness ξ·l_min²
/// against γ sets how many steps FIRE needs (an R = 10 µm doublet at ξ = 1e12 Pa/m stopped 29°
/// short of Young–Dupré after 40,000 steps, at 2.5e10 Pa/m 2.2° short).
pub fn derived_repulsion(mean_tension: Real, radius: Real, cutoff: Real, adhesion: Real) -> Real {
    (REPULSION_PER_PRESSURE * 2.0 * mean_tension / radius / cutoff).max(REPULSION_PER_ADHESION * adhesion)
}

/// Area of every node: a third of the areas of its faces.
fn node_areas(mesh: &crate::mesh::CellMesh) -> Vec<Real> {
    let mut areas = vec![0.0; mesh.node_count()];
    for (t, a) in mesh.triangles().iter().zip(mesh.face_areas()) {
        for &n in t {
            areas[n as usize] += a / 3.0;
        }
    }
    areas
}

impl<'p> Simulation<'p> {
    /// Volume (m³) by which each cell overlaps the others at the last evaluation: every node p of a
    /// cell inside another body (signed distance d < 0) spans the column a_p·(−d) between the two
    /// surfaces (a_p: a third of its faces' areas). A contact's overlap is spanned once from each
    /// side, so each column counts half towards both cells. Only penetrations within the contact
    /// cutoff are seen (deeper ones are invisible to the contact model itself), so a cell that went
    /// through another entirely is not counted.
    pub fn overlap_volumes(&self) -> Vec<Real> {
        let mut volumes = vec![0.0; self.tissue.len()];
        for (c, cell) in self.tissue.cells().iter().enumerate() {
            let mut areas = None;
            for (node, other, d) in self.work.contacts.node_contacts(c) {
                if d < 0.0 {
                    let areas = areas.get_or_insert_with(|| node_areas(cell.mesh()));
                    let column = 0.5 * areas[node as usize] * -d;
                    volumes[c] += column;
                    volumes[other as usize] += column;
                }
            }
        }
        volumes
    }

    /// One line per moving cell type whose spring repulsion cannot balance the pressure of its
    /// cells: the largest repulsive stress ξ·c (at depth c) must exceed [`REPULSION_MARGIN`] times
    /// the Laplace pressure 2γ̄/R of its largest-pressure cell (capped at max_pressure), or
    /// neighbours sink by p/ξ — more than c/4 — into each other, or through each other. Empty for
    /// one cell or the coupling model (whose tied nodes cannot cross).
    pub fn repulsion_shortfalls(&self) -> Vec<String> {
        let n = &self.params.numerics;
        if self.tissue.len() < 2 || n.contact_model != ContactModel::Spring {
            return Vec::new();
        }
        let c = n.contact_cutoff;
        let worst = self.params.largest_laplace_pressures(&self.tissue);
        let mut lines = Vec::new();
        for (t, entry) in worst.iter().enumerate() {
            let Some((pressure, radius)) = *entry else { continue };
            let p = &self.params.cell_types[t];
            let xi = FaceType::ALL.iter().map(|f| p.faces.get(*f).repulsion).fold(Real::INFINITY, Real::min);
            if xi * c < REPULSION_MARGIN * pressure {
                lines.push(format!(
                    "cell type {t} ({}): its weakest repulsion ξ = {xi:.3e} Pa/m holds at most ξ·c = {:.3e} Pa (cutoff c = \
                     {:.3} µm), below {REPULSION_MARGIN}× the Laplace pressure 2γ̄/R = {pressure:.3e} Pa of its cells (R ≈ {:.2} \
                     µm): they will sink about {:.3} µm into each other or pass through; set repulsion ≥ {:.1e} Pa/m",
                    p.name,
                    xi * c,
                    c * 1e6,
                    radius * 1e6,
                    pressure / xi * 1e6,
                    REPULSION_MARGIN * pressure / c
                ));
            }
        }
        lines
    }
}
