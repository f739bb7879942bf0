//! An R-tree (rstar 0.12) over a floor plan's wall segments, so that a particle's move is
//! tested against only the walls near it (paper 004 §4.3.3: a particle whose move crosses a
//! wall gets weight 0).
//!
//! ```
//! use wipdr_core::{Point2, Segment};
//! use wipdr_fusion::WallIndex;
//! let walls = WallIndex::new(&[Segment { a: Point2::new(0.0, -1.0), b: Point2::new(0.0, 1.0) }]);
//! assert!(walls.crosses(Point2::new(-0.5, 0.0), Point2::new(0.5, 0.0)));
//! assert!(!walls.crosses(Point2::new(0.5, 0.0), Point2::new(1.5, 0.0)));
//! ```

use rstar::{AABB, RTree, RTreeObject};
use wipdr_core::{Point2, Segment};

/// A wall segment stored in the R-tree.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Wall(Segment);

impl RTreeObject for Wall {
    type Envelope = AABB<[f64; 2]>;
    fn envelope(&self) -> Self::Envelope {
        AABB::from_corners([self.0.a.x, self.0.a.y], [self.0.b.x, self.0.b.y])
    }
}

/// Spatial index of wall segments.
#[derive(Debug, Clone)]
pub struct WallIndex {
    tree: RTree<Wall>,
}

impl WallIndex {
    /// Indexes `walls`; segments with a non-finite end are dropped (and logged).
    pub fn new(walls: &[Segment]) -> Self {
        let finite: Vec<Wall> = walls
            .iter()
            .filter(|s| {
                s.a.x.is_finite() && s.a.y.is_finite() && s.b.x.is_finite() && s.b.y.is_finite()
            })
            .map(|s| Wall(*s))
            .collect();
        if finite.len() < walls.len() {
            tracing::warn!(
                dropped = walls.len() - finite.len(),
                "non-finite wall segments dropped"
            );
        }
        Self {
            tree: RTree::bulk_load(finite),
        }
    }

    /// Number of indexed walls.
    pub fn len(&self) -> usize {
        self.tree.size()
    }

    /// Whether no wall is indexed.
    pub fn is_empty(&self) -> bool {
        self.tree.size() == 0
    }

    /// Appends to `out` the walls whose bounding box meets the box with corners `lo`, `hi`.
    pub fn walls_near(&self, lo: Point2, hi: Point2, out: &mut Vec<Segment>) {
        let envelope = AABB::from_corners([lo.x, lo.y], [hi.x, hi.y]);
        out.extend(
            self.tree
                .locate_in_envelope_intersecting(&envelope)
                .map(|w| w.0),
        );
    }

    /// Whether the move `from -> to` crosses (or touches) any wall.
    pub fn crosses(&self, from: Point2, to: Point2) -> bool {
        let envelope = AABB::from_corners([from.x, from.y], [to.x, to.y]);
        self.tree
            .locate_in_envelope_intersecting(&envelope)
            .any(|w| w.0.intersects(from, to))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{SyntheticConfig, SyntheticWalk};
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn agrees_with_the_linear_scan(x0 in -5.0f64..65.0, y0 in -5.0f64..45.0,
                                       dx in -8.0f64..8.0, dy in -8.0f64..8.0) {
            let plan = SyntheticWalk::generate(&SyntheticConfig::default()).plan;
            let index = WallIndex::new(&plan.walls);
            let (a, b) = (Point2::new(x0, y0), Point2::new(x0 + dx, y0 + dy));
            prop_assert_eq!(index.crosses(a, b), plan.crosses_wall(a, b));
        }
    }
}
