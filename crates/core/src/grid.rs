//! Square raster geometry: which cell a point falls in, a cell's centre, a cell's index.
//!
//! Every raster of wipdr (the walkable space of a floor plan, the distance to the training
//! trails, `pmf`'s lattice of placement hypotheses and its coverage gaps) is a [`GridSpec`]:
//! `cols x rows` square cells of side `cell_m` metres whose cell `(0, 0)` has its lower-left
//! corner at `origin`. Column `c` spans `[origin.x + c cell_m, origin.x + (c + 1) cell_m)`;
//! a point's column is `floor((x - origin.x) / cell_m)`, its row likewise in `y`, and the cells
//! are stored row-major (`index = row * cols + col`).
//!
//! A grid is only built through checked constructors: the cell size must be finite and
//! positive, the bounds finite, and the cell count at most a limit the caller names, so a
//! hostile coordinate (a waypoint at `1e20`, `1e308`, NaN) gives a [`GridError`] instead of a
//! wrapped `usize` and an out-of-bounds index. Float-to-index conversions go through
//! [`checked_usize`] (NaN, infinities, negatives and values over a limit are rejected), so no
//! lookup can panic, whatever the `f64` input.
//!
//! ```
//! use wipdr_core::{Point2, grid::GridSpec};
//! let g = GridSpec::covering(Point2::new(0.0, 0.0), Point2::new(10.0, 4.0), 0.5, 1 << 20).unwrap();
//! assert_eq!((g.cols(), g.rows()), (20, 8));
//! let (c, r) = g.cell_of(Point2::new(2.3, 1.1)).unwrap();
//! assert_eq!((c, r), (4, 2));
//! assert_eq!(g.centre(c, r), Point2::new(2.25, 1.25));
//! assert_eq!(g.cell_of(Point2::new(f64::NAN, 1.0)), None);
//! assert!(GridSpec::covering(Point2::new(0.0, 0.0), Point2::new(1e20, 1.0), 0.5, 1 << 20).is_err());
//! ```

use std::ops::Range;

use crate::{Point2, Vector2};

/// Why a [`GridSpec`] cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    /// The cell size is not finite or not positive.
    #[error("grid cell size must be finite and > 0, got {0}")]
    InvalidCell(f64),
    /// A bound (or the grid's far corner) is NaN or infinite.
    #[error("grid bounds must be finite, got {lo:?} .. {hi:?}")]
    NonFiniteBounds {
        /// Lower-left corner asked for.
        lo: [f64; 2],
        /// Upper-right corner asked for (or reached).
        hi: [f64; 2],
    },
    /// The upper bound lies below the lower one.
    #[error("grid bounds are inverted: {lo:?} .. {hi:?}")]
    InvertedBounds {
        /// Lower-left corner asked for.
        lo: [f64; 2],
        /// Upper-right corner asked for.
        hi: [f64; 2],
    },
    /// The grid would have more cells than the caller's limit.
    #[error("a {cols} x {rows} grid is larger than the limit of {limit} cells")]
    TooManyCells {
        /// Columns asked for (a float, since it may not fit an index).
        cols: f64,
        /// Rows asked for.
        rows: f64,
        /// The limit.
        limit: usize,
    },
    /// A grid with no column or no row.
    #[error("a grid needs at least one column and one row, got {cols} x {rows}")]
    Empty {
        /// Columns asked for.
        cols: usize,
        /// Rows asked for.
        rows: usize,
    },
}

/// `v` as an index when it is a whole or fractional number in `[0, limit]` (truncated towards
/// zero), `None` for NaN, infinities, negatives and values over `limit`: the checked form of
/// `v as usize`.
///
/// ```
/// use wipdr_core::grid::checked_usize;
/// assert_eq!(checked_usize(3.7, 10), Some(3));
/// for v in [f64::NAN, f64::INFINITY, -1.0, 11.0, 1e20] {
///     assert_eq!(checked_usize(v, 10), None);
/// }
/// ```
pub fn checked_usize(v: f64, limit: usize) -> Option<usize> {
    // `limit as f64` rounds up for limits beyond 2^53; the final comparison is exact.
    if v.is_finite() && v >= 0.0 && v <= limit as f64 {
        let i = v as usize;
        (i <= limit).then_some(i)
    } else {
        None
    }
}

/// `v` as an `i64` when it is finite and within `±2^62` (truncated towards zero), `None`
/// otherwise: the checked form of `v as i64` for cell keys of unbounded grids.
///
/// ```
/// use wipdr_core::grid::checked_i64;
/// assert_eq!(checked_i64(-3.0), Some(-3));
/// assert_eq!(checked_i64(1e20), None);
/// assert_eq!(checked_i64(f64::NAN), None);
/// ```
pub fn checked_i64(v: f64) -> Option<i64> {
    const BOUND: f64 = (1u64 << 62) as f64;
    if v.is_finite() && v.abs() <= BOUND {
        Some(v as i64)
    } else {
        None
    }
}

/// Geometry of a square raster; see the [module docs](self).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridSpec {
    origin: Point2,
    cell_m: f64,
    cols: usize,
    rows: usize,
}

fn corners(lo: Point2, hi: Point2) -> ([f64; 2], [f64; 2]) {
    ([lo.x, lo.y], [hi.x, hi.y])
}

fn check_cell(cell_m: f64) -> Result<(), GridError> {
    if cell_m.is_finite() && cell_m > 0.0 {
        Ok(())
    } else {
        Err(GridError::InvalidCell(cell_m))
    }
}

impl GridSpec {
    /// A grid of `cols x rows` cells of `cell_m` metres whose lower-left corner is `origin`.
    /// Errors on a bad cell size, a non-finite origin or far corner, no cell, or more than
    /// `max_cells` cells.
    pub fn new(
        origin: Point2,
        cell_m: f64,
        cols: usize,
        rows: usize,
        max_cells: usize,
    ) -> Result<Self, GridError> {
        check_cell(cell_m)?;
        if cols == 0 || rows == 0 {
            return Err(GridError::Empty { cols, rows });
        }
        if cols.checked_mul(rows).is_none_or(|n| n > max_cells) {
            return Err(GridError::TooManyCells {
                cols: cols as f64,
                rows: rows as f64,
                limit: max_cells,
            });
        }
        let g = Self {
            origin,
            cell_m,
            cols,
            rows,
        };
        let far = g.far_corner();
        if !(origin.x.is_finite() && origin.y.is_finite() && far.x.is_finite() && far.y.is_finite())
        {
            let (lo, hi) = corners(origin, far);
            return Err(GridError::NonFiniteBounds { lo, hi });
        }
        Ok(g)
    }

    /// The grid from `lo` covering `[lo, hi)`: `ceil((hi - lo) / cell_m)` cells along each
    /// axis, at least one.
    pub fn covering(
        lo: Point2,
        hi: Point2,
        cell_m: f64,
        max_cells: usize,
    ) -> Result<Self, GridError> {
        Self::spanning(lo, hi, cell_m, max_cells, |n| n.max(1.0))
    }

    /// The grid from `lo` with one cell more along each axis than [`GridSpec::covering`]
    /// (`ceil((hi - lo) / cell_m) + 1`), so that `hi` itself always falls inside.
    pub fn covering_inclusive(
        lo: Point2,
        hi: Point2,
        cell_m: f64,
        max_cells: usize,
    ) -> Result<Self, GridError> {
        Self::spanning(lo, hi, cell_m, max_cells, |n| n + 1.0)
    }

    fn spanning(
        lo: Point2,
        hi: Point2,
        cell_m: f64,
        max_cells: usize,
        count: impl Fn(f64) -> f64,
    ) -> Result<Self, GridError> {
        check_cell(cell_m)?;
        let (a, b) = corners(lo, hi);
        if !(a.iter().chain(&b).all(|v| v.is_finite())) {
            return Err(GridError::NonFiniteBounds { lo: a, hi: b });
        }
        if hi.x < lo.x || hi.y < lo.y {
            return Err(GridError::InvertedBounds { lo: a, hi: b });
        }
        // Finite bounds may still differ by more than f64::MAX: the span is then infinite
        // and caught as too many cells.
        let cols = count(((hi.x - lo.x) / cell_m).ceil());
        let rows = count(((hi.y - lo.y) / cell_m).ceil());
        let too_many = GridError::TooManyCells {
            cols,
            rows,
            limit: max_cells,
        };
        let (Some(c), Some(r)) = (
            checked_usize(cols, max_cells),
            checked_usize(rows, max_cells),
        ) else {
            return Err(too_many);
        };
        if c.checked_mul(r).is_none_or(|n| n > max_cells) {
            return Err(too_many);
        }
        Self::new(lo, cell_m, c, r, max_cells)
    }

    /// The same cells moved by `by` (the lattice of `pmf` follows the PDR origin). Errors when
    /// the moved grid is no longer finite.
    pub fn translated(&self, by: Vector2) -> Result<Self, GridError> {
        Self::new(
            self.origin + by,
            self.cell_m,
            self.cols,
            self.rows,
            usize::MAX,
        )
    }

    /// Lower-left corner of cell `(0, 0)`, metres.
    pub fn origin(&self) -> Point2 {
        self.origin
    }

    /// Side of a cell, metres.
    pub fn cell_m(&self) -> f64 {
        self.cell_m
    }

    /// Number of columns (cells along `x`).
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Number of rows (cells along `y`).
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Columns and rows.
    pub fn dims(&self) -> (usize, usize) {
        (self.cols, self.rows)
    }

    /// Number of cells, `cols * rows`.
    pub fn len(&self) -> usize {
        self.cols * self.rows
    }

    /// Always false: a grid has at least one cell (for clippy's `len_without_is_empty`).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Upper-right corner of the last cell, metres.
    pub fn far_corner(&self) -> Point2 {
        Point2::new(
            self.origin.x + self.cols as f64 * self.cell_m,
            self.origin.y + self.rows as f64 * self.cell_m,
        )
    }

    fn axis(v: f64, origin: f64, cell_m: f64, n: usize) -> Option<usize> {
        let c = ((v - origin) / cell_m).floor();
        if c >= 0.0 && c < n as f64 {
            Some(c as usize)
        } else {
            None
        }
    }

    /// Column of `x` (`floor((x - origin.x) / cell_m)`), `None` outside the grid or for a
    /// non-finite `x`. A lattice row shares its `y`, so the two axes can be looked up apart.
    pub fn col_of(&self, x: f64) -> Option<usize> {
        Self::axis(x, self.origin.x, self.cell_m, self.cols)
    }

    /// Row of `y`, `None` outside the grid or for a non-finite `y`.
    pub fn row_of(&self, y: f64) -> Option<usize> {
        Self::axis(y, self.origin.y, self.cell_m, self.rows)
    }

    /// `(col, row)` of the cell containing `p`, `None` outside the grid or non-finite.
    pub fn cell_of(&self, p: Point2) -> Option<(usize, usize)> {
        Some((self.col_of(p.x)?, self.row_of(p.y)?))
    }

    /// Row-major index of the cell containing `p`, `None` outside the grid or non-finite.
    pub fn index_of(&self, p: Point2) -> Option<usize> {
        self.cell_of(p).map(|(c, r)| self.index(c, r))
    }

    /// Row-major index of cell `(col, row)`: `row * cols + col`.
    pub fn index(&self, col: usize, row: usize) -> usize {
        row * self.cols + col
    }

    /// `(col, row)` of the cell of row-major index `i`.
    pub fn col_row(&self, i: usize) -> (usize, usize) {
        (i % self.cols, i / self.cols)
    }

    /// `x` of the centres of column `col`.
    pub fn centre_x(&self, col: usize) -> f64 {
        self.origin.x + (col as f64 + 0.5) * self.cell_m
    }

    /// `y` of the centres of row `row`.
    pub fn centre_y(&self, row: usize) -> f64 {
        self.origin.y + (row as f64 + 0.5) * self.cell_m
    }

    /// Centre of cell `(col, row)`.
    pub fn centre(&self, col: usize, row: usize) -> Point2 {
        Point2::new(self.centre_x(col), self.centre_y(row))
    }

    /// Centre of the cell of row-major index `i`.
    pub fn centre_of_index(&self, i: usize) -> Point2 {
        let (c, r) = self.col_row(i);
        self.centre(c, r)
    }

    /// The columns whose centre `x` lies in `[x0, x1)` (clipped to the grid; empty for
    /// non-finite or inverted bounds): the span of a scanline fill.
    pub fn cols_with_centre_in(&self, x0: f64, x1: f64) -> Range<usize> {
        let first = |x: f64| {
            let c = ((x - self.origin.x) / self.cell_m - 0.5).ceil();
            if c > 0.0 {
                checked_usize(c, self.cols).unwrap_or(self.cols)
            } else {
                0
            }
        };
        let (a, b) = (first(x0), first(x1));
        a..b.max(a)
    }

    /// The cells `(col range, row range)` that overlap the box `[lo, hi]` (clipped to the
    /// grid), `None` when the box misses the grid or is not finite.
    pub fn cells_overlapping(
        &self,
        lo: Point2,
        hi: Point2,
    ) -> Option<(Range<usize>, Range<usize>)> {
        let span = |a: f64, b: f64, origin: f64, n: usize| {
            let (u0, u1) = (
                ((a - origin) / self.cell_m).floor(),
                ((b - origin) / self.cell_m).floor(),
            );
            if !(u0.is_finite() && u1.is_finite()) || u1 < 0.0 || u0 >= n as f64 || u1 < u0 {
                return None;
            }
            let first = if u0 > 0.0 { u0 as usize } else { 0 };
            let last = checked_usize(u1, n - 1).unwrap_or(n - 1);
            Some(first..last + 1)
        };
        Some((
            span(lo.x, hi.x, self.origin.x, self.cols)?,
            span(lo.y, hi.y, self.origin.y, self.rows)?,
        ))
    }

    /// Every cell as `(col, row)`, row-major (the order of [`GridSpec::index`]).
    pub fn cells(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        (0..self.rows).flat_map(move |r| (0..self.cols).map(move |c| (c, r)))
    }

    /// The 8-neighbourhood of cell `(col, row)` inside the grid, as `(col, row)`.
    pub fn neighbours8(&self, col: usize, row: usize) -> impl Iterator<Item = (usize, usize)> {
        let (cols, rows) = (self.cols, self.rows);
        (-1i64..=1)
            .flat_map(|dr| (-1i64..=1).map(move |dc| (dc, dr)))
            .filter(|&d| d != (0, 0))
            .filter_map(move |(dc, dr)| {
                let c = col.checked_add_signed(dc as isize)?;
                let r = row.checked_add_signed(dr as isize)?;
                (c < cols && r < rows).then_some((c, r))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const LIMIT: usize = 1 << 20;

    #[test]
    fn covering_counts_cells_like_the_hand_written_grids() {
        let g =
            GridSpec::covering(Point2::new(-1.0, 2.0), Point2::new(9.2, 2.0), 0.5, LIMIT).unwrap();
        assert_eq!(g.dims(), (21, 1));
        let g =
            GridSpec::covering_inclusive(Point2::new(-1.0, 2.0), Point2::new(9.0, 2.0), 0.5, LIMIT)
                .unwrap();
        assert_eq!(g.dims(), (21, 1));
        assert_eq!(g.far_corner(), Point2::new(9.5, 2.5));
        assert_eq!(g.len(), 21);
    }

    #[test]
    fn bad_inputs_are_typed_errors() {
        let o = Point2::new(0.0, 0.0);
        let one = Point2::new(1.0, 1.0);
        for cell in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                GridSpec::covering(o, one, cell, LIMIT),
                Err(GridError::InvalidCell(_))
            ));
        }
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert!(matches!(
                GridSpec::covering(Point2::new(bad, 0.0), one, 1.0, LIMIT),
                Err(GridError::NonFiniteBounds { .. })
            ));
            assert!(matches!(
                GridSpec::covering_inclusive(o, Point2::new(1.0, bad), 1.0, LIMIT),
                Err(GridError::NonFiniteBounds { .. })
            ));
        }
        assert!(matches!(
            GridSpec::covering(one, o, 1.0, LIMIT),
            Err(GridError::InvertedBounds { .. })
        ));
        for far in [1e20, 1e308, f64::MAX] {
            let e = GridSpec::covering_inclusive(
                Point2::new(-f64::MAX, 0.0),
                Point2::new(far, 1.0),
                0.5,
                LIMIT,
            )
            .unwrap_err();
            assert!(
                matches!(e, GridError::TooManyCells { limit: LIMIT, .. }),
                "{e}"
            );
            assert!(e.to_string().contains(&LIMIT.to_string()), "{e}");
        }
        // 2048 x 1024 cells is over the limit although each axis is under it.
        assert!(matches!(
            GridSpec::covering(o, Point2::new(2048.0, 1024.0), 1.0, LIMIT),
            Err(GridError::TooManyCells { .. })
        ));
        assert!(matches!(
            GridSpec::new(o, 1.0, 0, 3, LIMIT),
            Err(GridError::Empty { .. })
        ));
        assert!(matches!(
            GridSpec::new(o, 1.0, usize::MAX, 3, usize::MAX),
            Err(GridError::TooManyCells { .. })
        ));
        assert!(matches!(
            GridSpec::new(Point2::new(f64::MAX, 0.0), 1e300, 4, 1, LIMIT),
            Err(GridError::NonFiniteBounds { .. })
        ));
        let g = GridSpec::new(o, 1.0, 2, 2, LIMIT).unwrap();
        assert!(g.translated(Vector2::new(f64::INFINITY, 0.0)).is_err());
        assert_eq!(
            g.translated(Vector2::new(1.0, -1.0)).unwrap().origin(),
            Point2::new(1.0, -1.0)
        );
    }

    #[test]
    fn lookups_outside_or_non_finite_are_none() {
        let g = GridSpec::new(Point2::new(0.0, 0.0), 1.0, 4, 3, LIMIT).unwrap();
        for p in [
            Point2::new(-0.1, 1.0),
            Point2::new(4.0, 1.0),
            Point2::new(1.0, 3.0),
            Point2::new(f64::NAN, 1.0),
            Point2::new(1.0, f64::INFINITY),
            Point2::new(1e308, -1e308),
        ] {
            assert_eq!(g.cell_of(p), None, "{p:?}");
            assert_eq!(g.index_of(p), None);
        }
        assert_eq!(g.cell_of(Point2::new(3.999, 0.0)), Some((3, 0)));
        assert_eq!(g.index_of(Point2::new(1.5, 2.5)), Some(9));
        assert_eq!(g.col_row(9), (1, 2));
        assert_eq!(g.centre_of_index(9), Point2::new(1.5, 2.5));
        assert_eq!(g.cells().count(), 12);
        assert_eq!(
            g.cells().map(|(c, r)| g.index(c, r)).collect::<Vec<_>>(),
            (0..12).collect::<Vec<_>>()
        );
    }

    #[test]
    fn scanline_spans_and_boxes_are_clipped() {
        let g = GridSpec::new(Point2::new(0.0, 0.0), 1.0, 10, 5, LIMIT).unwrap();
        // Centres 0.5, 1.5, ...: those in [1.0, 3.5) are columns 1 and 2, [3.5, 4.5) is 3.
        assert_eq!(g.cols_with_centre_in(1.0, 3.5), 1..3);
        assert_eq!(g.cols_with_centre_in(3.5, 4.5), 3..4);
        assert_eq!(g.cols_with_centre_in(-1e20, 1e20), 0..10);
        assert_eq!(g.cols_with_centre_in(f64::NAN, 5.0), 0..5);
        assert!(g.cols_with_centre_in(5.0, 2.0).is_empty());
        assert!(g.cols_with_centre_in(20.0, 30.0).is_empty());
        assert_eq!(
            g.cells_overlapping(Point2::new(-3.0, 1.2), Point2::new(2.5, 1.9)),
            Some((0..3, 1..2))
        );
        assert_eq!(
            g.cells_overlapping(Point2::new(-1e308, -1e308), Point2::new(1e308, 1e308)),
            Some((0..10, 0..5))
        );
        assert_eq!(
            g.cells_overlapping(Point2::new(11.0, 0.0), Point2::new(12.0, 1.0)),
            None
        );
        assert_eq!(
            g.cells_overlapping(Point2::new(f64::NAN, 0.0), Point2::new(1.0, 1.0)),
            None
        );
        let mut n: Vec<_> = g.neighbours8(0, 0).collect();
        n.sort();
        assert_eq!(n, vec![(0, 1), (1, 0), (1, 1)]);
        assert_eq!(g.neighbours8(5, 2).count(), 8);
        assert_eq!(g.neighbours8(9, 4).count(), 3);
    }

    proptest! {
        /// A cell's centre falls in that very cell.
        #[test]
        fn the_centre_of_a_cell_is_in_it(
            ox in -1e6f64..1e6, oy in -1e6f64..1e6, cell in 0.01f64..10.0,
            cols in 1usize..500, rows in 1usize..500, c in 0usize..500, r in 0usize..500,
        ) {
            let g = GridSpec::new(Point2::new(ox, oy), cell, cols, rows, usize::MAX).unwrap();
            let (c, r) = (c % cols, r % rows);
            prop_assert_eq!(g.cell_of(g.centre(c, r)), Some((c, r)));
            prop_assert_eq!(g.index_of(g.centre(c, r)), Some(g.index(c, r)));
            prop_assert_eq!(g.col_row(g.index(c, r)), (c, r));
        }

        /// No lookup or constructor panics, whatever the f64 input.
        #[test]
        fn nothing_panics_on_any_f64(
            a in any::<f64>(), b in any::<f64>(), x in any::<f64>(), y in any::<f64>(),
            cell in any::<f64>(), limit in 0usize..1 << 22,
        ) {
            let lo = Point2::new(a.min(b), x.min(y));
            let hi = Point2::new(a.max(b), x.max(y));
            for g in [
                GridSpec::covering(lo, hi, cell, limit),
                GridSpec::covering_inclusive(lo, hi, cell, limit),
                GridSpec::covering(Point2::new(a, x), Point2::new(b, y), cell, limit),
            ].into_iter().flatten() {
                prop_assert!(g.len() <= limit && g.cols() > 0 && g.rows() > 0);
                if let Some((c, r)) = g.cell_of(Point2::new(x, y)) {
                    prop_assert!(c < g.cols() && r < g.rows());
                }
                let span = g.cols_with_centre_in(a, b);
                prop_assert!(span.end <= g.cols());
                if let Some((cs, rs)) = g.cells_overlapping(lo, hi) {
                    prop_assert!(cs.end <= g.cols() && rs.end <= g.rows() && !cs.is_empty() && !rs.is_empty());
                }
            }
            let _ = checked_usize(a, limit);
            let _ = checked_i64(a);
            if let Some(i) = checked_usize(a, limit) {
                prop_assert!(i <= limit);
            }
        }
    }
}
