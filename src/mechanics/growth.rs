//! Growth rates g = dV0/dt drawn per cell (paper Methods, "Pressure"; Table 2: g).
//!
//! Each cell draws from a normal distribution N(avg, std) truncated at ±3σ (as the reference
//! program does), from its own random stream: ChaCha8 seeded with the run's seed, stream = cell id.
//! The draw therefore depends only on (seed, cell id), not on the order or the thread that draws it.

use super::CellTypeParams;
use crate::geometry::Real;
use crate::mesh::Tissue;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Stream offsets so that different random quantities of one cell never share a stream.
const GROWTH_STREAM: u64 = 1 << 40;

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

/// The growth rate (m³/s) of every cell, in tissue order.
pub fn draw_growth_rates(tissue: &Tissue, cell_params: &[&CellTypeParams], seed: u64) -> Vec<Real> {
    tissue
        .cells()
        .iter()
        .zip(cell_params)
        .map(|(cell, p)| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(GROWTH_STREAM + u64::from(cell.id().0));
            truncated_normal(&mut rng, p.growth_rate, p.growth_rate_std)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;
    use crate::mechanics::Parameters;
    use crate::mesh::{Cell, CellId, CellKind, shapes::icosphere};

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
        let p: Vec<_> = t.cells().iter().map(|_| &params.cell_types[0]).collect();
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
}
