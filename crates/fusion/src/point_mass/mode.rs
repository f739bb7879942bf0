//! The mode search (a summed-area table scanned a row at a time, with hysteresis) and the
//! estimate (the mean of the dominant mode).

use wipdr_core::Vector2;
use wipdr_core::grid::checked_usize;

use super::PointMassFilter;

/// The largest of `values` (NaN ignored; `-inf` for none), in four lanes so that the
/// comparisons do not form one dependency chain (the maximum does not depend on the order).
pub(super) fn max_of(values: &[f64]) -> f64 {
    let mut lanes = [f64::NEG_INFINITY; 4];
    let chunks = values.chunks_exact(4);
    let rest = chunks.remainder();
    for chunk in chunks {
        for (lane, &v) in lanes.iter_mut().zip(chunk) {
            if v > *lane {
                *lane = v;
            }
        }
    }
    for &v in rest {
        if v > lanes[0] {
            lanes[0] = v;
        }
    }
    lanes
        .into_iter()
        .fold(f64::NEG_INFINITY, |a, v| if v > a { v } else { a })
}

impl PointMassFilter {
    /// The cell whose neighbourhood (a square of half-width `mode_radius_m`) holds the most
    /// probability, over the active window (a summed-area table). The previously chosen cell
    /// is kept while its neighbourhood holds at least `mode_hysteresis` of the best one, so
    /// the estimate does not flip between two near-equal modes.
    pub(super) fn choose_mode(&mut self) {
        let (x0, x1, y0, y1) = self.active;
        let (w, h) = (x1 - x0 + 1, y1 - y0 + 1);
        let stride = w + 1;
        let (nx, ny) = self.lattice.dims();
        let sat = &mut self.sat;
        if sat.len() < stride * (h + 1) {
            sat.resize(stride * (h + 1), 0.0);
        }
        // Row 0 and column 0 are zero; every other entry is written below.
        sat[..stride].fill(0.0);
        for r in 0..h {
            let src = &self.prob[(y0 + r) * nx + x0..][..w];
            let (done, rest) = sat.split_at_mut((r + 1) * stride);
            let above = &done[r * stride + 1..][..w];
            let (first, cur) = rest[..stride].split_at_mut(1);
            first[0] = 0.0;
            let mut row = 0.0;
            for ((s, a), v) in cur.iter_mut().zip(above).zip(src) {
                row += v;
                *s = a + row;
            }
        }
        let sat = &self.sat[..stride * (h + 1)];
        // A square wider than the lattice covers the whole window: any larger `k` gives the
        // same masses, so the half-width is capped there (no overflow in `c + k`).
        let cap = nx.max(ny);
        let k =
            checked_usize((self.cfg.mode_radius_m / self.cfg.cell_m).round(), cap).unwrap_or(cap);
        let mass = |c: usize, r: usize| {
            let (a0, a1) = (c.saturating_sub(k), (c + k).min(w - 1) + 1);
            let (b0, b1) = (r.saturating_sub(k), (r + k).min(h - 1) + 1);
            sat[b1 * stride + a1] - sat[b0 * stride + a1] - sat[b1 * stride + a0]
                + sat[b0 * stride + a0]
        };
        // Row by row, the squares' columns clipped at the window's left edge, then the
        // interior ones (a run of `2k + 1` columns), then those clipped at the right edge:
        // the same four-term sum as `mass` in the same order, without per-cell clipping.
        let left = k.min(w);
        let right = w.saturating_sub(k).max(left);
        // The first cell (row-major) of the largest mass, found a row at a time: the row's
        // masses, their maximum (in lanes, no dependency chain) and, only when it beats the
        // best so far, its first position. The same cell as comparing cell after cell.
        let mut masses = std::mem::take(&mut self.row_buffers.weights);
        masses.clear();
        masses.resize(w, 0.0);
        let mut best = (0usize, 0usize, f64::NEG_INFINITY);
        for r in 0..h {
            let (b0, b1) = (r.saturating_sub(k), (r + k).min(h - 1) + 1);
            let top = &sat[b1 * stride..][..stride];
            let bottom = &sat[b0 * stride..][..stride];
            for (c, m) in masses[..left].iter_mut().enumerate() {
                let a1 = (c + k).min(w - 1) + 1;
                *m = top[a1] - bottom[a1] - top[0] + bottom[0];
            }
            if right > left {
                // Here left = k: column c's square spans sat columns c - k and c + k + 1.
                let (far, near) = (&top[..=w], &bottom[..=w]);
                let interior = far[2 * k + 1..]
                    .iter()
                    .zip(&near[2 * k + 1..])
                    .zip(far.iter().zip(near));
                for (m, ((t1, b1), (t0, b0))) in masses[left..right].iter_mut().zip(interior) {
                    *m = t1 - b1 - t0 + b0;
                }
            }
            for (c, m) in masses.iter_mut().enumerate().skip(right) {
                let (a0, a1) = (c - k, (c + k).min(w - 1) + 1);
                *m = top[a1] - bottom[a1] - top[a0] + bottom[a0];
            }
            let row_max = max_of(&masses);
            if row_max > best.2 {
                let c = masses.iter().position(|m| *m == row_max).unwrap_or(0);
                best = (c, r, row_max);
            }
        }
        self.row_buffers.weights = masses;
        let chosen = (y0 + best.1) * nx + x0 + best.0;
        if let Some(prev) = self.mode {
            let (pc, pr) = (prev % nx, prev / nx);
            if pc >= x0 && pc <= x1 && pr >= y0 && pr <= y1 {
                let m = mass(pc - x0, pr - y0);
                if m >= self.cfg.mode_hysteresis * best.2 {
                    // Keep the previous mode.
                    return;
                }
            }
        }
        self.mode = Some(chosen);
    }

    #[cfg(test)]
    pub(super) fn mean_near(&self, centre: usize, radius: f64) -> Vector2 {
        mean_of(&self.near_cells(centre, radius), self.offset_of(centre))
    }

    /// The posterior's geometric median within `radius` of the cell `centre` (0: the whole
    /// posterior), by Weiszfeld's iteration from `start` ([`median_of`]); the estimate
    /// gathers the cells once and calls [`median_of`] itself.
    #[cfg(test)]
    pub(super) fn median_near(&self, centre: usize, radius: f64, start: Vector2) -> Vector2 {
        median_of(&self.near_cells(centre, radius), start, self.cfg.cell_m)
    }

    /// The `(offset, probability)` of every active cell of positive probability within
    /// `radius` of the cell `centre` (0: every active cell), in [`Self::for_each_near`]'s
    /// order: gathered once, so the estimate's mean and its median's rounds walk a short
    /// list instead of the lattice window again.
    pub(super) fn near_cells(&self, centre: usize, radius: f64) -> Vec<(Vector2, f64)> {
        let mut cells = Vec::new();
        self.for_each_near(centre, radius, |o, p| cells.push((o, p)));
        cells
    }

    /// Calls `f(offset, probability)` for every active cell of positive probability within
    /// `radius` of the cell `centre` (0: every active cell).
    pub(super) fn for_each_near(
        &self,
        centre: usize,
        radius: f64,
        mut f: impl FnMut(Vector2, f64),
    ) {
        let c = self.offset_of(centre);
        let h = self.cfg.cell_m;
        // The square is clipped to the active window, so a half-width beyond the lattice's
        // size (or the whole posterior, radius 0) is the lattice's size.
        let nx = self.lattice.cols();
        let cap = nx.max(self.lattice.rows());
        let k = if radius > 0.0 {
            checked_usize((radius / h).ceil(), cap).unwrap_or(cap)
        } else {
            cap
        };
        let (cc, cr) = self.lattice.col_row(centre);
        let (a0, a1, b0, b1) = self.active;
        let (x0, x1) = (cc.saturating_sub(k).max(a0), (cc + k).min(a1));
        let (y0, y1) = (cr.saturating_sub(k).max(b0), (cr + k).min(b1));
        // `offset_of(i)` without its division: the same centres, the same bits, each
        // column's x computed once.
        let xs: Vec<f64> = (x0..=x1).map(|col| self.lattice.centre_x(col)).collect();
        for r in y0..=y1 {
            let y = self.lattice.centre_y(r);
            let row = &self.prob[r * nx + x0..=r * nx + x1];
            for (&x, &p) in xs.iter().zip(row) {
                if p <= 0.0 {
                    continue;
                }
                let o = Vector2::new(x, y);
                if radius > 0.0 && (o - c).norm() > radius {
                    continue;
                }
                f(o, p);
            }
        }
    }

    /// Second moment of the whole posterior (the active window) about `centre`, m², plus a
    /// cell's own spread (`cell² / 12` per axis) and `sd_floor_m²`: the estimate's covariance,
    /// which keeps a second mode's weight as uncertainty rather than hiding it.
    pub(super) fn spread_about(&self, centre: Vector2) -> nalgebra::Matrix2<f64> {
        let nx = self.lattice.cols();
        let (x0, x1, y0, y1) = self.active;
        let (mut sxx, mut sxy, mut syy, mut w) = (0.0, 0.0, 0.0, 0.0);
        // The cell centres' offsets from `centre` (the same subtractions as
        // `offset_of(i) - centre`, without a division per cell): each column's x offset once,
        // each row's y offset once, then the cells in row-major order as before, so the sums
        // keep their bits.
        let dxs: Vec<f64> = (x0..=x1)
            .map(|col| self.lattice.centre_x(col) - centre.x)
            .collect();
        for r in y0..=y1 {
            let row = &self.prob[r * nx + x0..=r * nx + x1];
            let dy = self.lattice.centre_y(r) - centre.y;
            for (&dx, &p) in dxs.iter().zip(row) {
                if p <= 0.0 {
                    continue;
                }
                sxx += p * dx * dx;
                sxy += p * dx * dy;
                syy += p * dy * dy;
                w += p;
            }
        }
        let cell =
            self.cfg.cell_m * self.cfg.cell_m / 12.0 + self.cfg.sd_floor_m * self.cfg.sd_floor_m;
        if !(w > 0.0 && w.is_finite()) {
            return nalgebra::Matrix2::new(cell, 0.0, 0.0, cell);
        }
        nalgebra::Matrix2::new(sxx / w + cell, sxy / w, sxy / w, syy / w + cell)
    }
}

/// The probability-weighted mean of `cells`, `fallback` when they weigh nothing.
pub(super) fn mean_of(cells: &[(Vector2, f64)], fallback: Vector2) -> Vector2 {
    let (mut sum, mut w) = (Vector2::zeros(), 0.0);
    for &(o, p) in cells {
        sum += p * o;
        w += p;
    }
    if w > 0.0 { sum / w } else { fallback }
}

/// The geometric median of the weighted `cells` by Weiszfeld's iteration from `start`: the
/// point of least expected Euclidean distance, which is what the evaluation scores (the mean
/// is least in expected squared distance, and a second mode pulls it further). `cell_m`
/// scales the convergence tolerance and the distance below which a cell counts as at the
/// iterate (Weiszfeld's step is undefined at a data point).
pub(super) fn median_of(cells: &[(Vector2, f64)], start: Vector2, cell_m: f64) -> Vector2 {
    const ROUNDS: usize = 50;
    let tolerance = 1e-3 * cell_m;
    let near = 1e-2 * cell_m;
    // Each pass also prices the iterate (its expected distance); an iterate no cheaper than
    // the one before ends the search with that one, so the result is never worse than
    // `start` (the clamp can step off a cell that is itself the median).
    let (mut best, mut best_cost) = (start, f64::INFINITY);
    let mut m = start;
    let mut converged = false;
    for round in 0..=ROUNDS {
        let (mut sum, mut w, mut cost) = (Vector2::zeros(), 0.0, 0.0);
        for &(o, p) in cells {
            let d = (o - m).norm();
            cost += p * d;
            let k = p / d.max(near);
            sum += k * o;
            w += k;
        }
        if cost.is_nan() || cost >= best_cost {
            break;
        }
        (best, best_cost) = (m, cost);
        if converged || round == ROUNDS || !(w > 0.0 && w.is_finite()) {
            break;
        }
        let next = sum / w;
        converged = (next - m).norm() < tolerance;
        m = next;
    }
    best
}
