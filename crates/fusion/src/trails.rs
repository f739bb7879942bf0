//! Where people walk, learned from training walks: a raster of the distance to the nearest
//! *trail* (a segment between two consecutive waypoints of a training walk). **wipdr's own,
//! not from the four papers**; it is the learned counterpart of the floor plan's walkable
//! space ([`crate::walkable`]): a floor plan says where one *can* walk, the trails where
//! people *did*. `pmf` weighs its placement hypotheses by it (`trail_sd_m`).
//!
//! Only training data goes in (the evaluation protocol allows anything learned from training
//! walks); a test walk's own waypoints never do. On survey data such as the ILC walks, where
//! collectors walk straight between surveyed points that many walks share, the trails are a
//! strong prior; where test walks leave every training trail (coverage gaps) it is wrong, so
//! the weight off the trails must stay soft.
//!
//! The raster stores, for every square cell (by its centre), the exact distance to the
//! nearest segment, capped at `max_distance_m`; building it stamps each segment's bounding
//! box grown by the cap, `O(segments x cells per box)`.
//!
//! ```
//! use wipdr_core::{Point2, Segment};
//! use wipdr_fusion::trails::TrailRaster;
//! let trails = [Segment { a: Point2::new(0.0, 0.0), b: Point2::new(10.0, 0.0) }];
//! let r = TrailRaster::new(&trails, 0.5, 5.0).unwrap();
//! assert!(r.distance(Point2::new(5.0, 0.1)) < 0.5);
//! assert!((r.distance(Point2::new(5.0, 3.0)) - 3.0).abs() < 0.5);
//! assert_eq!(r.distance(Point2::new(5.0, 40.0)), 5.0); // beyond the cap
//! ```

use wipdr_core::ConfigError;
use wipdr_core::{GridSpec, Point2, Segment};

use crate::FusionError;

/// Most cells a trail raster may have.
pub const MAX_CELLS: usize = 16 << 20;

/// Distance to the nearest training trail, per cell; see the [module docs](self).
#[derive(Debug, Clone)]
pub struct TrailRaster {
    grid: GridSpec,
    max_distance_m: f64,
    distance: Vec<f32>,
}

/// Distance from `p` to the segment `s`.
fn distance_to_segment(p: Point2, s: &Segment) -> f64 {
    let ab = s.b - s.a;
    let len2 = ab.norm_squared();
    let t = if len2 > 0.0 {
        ((p - s.a).dot(&ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (s.a + ab * t)).norm()
}

impl TrailRaster {
    /// Rasterises `segments` (non-finite ones are skipped) at `cell_m`, with distances capped
    /// at `max_distance_m`. Errors on a non-positive cell or cap, no finite segment, or a
    /// raster over [`MAX_CELLS`].
    pub fn new(
        segments: &[Segment],
        cell_m: f64,
        max_distance_m: f64,
    ) -> Result<Self, FusionError> {
        let invalid =
            |field, reason: String| FusionError::InvalidConfig(ConfigError::new(field, reason));
        if !(cell_m.is_finite() && cell_m > 0.0) {
            return Err(invalid(
                "cell_m",
                format!("must be finite and > 0, got {cell_m}"),
            ));
        }
        if !(max_distance_m.is_finite() && max_distance_m > 0.0) {
            return Err(invalid(
                "max_distance_m",
                format!("must be finite and > 0, got {max_distance_m}"),
            ));
        }
        let finite: Vec<&Segment> = segments
            .iter()
            .filter(|s| {
                s.a.x.is_finite() && s.a.y.is_finite() && s.b.x.is_finite() && s.b.y.is_finite()
            })
            .collect();
        if finite.is_empty() {
            return Err(invalid("trails", "no finite trail segment".into()));
        }
        let (mut lo, mut hi) = (
            Point2::new(f64::MAX, f64::MAX),
            Point2::new(f64::MIN, f64::MIN),
        );
        for s in &finite {
            for p in [s.a, s.b] {
                lo = Point2::new(lo.x.min(p.x), lo.y.min(p.y));
                hi = Point2::new(hi.x.max(p.x), hi.y.max(p.y));
            }
        }
        let m = max_distance_m + cell_m;
        let grid = GridSpec::covering_inclusive(
            Point2::new(lo.x - m, lo.y - m),
            Point2::new(hi.x + m, hi.y + m),
            cell_m,
            MAX_CELLS,
        )
        .map_err(|e| invalid("trails", format!("no trail raster over these trails: {e}")))?;
        let mut distance = vec![max_distance_m as f32; grid.len()];
        let grow = wipdr_core::Vector2::new(max_distance_m, max_distance_m);
        for s in finite {
            let box_lo = Point2::new(s.a.x.min(s.b.x), s.a.y.min(s.b.y)) - grow;
            let box_hi = Point2::new(s.a.x.max(s.b.x), s.a.y.max(s.b.y)) + grow;
            let Some((cols, rows)) = grid.cells_overlapping(box_lo, box_hi) else {
                continue;
            };
            for r in rows {
                for c in cols.clone() {
                    let d = distance_to_segment(grid.centre(c, r), s).min(max_distance_m) as f32;
                    let v = &mut distance[grid.index(c, r)];
                    if d < *v {
                        *v = d;
                    }
                }
            }
        }
        Ok(Self {
            grid,
            max_distance_m,
            distance,
        })
    }

    /// Distance from `p` (its cell's centre) to the nearest trail, capped at the raster's
    /// cap (also beyond the raster or for a non-finite point).
    pub fn distance(&self, p: Point2) -> f64 {
        self.grid
            .index_of(p)
            .map_or(self.max_distance_m, |i| f64::from(self.distance[i]))
    }

    /// The raster's cells.
    pub fn grid(&self) -> &GridSpec {
        &self.grid
    }

    /// The distance cap, metres.
    pub fn max_distance_m(&self) -> f64 {
        self.max_distance_m
    }

    /// Share of the raster's cells within `d` metres of a trail (for logs).
    pub fn share_within(&self, d: f64) -> f64 {
        let n = self.distance.iter().filter(|&&v| f64::from(v) <= d).count();
        n as f64 / self.distance.len().max(1) as f64
    }
}

/// The trails of some walks: one segment between each two consecutive waypoints (in time
/// order) of each walk.
pub fn trails_of<'a>(
    waypoints: impl IntoIterator<Item = &'a [wipdr_core::Waypoint]>,
) -> Vec<Segment> {
    waypoints
        .into_iter()
        .flat_map(|w| {
            w.windows(2).map(|p| Segment {
                a: p[0].position,
                b: p[1].position,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn errors_name_the_field() {
        let s = [Segment {
            a: Point2::new(0.0, 0.0),
            b: Point2::new(1.0, 0.0),
        }];
        for (cell, cap, field) in [(0.0, 1.0, "cell_m"), (1.0, f64::NAN, "max_distance_m")] {
            match TrailRaster::new(&s, cell, cap) {
                Err(FusionError::InvalidConfig(e)) => assert_eq!(e.path, field),
                other => panic!("expected an error on {field}, got {other:?}"),
            }
        }
        let nan = [Segment {
            a: Point2::new(f64::NAN, 0.0),
            b: Point2::new(1.0, 0.0),
        }];
        assert!(TrailRaster::new(&nan, 1.0, 1.0).is_err());
    }

    #[test]
    fn trails_join_consecutive_waypoints() {
        let wp = |t, x| wipdr_core::Waypoint::new(t, Point2::new(x, 0.0));
        let a = [wp(0, 0.0), wp(1, 1.0), wp(2, 3.0)];
        let b = [wp(0, 9.0)];
        let t = trails_of([&a[..], &b[..]]);
        assert_eq!(t.len(), 2);
        assert_eq!(t[1].a, Point2::new(1.0, 0.0));
        assert_eq!(t[1].b, Point2::new(3.0, 0.0));
    }

    /// Every cell holds, bit for bit, the capped distance of its centre to the nearest
    /// segment: stamping each segment's box misses no cell within the cap.
    #[test]
    fn stamping_equals_the_brute_force_raster() {
        let segments = [
            Segment {
                a: Point2::new(0.0, 0.0),
                b: Point2::new(7.3, 2.1),
            },
            Segment {
                a: Point2::new(7.3, 2.1),
                b: Point2::new(7.3, -4.9),
            },
            Segment {
                a: Point2::new(-3.2, 5.5),
                b: Point2::new(-3.2, 5.5),
            },
        ];
        let cap = 2.7;
        let r = TrailRaster::new(&segments, 0.4, cap).unwrap();
        let g = *r.grid();
        for (c, row) in g.cells() {
            let centre = g.centre(c, row);
            let exact = segments
                .iter()
                .map(|s| distance_to_segment(centre, s).min(cap) as f32)
                .fold(cap as f32, f32::min);
            assert_eq!(r.distance[g.index(c, row)], exact, "cell ({c}, {row})");
        }
    }

    proptest! {
        /// The raster's distance is within a cell's half-diagonal of the exact distance
        /// (it is exact at cell centres), capped.
        #[test]
        fn raster_distance_is_the_exact_one_at_cell_resolution(
            ax in -20.0..20.0f64, ay in -20.0..20.0f64,
            bx in -20.0..20.0f64, by in -20.0..20.0f64,
            px in -30.0..30.0f64, py in -30.0..30.0f64,
        ) {
            let s = Segment { a: Point2::new(ax, ay), b: Point2::new(bx, by) };
            let cell = 0.5;
            let r = TrailRaster::new(&[s], cell, 6.0).unwrap();
            let p = Point2::new(px, py);
            let exact = distance_to_segment(p, &s).min(6.0);
            let got = r.distance(p);
            prop_assert!((0.0..=6.0).contains(&got));
            prop_assert!((got - exact).abs() <= cell * std::f64::consts::FRAC_1_SQRT_2 + 1e-9,
                "got {got}, exact {exact}");
        }
    }
}
