//! The grid the estimator's belief lives on: regular square cells over the world's floor box,
//! which cells are free, and which cells motion can connect without crossing a wall.
//!
//! Walls are the scenario's zero-thickness vertical segments. A cell is *blocked* (no belief
//! may live there) when its centre lies outside the room or closer than half a cell to a wall.
//! The edge between two neighbouring cell centres is *cut* when the segment joining them
//! crosses a wall, at any height: a person cannot walk through a low wall either. Along each
//! row and each column the free cells form *runs*, maximal stretches joined by uncut edges;
//! the prediction only moves belief within a run, so one step can never carry belief across a
//! wall, whatever the kernel's width.

use super::GridError;
use nalgebra::Vector3;
use proto::scenario::World;

/// Most cells a grid may have (2000 × 2000).
pub const MAX_GRID_CELLS: usize = 4_000_000;

/// A run of free cells along one axis: indices `lo..=hi` along that axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Run {
    pub lo: u32,
    pub hi: u32,
}

const NO_RUN: Run = Run { lo: 1, hi: 0 };

/// Cells, free mask and runs over a world's floor.
#[derive(Clone, Debug)]
pub struct Grid {
    origin: [f64; 2],
    cell: f64,
    nx: usize,
    ny: usize,
    free: Vec<bool>,
    free_count: usize,
    /// Per cell, its run along x (indices are x) and along y (indices are y).
    pub(crate) row_run: Vec<Run>,
    pub(crate) col_run: Vec<Run>,
}

impl Grid {
    /// Cells of `cell` metres over the world's `[min, max]` box in x and y, the last row and
    /// column reaching past `max` when the box is not a multiple of the cell (those cells are
    /// free only if their centre is inside).
    ///
    /// # Errors
    /// A cell size that is not finite and positive, a box without area, or more than
    /// [`MAX_GRID_CELLS`] cells.
    pub fn new(world: &World, cell: f64) -> Result<Grid, GridError> {
        if !(cell.is_finite() && cell > 0.0) {
            return Err(GridError::Invalid(format!("cell size {cell} m is not positive")));
        }
        let (w, h) = (world.max[0] - world.min[0], world.max[1] - world.min[1]);
        if !(w.is_finite() && h.is_finite() && w > 0.0 && h > 0.0) {
            return Err(GridError::Invalid(format!(
                "world box {:?}–{:?} has no floor area",
                world.min, world.max
            )));
        }
        let (fx, fy) = ((w / cell - 1e-9).ceil(), (h / cell - 1e-9).ceil());
        if fx * fy > MAX_GRID_CELLS as f64 {
            return Err(GridError::Invalid(format!(
                "{fx}×{fy} cells of {cell} m, at most {MAX_GRID_CELLS}"
            )));
        }
        let (nx, ny) = (fx as usize, fy as usize);
        let mut grid = Grid {
            origin: [world.min[0], world.min[1]],
            cell,
            nx,
            ny,
            free: vec![false; nx * ny],
            free_count: 0,
            row_run: vec![NO_RUN; nx * ny],
            col_run: vec![NO_RUN; nx * ny],
        };
        for j in 0..ny {
            for i in 0..nx {
                let [x, y] = grid.centre(i, j);
                let inside = x <= world.max[0] && y <= world.max[1];
                let clear = world
                    .walls
                    .iter()
                    .all(|wall| distance_to_segment([x, y], wall.from, wall.to) >= 0.5 * cell);
                grid.free[j * nx + i] = inside && clear;
            }
        }
        grid.free_count = grid.free.iter().filter(|f| **f).count();
        if grid.free_count == 0 {
            return Err(GridError::Invalid(
                "no free cell: walls cover the whole world".into(),
            ));
        }
        grid.build_runs(world);
        Ok(grid)
    }

    /// Join free neighbours along each row and column unless a wall cuts the edge.
    fn build_runs(&mut self, world: &World) {
        let cut = |a: [f64; 2], b: [f64; 2]| {
            let (a, b) = (Vector3::new(a[0], a[1], 0.0), Vector3::new(b[0], b[1], 0.0));
            world.walls.iter().any(|w| w.height > 0.0 && w.crosses(&a, &b))
        };
        let (nx, ny) = (self.nx, self.ny);
        for j in 0..ny {
            let mut i = 0;
            while i < nx {
                if !self.free[j * nx + i] {
                    i += 1;
                    continue;
                }
                let lo = i;
                while i + 1 < nx
                    && self.free[j * nx + i + 1]
                    && !cut(self.centre(i, j), self.centre(i + 1, j))
                {
                    i += 1;
                }
                for k in lo..=i {
                    self.row_run[j * nx + k] = Run {
                        lo: lo as u32,
                        hi: i as u32,
                    };
                }
                i += 1;
            }
        }
        for i in 0..nx {
            let mut j = 0;
            while j < ny {
                if !self.free[j * nx + i] {
                    j += 1;
                    continue;
                }
                let lo = j;
                while j + 1 < ny
                    && self.free[(j + 1) * nx + i]
                    && !cut(self.centre(i, j), self.centre(i, j + 1))
                {
                    j += 1;
                }
                for k in lo..=j {
                    self.col_run[k * nx + i] = Run {
                        lo: lo as u32,
                        hi: j as u32,
                    };
                }
                j += 1;
            }
        }
    }

    /// `(nx, ny)`.
    pub fn shape(&self) -> (usize, usize) {
        (self.nx, self.ny)
    }

    pub fn len(&self) -> usize {
        self.nx * self.ny
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Cell edge, metres.
    pub fn cell(&self) -> f64 {
        self.cell
    }

    /// World `[x, y]` of cell `(0, 0)`'s corner.
    pub fn origin(&self) -> [f64; 2] {
        self.origin
    }

    /// World `[x, y]` of the centre of cell `(i, j)`.
    pub fn centre(&self, i: usize, j: usize) -> [f64; 2] {
        [
            self.origin[0] + (i as f64 + 0.5) * self.cell,
            self.origin[1] + (j as f64 + 0.5) * self.cell,
        ]
    }

    /// Centre of the cell with row-major index `k` (x fastest).
    pub fn centre_of(&self, k: usize) -> [f64; 2] {
        self.centre(k % self.nx, k / self.nx)
    }

    /// Row-major index of the cell holding world `(x, y)`, if on the grid.
    pub fn index_of(&self, x: f64, y: f64) -> Option<usize> {
        let fi = ((x - self.origin[0]) / self.cell).floor();
        let fj = ((y - self.origin[1]) / self.cell).floor();
        (fi >= 0.0 && fj >= 0.0 && fi < self.nx as f64 && fj < self.ny as f64)
            .then(|| fj as usize * self.nx + fi as usize)
    }

    /// Whether belief may live in cell `k`.
    pub fn is_free(&self, k: usize) -> bool {
        self.free[k]
    }

    pub fn free_mask(&self) -> &[bool] {
        &self.free
    }

    pub fn free_count(&self) -> usize {
        self.free_count
    }
}

/// Distance from `p` to the segment `a–b` in the plane.
pub fn distance_to_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((p[0] - a[0] - t * dx).powi(2) + (p[1] - a[1] - t * dy).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn world(walls: &str) -> World {
        toml::from_str(&format!(
            "min = [0.0, 0.0, 0.0]\nmax = [4.0, 3.0, 2.5]\nwalls = [{walls}]"
        ))
        .unwrap()
    }

    #[test]
    fn cells_cover_the_box_and_walls_block_cells_and_edges() {
        let g = Grid::new(&world(""), 0.5).unwrap();
        assert_eq!(g.shape(), (8, 6));
        assert_eq!(g.free_count(), 48);
        assert_eq!(g.centre(0, 0), [0.25, 0.25]);
        assert_eq!(g.index_of(3.9, 2.9), Some(47));
        assert_eq!(g.index_of(4.1, 1.0), None);
        // A wall at x = 2.1 from y = 0 to 3: the cells centred at x = 2.25 are within 0.25 m.
        let g = Grid::new(
            &world("{ from = [2.1, 0.0], to = [2.1, 3.0], height = 2.5 }"),
            0.5,
        )
        .unwrap();
        assert_eq!(g.free_count(), 42);
        assert!(!g.is_free(g.index_of(2.2, 1.0).unwrap()));
        // Runs along a row stop at the wall: the left part is 0..=3 (x < 2).
        let k = g.index_of(0.3, 1.0).unwrap();
        assert_eq!(g.row_run[k], Run { lo: 0, hi: 3 });
        // A wall on a grid line blocks no cell but cuts the edges across it.
        let g = Grid::new(
            &world("{ from = [2.0, 0.0], to = [2.0, 3.0], height = 1.0 }"),
            0.5,
        )
        .unwrap();
        assert_eq!(g.free_count(), 48);
        assert_eq!(g.row_run[g.index_of(2.2, 1.0).unwrap()], Run { lo: 4, hi: 7 });
        // Columns are unaffected by a wall parallel to them.
        assert_eq!(g.col_run[g.index_of(2.2, 1.0).unwrap()], Run { lo: 0, hi: 5 });
    }

    #[test]
    fn a_box_that_is_not_a_multiple_blocks_cells_past_the_edge() {
        let mut w = world("");
        w.max[0] = 3.6;
        let g = Grid::new(&w, 0.5).unwrap();
        assert_eq!(g.shape(), (8, 6));
        // The last column's centre, x = 3.75, is outside the room; x = 3.25 is inside.
        assert!(!g.is_free(g.index_of(3.7, 1.0).unwrap()));
        assert!(g.is_free(g.index_of(3.3, 1.0).unwrap()));
        assert_eq!(g.free_count(), 42);
    }

    #[test]
    fn bad_grids_are_refused() {
        assert!(Grid::new(&world(""), 0.0).is_err());
        assert!(Grid::new(&world(""), f64::NAN).is_err());
        assert!(
            Grid::new(&world(""), 1e-4)
                .unwrap_err()
                .to_string()
                .contains("at most")
        );
    }

    #[test]
    fn distance_to_segment_hand_values() {
        assert_eq!(distance_to_segment([1.0, 1.0], [0.0, 0.0], [2.0, 0.0]), 1.0);
        assert_eq!(distance_to_segment([3.0, 0.0], [0.0, 0.0], [2.0, 0.0]), 1.0);
        assert!((distance_to_segment([0.0, 1.0], [0.0, 0.0], [1.0, 1.0]) - 0.5f64.sqrt()).abs() < 1e-12);
    }
}
