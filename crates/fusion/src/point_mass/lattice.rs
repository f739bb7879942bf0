//! The lattice of placement hypotheses: laying it, normalising it with the recovery floor
//! and the active window, growing and blurring it, weighing it a row at a time.

use wipdr_core::{Point2, Vector2};

use super::{GapRaster, MAX_CELLS, PointMassFilter, grid_error};
use crate::FusionError;
use wipdr_core::GridSpec;

impl PointMassFilter {
    /// Lays a uniform lattice over `[lo, hi]` plus the margin.
    pub(super) fn lay_lattice(&mut self, lo: Point2, hi: Point2) -> Result<(), FusionError> {
        let m = self.cfg.margin_m;
        let h = self.cfg.cell_m;
        let lo = lo - Vector2::new(m, m);
        let hi = hi + Vector2::new(m, m);
        // Hostile bounds (non-finite, 1e20 apart) are a typed error here, not a panic.
        let positions = GridSpec::covering(lo, hi, h, MAX_CELLS)
            .map_err(grid_error("cell_m", "no lattice over these bounds"))?;
        // Offsets are relative to the PDR origin at lay time: the lattice holds positions
        // `o + D`, so shift by the displacement so far.
        let lattice = positions
            .translated(-self.pdr)
            .map_err(grid_error("cell_m", "no lattice at this PDR displacement"))?;
        self.lattice = lattice;
        let n = lattice.len();
        self.prob = vec![1.0 / n as f64; n];
        self.scratch = vec![0.0; n];
        self.floor = self.cfg.recovery / n as f64;
        self.bg = 1.0 / n as f64;
        self.active = (0, lattice.cols() - 1, 0, lattice.rows() - 1);
        self.initialised = true;
        if let Some(cov) = self.coverage.clone()
            && self.cfg.gap_distance_m > 0.0
        {
            let (plo, phi) = (lo, hi);
            self.gap = GapRaster::new(&cov, h, self.cfg.gap_distance_m, (plo, phi));
        }
        Ok(())
    }

    pub(super) fn collapse_at(&mut self, p: Point2) {
        let o = Point2::from(p.coords - self.pdr);
        let n = self.prob.len();
        self.prob.iter_mut().for_each(|v| *v = 0.0);
        self.bg = 0.0;
        let (cols, rows) = self.lattice.dims();
        self.active = (0, cols - 1, 0, rows - 1);
        if let Some(i) = self.lattice.index_of(o) {
            self.prob[i] = 1.0;
        } else {
            self.prob.iter_mut().for_each(|v| *v = 1.0 / n as f64);
            self.bg = 1.0 / n as f64;
        }
        self.normalise(None);
        self.choose_mode();
    }

    pub(super) fn offset_of(&self, i: usize) -> Vector2 {
        self.lattice.centre_of_index(i).coords
    }

    /// The represented total: the background cells plus the active window (rows summed in
    /// order, so that every caller gets the same bits for the same distribution).
    pub(super) fn active_total(&self) -> f64 {
        let (x0, x1, y0, y1) = self.active;
        let (w, nx) = (x1 - x0 + 1, self.lattice.cols());
        let n_active = (w * (y1 - y0 + 1)) as f64;
        let mut total = self.bg * (self.prob.len() as f64 - n_active);
        for r in y0..=y1 {
            total += self.prob[r * nx + x0..][..w].iter().sum::<f64>();
        }
        total
    }

    /// Normalises, applies the recovery floor and recomputes the active window. Cells outside
    /// the window all hold the background probability `bg` (implicitly: their array values
    /// are rewritten when the window grows over them). `sum` is the represented total when
    /// the caller has it ([`Self::weigh`] returns it), else it is summed here. Two passes
    /// over the window (normalise + floor + the second sum; renormalise + the new window),
    /// and one more over the new window when it changed.
    pub(super) fn normalise(&mut self, sum: Option<f64>) {
        let (x0, x1, y0, y1) = self.active;
        let (nx, w) = (self.lattice.cols(), x1 - x0 + 1);
        let n = self.prob.len() as f64;
        let n_active = (w * (y1 - y0 + 1)) as f64;
        let sum = sum.unwrap_or_else(|| self.active_total());
        if sum.is_finite() && sum > 0.0 {
            self.log_evidence += sum.ln();
        }
        let floor = self.floor;
        // Whether some cell is clearly above the floor (the maximum compared with 1.5 floor,
        // without the maximum's dependency chain).
        let limit = floor * 1.5;
        let mut above = false;
        let mut sum2 = 0.0;
        if sum.is_finite() && sum > 0.0 {
            // Background cells exist only outside a partial window.
            self.bg = if n_active < n {
                (self.bg / sum).max(floor)
            } else {
                floor
            };
            // The total after the floor, summed as `active_total` does.
            sum2 = self.bg * (n - n_active);
            for r in y0..=y1 {
                let mut row_sum = 0.0;
                for v in &mut self.prob[r * nx + x0..][..w] {
                    // `(v / sum).max(floor)` (a NaN quotient also gives the floor).
                    let q = *v / sum;
                    *v = if q > floor { q } else { floor };
                    above |= *v > limit;
                    row_sum += *v;
                }
                sum2 += row_sum;
            }
        }
        if !above {
            // Every explicit hypothesis is at the floor: spread uniformly again (recovery).
            tracing::debug!("pmf: every hypothesis vanished; back to uniform");
            self.prob.iter_mut().for_each(|v| *v = 1.0 / n);
            self.bg = 1.0 / n;
            self.active = (0, nx - 1, 0, self.lattice.rows() - 1);
            return;
        }
        // Re-normalise after the floor, shrink the window to the cells above it.
        if n_active < n {
            self.bg /= sum2;
        }
        let threshold = self.bg * 1.5;
        let (mut a0, mut a1, mut b0, mut b1) = (usize::MAX, 0, usize::MAX, 0);
        for r in y0..=y1 {
            let row = &mut self.prob[r * nx + x0..][..w];
            for v in row.iter_mut() {
                *v /= sum2;
            }
            if let Some(first) = row.iter().position(|v| *v > threshold) {
                let last = row.iter().rposition(|v| *v > threshold).unwrap_or(first);
                a0 = a0.min(x0 + first);
                a1 = a1.max(x0 + last);
                b0 = b0.min(r);
                b1 = b1.max(r);
            }
        }
        if a0 != usize::MAX && (a0, a1, b0, b1) != self.active {
            // Cells dropped from the window now count as background: renormalise so that
            // the represented distribution sums to one exactly.
            self.active = (a0, a1, b0, b1);
            let total = self.active_total();
            self.bg /= total;
            for r in b0..=b1 {
                for v in &mut self.prob[r * nx + a0..=r * nx + a1] {
                    *v /= total;
                }
            }
        }
    }

    /// Grows the active window by one cell on each side, filling new cells with `bg`.
    pub(super) fn grow(&mut self) {
        let (x0, x1, y0, y1) = self.active;
        let (nx, ny) = self.lattice.dims();
        let (a0, a1) = (x0.saturating_sub(1), (x1 + 1).min(nx - 1));
        let (b0, b1) = (y0.saturating_sub(1), (y1 + 1).min(ny - 1));
        for r in b0..=b1 {
            for c in a0..=a1 {
                if r < y0 || r > y1 || c < x0 || c > x1 {
                    self.prob[r * nx + c] = self.bg;
                }
            }
        }
        self.active = (a0, a1, b0, b1);
    }

    /// Multiplies every active cell by a weight of its position `o + D`, and the background
    /// by `background_weight`, and returns the
    /// represented total afterwards (summed as [`Self::active_total`] does, for
    /// [`Self::normalise`]). The positions of one window row share their y and those of one
    /// column their x, so the weights are filled a row at a time:
    /// `row_weights(y, xs, columns, weights)` gets the row's y, the x of every column, each
    /// x's raster column `column_of(x)` (looked up once per input, not once per cell) and
    /// fills `weights`.
    pub(super) fn weigh(
        &mut self,
        background_weight: f64,
        column_of: impl Fn(f64) -> usize,
        mut row_weights: impl FnMut(f64, &[f64], &[usize], &mut [f64]),
    ) -> f64 {
        let (x0, x1, y0, y1) = self.active;
        let (lattice, w) = (self.lattice, x1 - x0 + 1);
        let nx = lattice.cols();
        let mut buf = std::mem::take(&mut self.row_buffers);
        // The same arithmetic as `offset_of(i) + pdr`, so the positions keep their bits.
        buf.xs.clear();
        buf.xs
            .extend((x0..=x1).map(|c| lattice.centre_x(c) + self.pdr.x));
        buf.columns.clear();
        buf.columns.extend(buf.xs.iter().map(|&x| column_of(x)));
        buf.weights.clear();
        buf.weights.resize(w, 0.0);
        let n_active = (w * (y1 - y0 + 1)) as f64;
        // The background cells (outside the window) are weighed alike, by the input's weight
        // of a hypothesis far from where the window is (not by 1, which would let them gain
        // on the window at every input until they held most of the mass).
        self.bg *= background_weight;
        let mut total = self.bg * (self.prob.len() as f64 - n_active);
        for r in y0..=y1 {
            let y = lattice.centre_y(r) + self.pdr.y;
            row_weights(y, &buf.xs, &buf.columns, &mut buf.weights);
            let mut row_sum = 0.0;
            for (v, weight) in self.prob[r * nx + x0..][..w].iter_mut().zip(&buf.weights) {
                *v *= weight;
                row_sum += *v;
            }
            total += row_sum;
        }
        self.row_buffers = buf;
        total
    }

    /// Binomial blur `[1 2 1] / 4` in x then y over the active window grown by a cell
    /// (cells beyond the window count as background).
    pub(super) fn blur(&mut self) {
        self.grow();
        let (x0, x1, y0, y1) = self.active;
        let (nx, w, bg) = (self.lattice.cols(), x1 - x0 + 1, self.bg);
        let mut buf = std::mem::take(&mut self.row_buffers);
        // A row padded with the background on both sides.
        let padded = &mut buf.weights;
        padded.clear();
        padded.resize(w + 2, bg);
        for r in y0..=y1 {
            let i = r * nx + x0;
            padded[1..=w].copy_from_slice(&self.prob[i..i + w]);
            for (s, t) in self.scratch[i..i + w].iter_mut().zip(padded.windows(3)) {
                *s = 0.25 * t[0] + 0.5 * t[1] + 0.25 * t[2];
            }
        }
        let background_row = &mut buf.xs;
        background_row.clear();
        background_row.resize(w, bg);
        for r in y0..=y1 {
            let i = r * nx + x0;
            let s = &self.scratch;
            let down = if r > y0 {
                &s[i - nx..i - nx + w]
            } else {
                &background_row[..]
            };
            let up = if r < y1 {
                &s[i + nx..i + nx + w]
            } else {
                &background_row[..]
            };
            let cells = self.prob[i..i + w].iter_mut().zip(&s[i..i + w]);
            for (((p, mid), d), u) in cells.zip(down).zip(up) {
                *p = 0.25 * d + 0.5 * mid + 0.25 * u;
            }
        }
        self.row_buffers = buf;
    }
}
