//! Coverage gaps of the radio map: which positions are far from every reference point.

use std::collections::VecDeque;

use wipdr_core::{GridSpec, Point2};

use super::MAX_CELLS;

/// Whether each position cell (square cells of the lattice's size over the lattice's
/// position extent) is farther than the gap distance from every reference point.
#[derive(Debug, Clone)]
pub(super) struct GapRaster {
    /// The raster's cells.
    pub(super) grid: GridSpec,
    /// Per cell (row-major): in a gap.
    pub(super) gap: Vec<bool>,
    /// Per cell (row-major): the distance from the cell's centre to the nearest reference
    /// point, metres, where the search reached (up to the gap distance plus two cells);
    /// infinite beyond.
    pub(super) distance: Vec<f32>,
}

impl GapRaster {
    /// Cells farther than `distance` from every point (BFS over the 8-neighbourhood with
    /// nearest-seed propagation), over `extent` (one cell more on the far sides). `None`
    /// without points or when the extent gives no raster (non-finite, over [`MAX_CELLS`]).
    pub(super) fn new(
        points: &[Point2],
        cell_m: f64,
        distance: f64,
        extent: (Point2, Point2),
    ) -> Option<Self> {
        let (lo, hi) = extent;
        let grid = match GridSpec::covering_inclusive(lo, hi, cell_m, MAX_CELLS) {
            Ok(g) => g,
            Err(e) => {
                tracing::warn!(error = %e, "pmf: no coverage-gap raster");
                return None;
            }
        };
        if points.is_empty() {
            return None;
        }
        let mut seed = vec![u32::MAX; grid.len()];
        let mut queue = VecDeque::new();
        let seeds: Vec<Point2> = points.to_vec();
        for (k, p) in seeds.iter().enumerate() {
            let Ok(k) = u32::try_from(k) else {
                tracing::warn!("pmf: more than u32::MAX reference points; the rest ignored");
                break;
            };
            if let Some(i) = grid.index_of(*p)
                && seed[i] == u32::MAX
            {
                seed[i] = k;
                queue.push_back(i);
            }
        }
        let centre = |i: usize| grid.centre_of_index(i);
        while let Some(i) = queue.pop_front() {
            let s = seeds[seed[i] as usize];
            let (col, row) = grid.col_row(i);
            for (c, r) in grid.neighbours8(col, row) {
                let j = grid.index(c, r);
                if seed[j] == seed[i] {
                    // The same seed: not nearer (and already queued).
                    continue;
                }
                let cj = centre(j);
                let d2 = (cj - s).norm_squared();
                // Nearer by more than 1e-12 m; the squared distances (no square root)
                // settle the common case of not nearer at all, since the root is monotone.
                let better = seed[j] == u32::MAX || {
                    let other2 = (cj - seeds[seed[j] as usize]).norm_squared();
                    d2 < other2 && d2.sqrt() < other2.sqrt() - 1e-12
                };
                if better && d2.sqrt() <= distance + 2.0 * cell_m {
                    seed[j] = seed[i];
                    queue.push_back(j);
                }
            }
        }
        // The gap test on the f64 distance (as before the distances were kept); the kept
        // distance is f32 (the radius term needs no more).
        let (gap, nearest): (Vec<bool>, Vec<f32>) = (0..grid.len())
            .map(|i| {
                let d = if seed[i] == u32::MAX {
                    f64::INFINITY
                } else {
                    (centre(i) - seeds[seed[i] as usize]).norm()
                };
                (d > distance, d as f32)
            })
            .unzip();
        Some(Self {
            grid,
            gap,
            distance: nearest,
        })
    }

    /// The distance from `p`'s cell to the nearest reference point, metres, capped at `cap`
    /// (and `cap` outside the raster or beyond the search).
    pub(super) fn distance_at(&self, p: Point2, cap: f64) -> f64 {
        self.grid.cell_of(p).map_or(cap, |(c, r)| {
            f64::from(self.distance[self.grid.index(c, r)]).min(cap)
        })
    }

    /// Whether `p` is in a gap (everything outside the raster is). The filter looks rows and
    /// columns up separately (`on_wifi`); this is the per-point form the tests check.
    #[cfg(test)]
    pub(super) fn is_gap(&self, p: Point2) -> bool {
        self.grid
            .cell_of(p)
            .is_none_or(|(c, r)| self.gap[self.grid.index(c, r)])
    }
}
