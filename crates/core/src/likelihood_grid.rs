//! A Wi-Fi scan's likelihood over a floor, as fusion consumes it: a raster of values relative
//! to the most likely cell, and one value for the places the radio map does not know.

use crate::{GridSpec, Point2};

/// A scan's likelihood over one floor's raster, relative to its most likely cell (1 there),
/// for filters that weigh positions by it (`pmf`, the particle filters): what
/// `wipdr_fingerprint::likelihood::ScanLikelihood` makes of a scan, in the form fusion reads
/// without depending on the fingerprint crate.
///
/// A cell the radio map does not reach (no reference point near it) has no value of its own:
/// it reads the mean relative likelihood of the known cells within `reach_m` of it (a scan
/// taken in a coverage gap resembles the scans of the covered places around the gap, so an
/// unknown place near where the scan fits is likely and one far from it is not), or, with no
/// known cell in reach and off the raster, [`WifiLikelihood::unknown`], the mean over all
/// known cells (the likelihood of the scan at a place one knows nothing about is its average
/// over the places one does know).
///
/// ```
/// use wipdr_core::{GridSpec, Point2, WifiLikelihood};
/// let grid = GridSpec::new(Point2::new(0.0, 0.0), 2.0, 3, 1, 100).unwrap();
/// let l = WifiLikelihood::from_log(grid, &[Some(-1.0), Some(0.0), None], 0.0).unwrap();
/// assert_eq!(l.at(Point2::new(3.0, 1.0)), 1.0); // the best cell
/// assert!((l.at(Point2::new(1.0, 1.0)) - (-1.0f64).exp()).abs() < 1e-6);
/// assert_eq!(l.at(Point2::new(5.0, 1.0)), l.unknown()); // a cell without coverage
/// assert_eq!(l.at(Point2::new(50.0, 1.0)), l.unknown()); // off the raster
/// // With a reach, a cell without coverage reads its known neighbours' mean.
/// let l = WifiLikelihood::from_log(grid, &[Some(-1.0), Some(0.0), None], 2.0).unwrap();
/// assert_eq!(l.at(Point2::new(5.0, 1.0)), 1.0);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct WifiLikelihood {
    grid: GridSpec,
    /// Per cell (row-major): the likelihood relative to the best cell, in `[0, 1]`; negative
    /// for a cell without coverage.
    relative: Vec<f32>,
    unknown: f64,
}

impl WifiLikelihood {
    /// From a raster's log-likelihoods (`None`: no coverage); a cell without coverage reads
    /// the mean of the known cells within `reach_m` (a square of that half-width; 0: none,
    /// every such cell reads [`WifiLikelihood::unknown`]). `None` when no cell has a finite
    /// value or the lengths differ. Costs two passes over the raster.
    pub fn from_log(grid: GridSpec, log_likelihood: &[Option<f64>], reach_m: f64) -> Option<Self> {
        if log_likelihood.len() != grid.len() {
            return None;
        }
        let max = log_likelihood
            .iter()
            .flatten()
            .copied()
            .filter(|v| v.is_finite())
            .fold(f64::NEG_INFINITY, f64::max);
        if !max.is_finite() {
            return None;
        }
        let (mut sum, mut known) = (0.0, 0usize);
        let mut relative: Vec<f32> = log_likelihood
            .iter()
            .map(|v| match v {
                Some(v) if v.is_finite() => {
                    let r = (v - max).exp();
                    sum += r;
                    known += 1;
                    r as f32
                }
                _ => -1.0,
            })
            .collect();
        // known >= 1: the maximum is some cell's value.
        let unknown = sum / known as f64;
        fill_from_neighbours(&grid, &mut relative, reach_m);
        Some(Self {
            grid,
            relative,
            unknown,
        })
    }

    /// The raster.
    pub fn grid(&self) -> &GridSpec {
        &self.grid
    }

    /// The value of a place the radio map does not know (off the raster, or a cell without
    /// coverage): the mean relative likelihood over the known cells, in `(0, 1]`.
    pub fn unknown(&self) -> f64 {
        self.unknown
    }

    /// The relative likelihood at `p` (its cell's), in `[0, 1]`.
    pub fn at(&self, p: Point2) -> f64 {
        self.grid
            .index_of(p)
            .map_or(self.unknown, |i| self.cell_value(i))
    }

    /// The relative likelihood of cell `(col, row)` of [`Self::grid`]; `unknown` for a cell
    /// without coverage. `col` or `row` out of range reads `unknown` too.
    pub fn at_cell(&self, col: usize, row: usize) -> f64 {
        if col >= self.grid.cols() || row >= self.grid.rows() {
            return self.unknown;
        }
        self.cell_value(self.grid.index(col, row))
    }

    fn cell_value(&self, i: usize) -> f64 {
        let v = self.relative[i];
        if v >= 0.0 { f64::from(v) } else { self.unknown }
    }

    /// Where `p` falls in the likelihood: the number of raster cells more likely than `p`'s
    /// value (its rank, 0 for the best), and whether the smallest set of most likely cells
    /// holding `mass` of the raster's total holds `p` (its value is at least the least value
    /// in that set). The calibration of a scan's likelihood against the truth.
    ///
    /// ```
    /// use wipdr_core::{GridSpec, Point2, WifiLikelihood};
    /// let grid = GridSpec::new(Point2::new(0.0, 0.0), 1.0, 4, 1, 100).unwrap();
    /// let ln = |v: f64| Some(v.ln());
    /// let l = WifiLikelihood::from_log(grid, &[ln(1.0), ln(0.5), ln(0.3), ln(0.2)], 0.0).unwrap();
    /// assert_eq!(l.rank_and_region(Point2::new(1.5, 0.5), 0.6), (1, true)); // 1 + 0.5 >= 0.6 x 2
    /// assert_eq!(l.rank_and_region(Point2::new(2.5, 0.5), 0.6), (2, false));
    /// ```
    pub fn rank_and_region(&self, p: Point2, mass: f64) -> (usize, bool) {
        let v = self.at(p);
        let values: Vec<f64> = (0..self.relative.len())
            .map(|i| self.cell_value(i))
            .collect();
        let rank = values.iter().filter(|&&q| q > v).count();
        let total: f64 = values.iter().sum();
        let mut sorted = values;
        sorted.sort_by(|a, b| b.total_cmp(a));
        let (mut acc, mut least) = (0.0, 0.0);
        for q in sorted {
            acc += q;
            least = q;
            if acc >= mass * total {
                break;
            }
        }
        (rank, v >= least)
    }

    /// Bytes held (the raster's values).
    pub fn heap_bytes(&self) -> usize {
        self.relative.len() * std::mem::size_of::<f32>()
    }
}

/// Gives each cell without a value (negative) the mean of the valued cells in the square of
/// half-width `reach_m` about it, from summed-area tables of the values and of their count;
/// cells with none in reach stay negative.
fn fill_from_neighbours(grid: &GridSpec, relative: &mut [f32], reach_m: f64) {
    let Some(k) = crate::grid::checked_usize((reach_m / grid.cell_m()).floor(), 1 << 20) else {
        return;
    };
    if k == 0 || !relative.iter().any(|v| *v < 0.0) {
        return;
    }
    let (cols, rows) = grid.dims();
    let stride = cols + 1;
    let mut sum = vec![0.0f64; stride * (rows + 1)];
    let mut count = vec![0u32; stride * (rows + 1)];
    for r in 0..rows {
        let (mut row_sum, mut row_count) = (0.0, 0u32);
        for c in 0..cols {
            let v = relative[r * cols + c];
            if v >= 0.0 {
                row_sum += f64::from(v);
                row_count += 1;
            }
            let i = (r + 1) * stride + c + 1;
            sum[i] = sum[i - stride] + row_sum;
            count[i] = count[i - stride] + row_count;
        }
    }
    let square = |t: &dyn Fn(usize) -> f64, c: usize, r: usize| {
        let (c0, c1) = (c.saturating_sub(k), (c + k + 1).min(cols));
        let (r0, r1) = (r.saturating_sub(k), (r + k + 1).min(rows));
        t(r1 * stride + c1) - t(r0 * stride + c1) - t(r1 * stride + c0) + t(r0 * stride + c0)
    };
    for r in 0..rows {
        for c in 0..cols {
            let i = r * cols + c;
            if relative[i] >= 0.0 {
                continue;
            }
            let n = square(&|j| f64::from(count[j]), c, r);
            if n > 0.0 {
                let mean = square(&|j| sum[j], c, r) / n;
                relative[i] = -1.0 - mean.clamp(0.0, 1.0) as f32;
            }
        }
    }
    // Filled cells were marked below -1 so that they did not count as known while filling.
    for v in relative.iter_mut() {
        if *v < -1.0 {
            *v = -1.0 - *v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_finite_value_or_a_length_mismatch_gives_none() {
        let grid = GridSpec::new(Point2::origin(), 1.0, 2, 1, 10).unwrap();
        assert!(WifiLikelihood::from_log(grid, &[None, None], 0.0).is_none());
        assert!(WifiLikelihood::from_log(grid, &[Some(f64::NAN), None], 0.0).is_none());
        assert!(WifiLikelihood::from_log(grid, &[Some(0.0)], 0.0).is_none());
    }

    #[test]
    fn unknown_is_the_mean_of_the_known_cells() {
        let grid = GridSpec::new(Point2::origin(), 1.0, 4, 1, 10).unwrap();
        let l = WifiLikelihood::from_log(grid, &[Some(0.0), Some(-(2f64.ln())), None, None], 0.0)
            .unwrap();
        assert!((l.unknown() - 0.75).abs() < 1e-9);
        assert_eq!(l.at_cell(2, 0), l.unknown());
        assert_eq!(l.at_cell(9, 0), l.unknown());
        assert!((l.at_cell(1, 0) - 0.5).abs() < 1e-7);
    }

    #[test]
    fn a_cell_without_coverage_reads_the_mean_of_its_known_neighbours_in_reach() {
        // 5 x 1: known 1, 0.5 at columns 0 and 1; column 2 reaches both (reach 2 cells),
        // column 3 only column 1, column 4 none.
        let grid = GridSpec::new(Point2::origin(), 1.0, 5, 1, 10).unwrap();
        let half = -(2f64.ln());
        let l = WifiLikelihood::from_log(grid, &[Some(0.0), Some(half), None, None, None], 2.0)
            .unwrap();
        assert!((l.at_cell(2, 0) - 0.75).abs() < 1e-6);
        assert!((l.at_cell(3, 0) - 0.5).abs() < 1e-6);
        assert_eq!(l.at_cell(4, 0), l.unknown());
    }

    proptest::proptest! {
        #[test]
        fn values_stay_in_zero_one(values in proptest::collection::vec(
            proptest::option::of(-1e6f64..1e6), 1..40), reach in 0.0f64..10.0) {
            let grid = GridSpec::new(Point2::origin(), 1.0, values.len(), 1, 100).unwrap();
            if let Some(l) = WifiLikelihood::from_log(grid, &values, reach) {
                proptest::prop_assert!(l.unknown() > 0.0 && l.unknown() <= 1.0);
                for c in 0..values.len() {
                    let v = l.at_cell(c, 0);
                    proptest::prop_assert!((0.0..=1.0).contains(&v));
                }
            }
        }
    }
}
