//! Per-cell random draws: growth rates g = dV0/dt (paper Methods, "Pressure"; Table 2: g) and
//! division volumes V_max (Methods, "Cell division"; Table 2: V_max).
//!
//! Each cell draws from a normal distribution N(avg, std) truncated at ±3σ (as the reference
//! program does), from its own random stream: ChaCha8 seeded with the run's seed, stream = a
//! per-quantity offset + cell id. A draw therefore depends only on (seed, cell id), not on the order
//! or the thread that draws it; daughters, which get fresh ids, get fresh draws.

use super::CellTypeParams;
use crate::geometry::Real;
use crate::mesh::{CellId, Tissue};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Stream offsets so that different random quantities of one cell never share a stream.
const GROWTH_STREAM: u64 = 1 << 40;
const DIVISION_VOLUME_STREAM: u64 = 2 << 40;
/// Streams of the division plane and cap of a cell (see [`division_seed`]).
const DIVISION_PLANE_STREAM: u64 = 3 << 40;

/// Draws N(mean, std) truncated to mean ± 3·std, from `rng`.
fn truncated_normal(rng: &mut ChaCha8Rng, mean: Real, std: Real) -> Real {
    // A zero (or, in unvalidated parameters, non-finite) spread draws the mean itself.
    let Ok(normal) = Normal::new(mean, std) else { return mean };
    if std <= 0.0 {
        return mean;
    }
    loop {
        let x = normal.sample(rng);
        if (x - mean).abs() <= 3.0 * std {
            return x;
        }
    }
}

fn stream(seed: u64, offset: u64, cell: CellId) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(offset + u64::from(cell.0));
    rng
}

/// The growth rate (m³/s) of cell `cell` with parameters `p`.
pub fn draw_growth_rate(p: &CellTypeParams, seed: u64, cell: CellId) -> Real {
    truncated_normal(&mut stream(seed, GROWTH_STREAM, cell), p.growth_rate, p.growth_rate_std)
}

/// The division volume V_max (m³) of cell `cell`: N(division_volume, division_volume_std) truncated
/// at ±3σ and at 0; `inf` when the type never divides.
pub fn draw_division_volume(p: &CellTypeParams, seed: u64, cell: CellId) -> Real {
    if !p.division_volume.is_finite() {
        return Real::INFINITY;
    }
    truncated_normal(&mut stream(seed, DIVISION_VOLUME_STREAM, cell), p.division_volume, p.division_volume_std).max(0.0)
}

/// A seed for the `attempt`-th division attempt of cell `cell` (random plane orientation, cap
/// points): the first value of the cell's own division stream, mixed with the attempt number.
pub fn division_seed(seed: u64, cell: CellId, attempt: u32) -> u64 {
    let base = stream(seed, DIVISION_PLANE_STREAM, cell).next_u64();
    base ^ u64::from(attempt).wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// The growth rate (m³/s) of every cell, in tissue order.
pub fn draw_growth_rates(tissue: &Tissue, cell_params: &[CellTypeParams], seed: u64) -> Vec<Real> {
    tissue.cells().iter().zip(cell_params).map(|(cell, p)| draw_growth_rate(p, seed, cell.id())).collect()
}

/// The division volume (m³) of every cell, in tissue order.
pub fn draw_division_volumes(tissue: &Tissue, cell_params: &[CellTypeParams], seed: u64) -> Vec<Real> {
    tissue.cells().iter().zip(cell_params).map(|(cell, p)| draw_division_volume(p, seed, cell.id())).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;
    use crate::mechanics::Parameters;
    use crate::mesh::{Cell, CellKind, shapes::icosphere};

    fn tissue(ids: &[u32]) -> Tissue {
        Tissue::from_cells(
            ids.iter()
                .map(|&i| Cell::new(CellId(i), CellKind::Epithelial, 0, icosphere(1.0, 0, Vec3::zeros())))
                .collect(),
        )
        .unwrap()
    }

    #[test]
    fn draws_depend_on_seed_and_cell_id_only_and_stay_within_three_sigma() {
        let mut params = Parameters::default();
        params.cell_types[0].growth_rate = 1e-11;
        params.cell_types[0].growth_rate_std = 2e-12;
        let ids: Vec<u32> = (0..400).collect();
        let t = tissue(&ids);
        let p: Vec<_> = t.cells().iter().map(|_| params.cell_types[0].clone()).collect();
        let a = draw_growth_rates(&t, &p, 7);
        assert!(a.iter().all(|g| (g - 1e-11).abs() <= 6e-12));
        let mean = a.iter().sum::<f64>() / a.len() as f64;
        let var = a.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / a.len() as f64;
        assert!((mean - 1e-11).abs() < 4e-13, "mean {mean}");
        assert!((var.sqrt() / 2e-12 - 1.0).abs() < 0.15, "std {}", var.sqrt());
        // Reordered tissue: same draw per id. Other seed: different draws.
        let rev: Vec<u32> = ids.iter().rev().copied().collect();
        let b = draw_growth_rates(&tissue(&rev), &p, 7);
        assert_eq!(a[0], b[399]);
        assert_ne!(a, draw_growth_rates(&t, &p, 8));
    }

    #[test]
    fn division_volumes_are_per_cell_id_and_infinite_for_types_that_never_divide() {
        let mut params = Parameters::default();
        params.cell_types[0].division_volume = 2e-16;
        params.cell_types[0].division_volume_std = 2e-17;
        let p = &params.cell_types[0];
        let a: Vec<Real> = (0..200).map(|i| draw_division_volume(p, 3, CellId(i))).collect();
        assert!(a.iter().all(|v| (v - 2e-16).abs() <= 6e-17 + 1e-30));
        assert!(a.windows(2).any(|w| w[0] != w[1]));
        assert_eq!(draw_division_volume(p, 3, CellId(17)), a[17]);
        // Independent of the growth-rate stream of the same cell.
        params.cell_types[0].growth_rate_std = 1e-12;
        let g = draw_growth_rate(&params.cell_types[0], 3, CellId(17));
        assert_ne!(g, 1e-11);
        assert_eq!(draw_division_volume(&params.cell_types[1], 3, CellId(17)), Real::INFINITY);
        assert_ne!(division_seed(3, CellId(1), 0), division_seed(3, CellId(1), 1));
        assert_ne!(division_seed(3, CellId(1), 0), division_seed(3, CellId(2), 0));
    }
}
