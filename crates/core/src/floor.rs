//! Floor plans in metres: the floor outline, unit (shop) polygons and wall segments.

use crate::{CoreError, Point2};
use serde::{Deserialize, Serialize};

/// A straight wall segment from `a` to `b`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Segment {
    /// One end.
    pub a: Point2,
    /// The other end.
    pub b: Point2,
}

impl Segment {
    /// Whether this segment and the segment `p -> q` intersect (touching counts).
    ///
    /// ```
    /// use wipdr_core::{Point2, Segment};
    /// let wall = Segment { a: Point2::new(0.0, -1.0), b: Point2::new(0.0, 1.0) };
    /// assert!(wall.intersects(Point2::new(-1.0, 0.0), Point2::new(1.0, 0.0)));
    /// assert!(!wall.intersects(Point2::new(0.5, 0.0), Point2::new(1.0, 0.0)));
    /// ```
    pub fn intersects(&self, p: Point2, q: Point2) -> bool {
        segments_intersect(self.a, self.b, p, q)
    }

    /// Distance from `p` to the closest point of the segment.
    pub fn distance_to(&self, p: Point2) -> f64 {
        (p - self.closest_point(p)).norm()
    }

    /// The point of the segment closest to `p`.
    pub fn closest_point(&self, p: Point2) -> Point2 {
        let d = self.b - self.a;
        let len2 = d.norm_squared();
        if len2 <= f64::EPSILON {
            return self.a;
        }
        let t = ((p - self.a).dot(&d) / len2).clamp(0.0, 1.0);
        self.a + d * t
    }
}

fn orient(a: Point2, b: Point2, c: Point2) -> f64 {
    (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)
}

fn on_segment(a: Point2, b: Point2, p: Point2) -> bool {
    p.x >= a.x.min(b.x) && p.x <= a.x.max(b.x) && p.y >= a.y.min(b.y) && p.y <= a.y.max(b.y)
}

/// Whether segments `a-b` and `c-d` intersect, including touching and collinear overlap.
pub fn segments_intersect(a: Point2, b: Point2, c: Point2, d: Point2) -> bool {
    let d1 = orient(c, d, a);
    let d2 = orient(c, d, b);
    let d3 = orient(a, b, c);
    let d4 = orient(a, b, d);
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    (d1 == 0.0 && on_segment(c, d, a))
        || (d2 == 0.0 && on_segment(c, d, b))
        || (d3 == 0.0 && on_segment(a, b, c))
        || (d4 == 0.0 && on_segment(a, b, d))
}

/// A simple polygon with optional holes; rings are open (the last vertex is not repeated).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Polygon {
    /// Outer ring.
    pub exterior: Vec<Point2>,
    /// Holes.
    pub holes: Vec<Vec<Point2>>,
}

impl Polygon {
    /// Builds a polygon; drops a repeated closing vertex; needs at least three vertices.
    pub fn new(mut exterior: Vec<Point2>, holes: Vec<Vec<Point2>>) -> Result<Self, CoreError> {
        if exterior.len() > 1 && exterior.first() == exterior.last() {
            exterior.pop();
        }
        if exterior.len() < 3 {
            return Err(CoreError::DegeneratePolygon(exterior.len()));
        }
        if exterior
            .iter()
            .any(|p| !p.x.is_finite() || !p.y.is_finite())
        {
            return Err(CoreError::NonFinite {
                field: "polygon vertex",
            });
        }
        Ok(Self { exterior, holes })
    }

    /// The axis-aligned rectangle with corners `(x0, y0)` and `(x1, y1)`, counter-clockwise
    /// from `(x0, y0)` when `x0 < x1` and `y0 < y1`, no holes. Errors on a non-finite corner.
    ///
    /// ```
    /// use wipdr_core::{Point2, Polygon};
    /// let r = Polygon::rectangle(0.0, 0.0, 4.0, 2.0).unwrap();
    /// assert!(r.contains(Point2::new(3.0, 1.0)) && !r.contains(Point2::new(5.0, 1.0)));
    /// assert!(Polygon::rectangle(0.0, 0.0, f64::NAN, 2.0).is_err());
    /// ```
    pub fn rectangle(x0: f64, y0: f64, x1: f64, y1: f64) -> Result<Self, CoreError> {
        Self::new(
            vec![
                Point2::new(x0, y0),
                Point2::new(x1, y0),
                Point2::new(x1, y1),
                Point2::new(x0, y1),
            ],
            vec![],
        )
    }

    /// Even-odd point-in-polygon test (inside the exterior, outside every hole).
    ///
    /// ```
    /// use wipdr_core::{Point2, Polygon};
    /// let sq = Polygon::new(vec![Point2::new(0.0, 0.0), Point2::new(2.0, 0.0),
    ///     Point2::new(2.0, 2.0), Point2::new(0.0, 2.0)], vec![]).unwrap();
    /// assert!(sq.contains(Point2::new(1.0, 1.0)));
    /// assert!(!sq.contains(Point2::new(3.0, 1.0)));
    /// ```
    pub fn contains(&self, p: Point2) -> bool {
        ring_contains(&self.exterior, p) && !self.holes.iter().any(|h| ring_contains(h, p))
    }

    /// The ring edges (exterior and holes) as segments.
    pub fn edges(&self) -> impl Iterator<Item = Segment> + '_ {
        std::iter::once(&self.exterior)
            .chain(self.holes.iter())
            .flat_map(|ring| {
                (0..ring.len()).map(move |i| Segment {
                    a: ring[i],
                    b: ring[(i + 1) % ring.len()],
                })
            })
    }

    /// Signed area of the exterior ring minus holes (absolute values), m².
    pub fn area(&self) -> f64 {
        ring_area(&self.exterior).abs() - self.holes.iter().map(|h| ring_area(h).abs()).sum::<f64>()
    }

    /// Axis-aligned bounding box `(min, max)` of the exterior.
    pub fn bbox(&self) -> (Point2, Point2) {
        let mut lo = Point2::new(f64::INFINITY, f64::INFINITY);
        let mut hi = Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
        for p in &self.exterior {
            lo.x = lo.x.min(p.x);
            lo.y = lo.y.min(p.y);
            hi.x = hi.x.max(p.x);
            hi.y = hi.y.max(p.y);
        }
        (lo, hi)
    }
}

fn ring_area(r: &[Point2]) -> f64 {
    let n = r.len();
    (0..n)
        .map(|i| {
            let (a, b) = (r[i], r[(i + 1) % n]);
            a.x * b.y - b.x * a.y
        })
        .sum::<f64>()
        / 2.0
}

fn ring_contains(r: &[Point2], p: Point2) -> bool {
    let n = r.len();
    let mut inside = false;
    let mut j = n.wrapping_sub(1);
    for i in 0..n {
        let (a, b) = (r[i], r[j]);
        if (a.y > p.y) != (b.y > p.y) {
            let x = (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x;
            if p.x < x {
                inside = !inside;
            }
        }
        j = i;
    }
    inside
}

/// A named unit of the floor (a shop, a service room): not walkable space for map matching.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Unit {
    /// Display name, possibly empty.
    pub name: String,
    /// The unit's footprint, metres.
    pub polygon: Polygon,
}

/// A floor plan in the metre frame of the waypoints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FloorPlan {
    /// Floor width (x extent), metres.
    pub width: f64,
    /// Floor height (y extent), metres.
    pub height: f64,
    /// The floor outline (one or more polygons).
    pub outline: Vec<Polygon>,
    /// Units (shops, rooms).
    pub units: Vec<Unit>,
    /// Wall segments: the edges of the outline and of every unit.
    pub walls: Vec<Segment>,
}

impl FloorPlan {
    /// Builds a plan; walls are the edges of the outline and of every unit.
    pub fn new(
        width: f64,
        height: f64,
        outline: Vec<Polygon>,
        units: Vec<Unit>,
    ) -> Result<Self, CoreError> {
        if !(width.is_finite() && height.is_finite() && width > 0.0 && height > 0.0) {
            return Err(CoreError::InvalidFloorSize { width, height });
        }
        let walls = outline
            .iter()
            .flat_map(|p| p.edges())
            .chain(units.iter().flat_map(|u| u.polygon.edges()))
            .collect();
        Ok(Self {
            width,
            height,
            outline,
            units,
            walls,
        })
    }

    /// A `width` x `height` rectangle `[0, width] x [0, height]` as the only outline
    /// polygon, with no units (its walls are the rectangle's four sides): handy for tests
    /// and synthetic floors.
    ///
    /// ```
    /// use wipdr_core::{FloorPlan, Point2};
    /// let plan = FloorPlan::rectangle(20.0, 10.0).unwrap();
    /// assert!(plan.is_walkable(Point2::new(19.0, 1.0)));
    /// assert!(!plan.inside_outline(Point2::new(21.0, 1.0)));
    /// assert_eq!(plan.walls.len(), 4);
    /// assert!(FloorPlan::rectangle(0.0, 10.0).is_err());
    /// assert!(FloorPlan::rectangle(f64::NAN, 10.0).is_err());
    /// ```
    pub fn rectangle(width: f64, height: f64) -> Result<Self, CoreError> {
        if !(width.is_finite() && height.is_finite() && width > 0.0 && height > 0.0) {
            return Err(CoreError::InvalidFloorSize { width, height });
        }
        let outline = Polygon::rectangle(0.0, 0.0, width, height)?;
        Self::new(width, height, vec![outline], vec![])
    }

    /// Whether `p` lies inside the floor outline.
    pub fn inside_outline(&self, p: Point2) -> bool {
        self.outline.iter().any(|o| o.contains(p))
    }

    /// The unit containing `p`, if any.
    pub fn unit_at(&self, p: Point2) -> Option<&Unit> {
        self.units.iter().find(|u| u.polygon.contains(p))
    }

    /// Walkable: inside the outline and in no unit.
    pub fn is_walkable(&self, p: Point2) -> bool {
        self.inside_outline(p) && self.unit_at(p).is_none()
    }

    /// Whether the move `from -> to` crosses any wall (linear scan; spatial indexes live in
    /// the crates that need speed).
    pub fn crosses_wall(&self, from: Point2, to: Point2) -> bool {
        self.walls.iter().any(|w| w.intersects(from, to))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(x0: f64, y0: f64, s: f64) -> Polygon {
        Polygon::rectangle(x0, y0, x0 + s, y0 + s).unwrap()
    }

    #[test]
    fn plan_walkable_and_walls() {
        let plan = FloorPlan::new(
            10.0,
            10.0,
            vec![square(0.0, 0.0, 10.0)],
            vec![Unit {
                name: "shop".into(),
                polygon: square(2.0, 2.0, 2.0),
            }],
        )
        .unwrap();
        assert_eq!(plan.walls.len(), 8);
        assert!(plan.is_walkable(Point2::new(1.0, 1.0)));
        assert!(!plan.is_walkable(Point2::new(3.0, 3.0)));
        assert!(!plan.is_walkable(Point2::new(11.0, 3.0)));
        assert!(plan.crosses_wall(Point2::new(1.0, 3.0), Point2::new(3.0, 3.0)));
        assert!(!plan.crosses_wall(Point2::new(1.0, 1.0), Point2::new(1.0, 8.0)));
        assert!((square(0.0, 0.0, 3.0).area() - 9.0).abs() < 1e-12);
    }

    #[test]
    fn degenerate_inputs() {
        assert_eq!(
            Polygon::new(vec![Point2::new(0.0, 0.0), Point2::new(1.0, 0.0)], vec![]),
            Err(CoreError::DegeneratePolygon(2))
        );
        assert!(FloorPlan::new(0.0, 1.0, vec![], vec![]).is_err());
        assert!(FloorPlan::new(f64::NAN, 1.0, vec![], vec![]).is_err());
    }

    #[test]
    fn closest_point_on_degenerate_segment() {
        let s = Segment {
            a: Point2::new(1.0, 1.0),
            b: Point2::new(1.0, 1.0),
        };
        assert_eq!(s.distance_to(Point2::new(4.0, 5.0)), 5.0);
    }
}
