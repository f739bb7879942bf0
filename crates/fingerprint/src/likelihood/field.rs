//! One AP's signal field over a floor's raster, laid out for the per-scan pass: its cells in
//! raster order, grouped into runs of consecutive cells so that the pass adds to contiguous
//! slices of the raster (no index arithmetic or bounds check per cell, and the silence-only
//! pass vectorises).

/// One cell of an AP's field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct FieldCell {
    /// The cell's index in the floor's raster.
    pub cell: u32,
    /// ln of the heard density's Gaussian part's factor `(1 - outlier) P / (σ sqrt(2π))`.
    pub ln_scale: f32,
    /// RSS mean, dBm.
    pub mean_dbm: f32,
    /// `1 / (2 σ²)`, 1/dB².
    pub inv_two_var: f32,
    /// `ln(1 - (1 - outlier) P)`: the AP not heard here.
    pub ln_silent: f32,
}

/// A run of consecutive raster cells in an AP's field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct CellRun {
    /// The raster index of the run's first cell.
    pub cell: usize,
    /// The index of the run's first cell in the field's cell list.
    pub first: usize,
    /// The number of cells.
    pub len: usize,
}

/// An AP's field: its cells in raster order, their runs, and their `ln_silent` again as one
/// contiguous array (what a scan that heard the AP past the cap removes).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct ApField {
    cells: Vec<FieldCell>,
    runs: Vec<CellRun>,
    ln_silent: Vec<f32>,
}

impl ApField {
    /// From cells in strictly increasing raster order (the fit's order).
    pub fn new(cells: Vec<FieldCell>) -> Self {
        debug_assert!(cells.windows(2).all(|w| w[0].cell < w[1].cell));
        let mut runs: Vec<CellRun> = Vec::new();
        for (i, c) in cells.iter().enumerate() {
            let cell = c.cell as usize;
            match runs.last_mut() {
                Some(r) if r.cell + r.len == cell => r.len += 1,
                _ => runs.push(CellRun {
                    cell,
                    first: i,
                    len: 1,
                }),
            }
        }
        let ln_silent = cells.iter().map(|c| c.ln_silent).collect();
        Self {
            cells,
            runs,
            ln_silent,
        }
    }

    /// The cell at raster index `cell`, if the field holds it.
    pub fn find(&self, cell: u32) -> Option<&FieldCell> {
        self.cells
            .binary_search_by_key(&cell, |c| c.cell)
            .ok()
            .map(|j| &self.cells[j])
    }

    /// Adds `term(cell, its ln_heard_outside)` to each of the field's cells of `raster`, run by
    /// run. Runs past the raster's end are skipped (a field always fits its floor's raster).
    pub fn add_heard(
        &self,
        raster: &mut [f64],
        ln_heard_outside: &[f32],
        term: impl Fn(&FieldCell, f32) -> f64,
    ) {
        for r in &self.runs {
            let span = r.cell..r.cell + r.len;
            if let (Some(dst), Some(outside), Some(src)) = (
                raster.get_mut(span.clone()),
                ln_heard_outside.get(span),
                self.cells.get(r.first..r.first + r.len),
            ) {
                for ((v, h), c) in dst.iter_mut().zip(outside).zip(src) {
                    *v += term(c, *h);
                }
            }
        }
    }

    /// Subtracts each cell's `ln_silent` from `raster` (a scan heard the AP, unscored).
    pub fn remove_silence(&self, raster: &mut [f64]) {
        for r in &self.runs {
            if let (Some(dst), Some(src)) = (
                raster.get_mut(r.cell..r.cell + r.len),
                self.ln_silent.get(r.first..r.first + r.len),
            ) {
                for (v, s) in dst.iter_mut().zip(src) {
                    *v -= f64::from(*s);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(cell: u32, ln_silent: f32) -> FieldCell {
        FieldCell {
            cell,
            ln_scale: 0.0,
            mean_dbm: -60.0,
            inv_two_var: 0.1,
            ln_silent,
        }
    }

    #[test]
    fn runs_group_consecutive_cells_and_cover_each_cell_once() {
        let f = ApField::new(vec![
            cell(2, -1.0),
            cell(3, -2.0),
            cell(4, -3.0),
            cell(7, -4.0),
            cell(9, -5.0),
            cell(10, -6.0),
        ]);
        assert_eq!(f.runs.len(), 3);
        let mut raster = vec![0.0f64; 12];
        f.remove_silence(&mut raster);
        assert_eq!(
            raster,
            vec![0.0, 0.0, 1.0, 2.0, 3.0, 0.0, 0.0, 4.0, 0.0, 5.0, 6.0, 0.0]
        );
        let mut seen = vec![0.0f64; 12];
        let outside: Vec<f32> = (0..12).map(|i| i as f32).collect();
        f.add_heard(&mut seen, &outside, |c, h| {
            f64::from(h) - f64::from(c.ln_silent)
        });
        assert_eq!(
            seen,
            vec![
                0.0, 0.0, 3.0, 5.0, 7.0, 0.0, 0.0, 11.0, 0.0, 14.0, 16.0, 0.0
            ]
        );
        assert_eq!(f.find(7).map(|c| c.ln_silent), Some(-4.0));
        assert!(f.find(8).is_none());
    }

    #[test]
    fn a_run_past_the_raster_is_skipped_not_a_panic() {
        let f = ApField::new(vec![cell(2, -1.0), cell(3, -2.0)]);
        let mut raster = vec![0.0f64; 3];
        f.remove_silence(&mut raster);
        assert_eq!(raster, vec![0.0, 0.0, 0.0]);
    }
}
