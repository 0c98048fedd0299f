//! The belief in the compact form a `TrackReport` carries ([`proto::msg::GridPosterior`]):
//! cells summed in blocks so that neither side exceeds the report's limit, each block's mass
//! quantized to a byte relative to the fullest.

use super::belief::Belief;
use proto::msg::{GridPosterior, MAX_GRID_POSTERIOR_SIDE};

/// `belief` in at most `side` (≤ [`MAX_GRID_POSTERIOR_SIDE`]) cells per side.
pub fn posterior(belief: &Belief, side: u16) -> GridPosterior {
    let grid = belief.grid();
    let (nx, ny) = grid.shape();
    let side = usize::from(side.clamp(1, MAX_GRID_POSTERIOR_SIDE));
    // One block factor for both axes keeps the cells square.
    let factor = nx.max(ny).div_ceil(side).max(1);
    let (bx, by) = (nx.div_ceil(factor), ny.div_ceil(factor));
    let mut sums = vec![0.0f64; bx * by];
    for (k, m) in belief.mass().iter().enumerate() {
        let (i, j) = (k % nx, k / nx);
        sums[(j / factor) * bx + i / factor] += m;
    }
    let peak = sums.iter().copied().fold(0.0, f64::max);
    let cells = sums
        .iter()
        .map(|m| {
            if peak > 0.0 {
                (255.0 * m / peak).round() as u8
            } else {
                0
            }
        })
        .collect();
    let origin = grid.origin();
    GridPosterior {
        origin: [origin[0] as f32, origin[1] as f32],
        cell_m: (grid.cell() * factor as f64) as f32,
        nx: bx as u16,
        ny: by as u16,
        peak_mass: peak.clamp(0.0, 1.0) as f32,
        cells,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Grid;
    use proto::scenario::World;
    use proto::validate::Validate;
    use std::sync::Arc;

    #[test]
    fn a_large_grid_is_summed_into_blocks_and_keeps_its_peak() {
        let world: World = toml::from_str("min = [0.0, 0.0, 0.0]\nmax = [12.0, 8.0, 2.5]").unwrap();
        let grid = Arc::new(Grid::new(&world, 0.1).unwrap());
        let b = Belief::gaussian(grid, [9.05, 2.05], 0.2);
        let p = posterior(&b, 48);
        assert!(p.nx <= 48 && p.ny <= 48, "{}x{}", p.nx, p.ny);
        assert_eq!(p.cells.len(), usize::from(p.nx) * usize::from(p.ny));
        let best = (0..p.cells.len()).max_by_key(|k| p.cells[*k]).unwrap();
        let (i, j) = (best % usize::from(p.nx), best / usize::from(p.nx));
        let centre = [
            p.origin[0] + (i as f32 + 0.5) * p.cell_m,
            p.origin[1] + (j as f32 + 0.5) * p.cell_m,
        ];
        assert!((centre[0] - 9.05).abs() <= p.cell_m && (centre[1] - 2.05).abs() <= p.cell_m);
        assert_eq!(p.cells[best], 255);
        let total: f32 = (0..usize::from(p.ny))
            .flat_map(|j| (0..usize::from(p.nx)).map(move |i| (i, j)))
            .map(|(i, j)| p.mass(i, j))
            .sum();
        assert!((total - 1.0).abs() < 0.05, "mass {total}");
        // It travels: a report with it validates.
        let mut env = proto::examples::messages()[8].clone();
        if let proto::Message::TrackReport(r) = &mut env.body {
            r.grid = Some(p);
        }
        env.validate().unwrap();
        assert!(proto::encode(&env).unwrap().len() < proto::MAX_FRAME_BYTES);
    }
}
