//! The synthetic floor: a mall with rows of shops, a 3 x 3 grid of corridors and an open hall,
//! and the corridor graph that walks follow.
//!
//! Corridor centre lines run at `x = 1/12, 1/2, 11/12` of the width and `y = 3/16, 1/2, 13/16`
//! of the height (with the defaults: `x = 10, 60, 110`, `y = 15, 40, 65` m on a 120 x 80 m
//! floor). Everything that is neither corridor nor hall is shops: each row of non-walkable grid
//! cells is split into shops of about `shop_width_m`. Walls are the outline and every shop's
//! edges ([`FloorPlan::new`]).

use crate::SimError;
use crate::config::FloorConfig;
use wipdr_core::ConfigError;
use wipdr_core::{FloorPlan, Point2, Polygon, Segment, Unit};

/// An axis-aligned rectangle `[x0, x1] x [y0, y1]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rect {
    /// Left.
    pub x0: f64,
    /// Bottom.
    pub y0: f64,
    /// Right.
    pub x1: f64,
    /// Top.
    pub y1: f64,
}

impl Rect {
    /// Whether `p` lies inside (closed).
    pub fn contains(&self, p: Point2) -> bool {
        p.x >= self.x0 && p.x <= self.x1 && p.y >= self.y0 && p.y <= self.y1
    }

    fn polygon(&self) -> Polygon {
        Polygon {
            exterior: vec![
                Point2::new(self.x0, self.y0),
                Point2::new(self.x1, self.y0),
                Point2::new(self.x1, self.y1),
                Point2::new(self.x0, self.y1),
            ],
            holes: vec![],
        }
    }
}

/// The walkable corridor graph: junction nodes and straight edges between them.
#[derive(Debug, Clone, PartialEq)]
pub struct CorridorGraph {
    /// Node positions, metres.
    pub nodes: Vec<Point2>,
    /// Undirected edges as node index pairs `(a, b)` with `a < b`, sorted.
    pub edges: Vec<(usize, usize)>,
    /// Neighbours of each node, sorted by index (deterministic iteration).
    pub neighbours: Vec<Vec<usize>>,
}

/// The generated floor: the plan, its walkable rectangles and the corridor graph.
#[derive(Debug, Clone, PartialEq)]
pub struct SimFloorPlan {
    /// The plan (outline, shops, walls) in metres.
    pub plan: FloorPlan,
    /// Corridors and the hall: the walkable space.
    pub walkable: Vec<Rect>,
    /// The hall rectangle.
    pub hall: Rect,
    /// The graph walks follow.
    pub graph: CorridorGraph,
    /// Walls with shared shop edges merged (for counting crossed walls once).
    pub unique_walls: Vec<Segment>,
}

impl SimFloorPlan {
    /// Builds the floor from its configuration (deterministic: no randomness).
    pub fn build(cfg: &FloorConfig) -> Result<Self, SimError> {
        let (w, h) = (cfg.width_m, cfg.height_m);
        let half = cfg.corridor_width_m / 2.0;
        if cfg.lane_offset_m < 0.0 || cfg.lane_offset_m + 0.2 >= half {
            return Err(SimError::InvalidConfig(ConfigError::new(
                "floor.lane_offset_m",
                "must be in [0, corridor half width - 0.2)",
            )));
        }
        let [hx0, hx1] = cfg.hall_x_fraction;
        if !(0.0 < hx0 && hx0 < 0.5 && 0.5 < hx1 && hx1 < 1.0) {
            return Err(SimError::InvalidConfig(ConfigError::new(
                "floor.hall_x_fraction",
                "must satisfy 0 < from < 0.5 < to < 1",
            )));
        }
        let xs = [w / 12.0, w / 2.0, w * 11.0 / 12.0];
        let ys = [h * 3.0 / 16.0, h / 2.0, h * 13.0 / 16.0];
        if xs[0] - half < 1.0 || ys[0] - half < 1.0 || xs[1] - xs[0] < 4.0 * half {
            return Err(SimError::InvalidConfig(ConfigError::new(
                "floor.corridor_width_m",
                "too wide for the floor size",
            )));
        }
        let mut walkable = Vec::new();
        for &y in &ys {
            walkable.push(Rect {
                x0: xs[0] - half,
                y0: y - half,
                x1: xs[2] + half,
                y1: y + half,
            });
        }
        for &x in &xs {
            walkable.push(Rect {
                x0: x - half,
                y0: ys[0] - half,
                x1: x + half,
                y1: ys[2] + half,
            });
        }
        let hall = Rect {
            x0: w * hx0,
            y0: ys[0] + half,
            x1: w * hx1,
            y1: ys[2] - half,
        };
        if hall.x0 <= xs[0] + half || hall.x1 >= xs[2] - half {
            return Err(SimError::InvalidConfig(ConfigError::new(
                "floor.hall_x_fraction",
                "the hall must lie between the outer corridors",
            )));
        }
        walkable.push(hall);
        let is_walkable = |p: Point2| walkable.iter().any(|r| r.contains(p));

        // Grid of cell boundaries; every non-walkable cell row is cut into shops.
        let mut bx = vec![0.0, w, hall.x0, hall.x1];
        let mut by = vec![0.0, h];
        for &x in &xs {
            bx.extend([x - half, x + half]);
        }
        for &y in &ys {
            by.extend([y - half, y + half]);
        }
        bx.sort_by(f64::total_cmp);
        by.sort_by(f64::total_cmp);
        bx.dedup();
        by.dedup();
        let mut units = Vec::new();
        for row in by.windows(2) {
            let (y0, y1) = (row[0], row[1]);
            let mut run_start: Option<f64> = None;
            for (i, col) in bx.windows(2).enumerate() {
                let centre = Point2::new((col[0] + col[1]) / 2.0, (y0 + y1) / 2.0);
                let shop = !is_walkable(centre);
                if shop && run_start.is_none() {
                    run_start = Some(col[0]);
                }
                let last = i + 2 == bx.len();
                if let Some(x0) = run_start {
                    let end = if !shop {
                        Some(col[0])
                    } else if last {
                        Some(col[1])
                    } else {
                        None
                    };
                    if let Some(x1) = end {
                        let n = ((x1 - x0) / cfg.shop_width_m).round().max(1.0) as usize;
                        let step = (x1 - x0) / n as f64;
                        for k in 0..n {
                            let r = Rect {
                                x0: x0 + step * k as f64,
                                y0,
                                x1: if k + 1 == n {
                                    x1
                                } else {
                                    x0 + step * (k + 1) as f64
                                },
                                y1,
                            };
                            units.push(Unit {
                                name: format!("shop {:02}", units.len() + 1),
                                polygon: r.polygon(),
                            });
                        }
                        run_start = None;
                    }
                }
            }
        }
        let outline = Rect {
            x0: 0.0,
            y0: 0.0,
            x1: w,
            y1: h,
        };
        let plan = FloorPlan::new(w, h, vec![outline.polygon()], units)?;
        let unique_walls = merge_walls(&plan.walls);
        let graph = corridor_graph(&xs, &ys, &hall);
        Ok(Self {
            plan,
            walkable,
            hall,
            graph,
            unique_walls,
        })
    }

    /// Whether `p` is in a corridor or the hall.
    pub fn is_walkable(&self, p: Point2) -> bool {
        self.walkable.iter().any(|r| r.contains(p))
    }

    /// Number of distinct walls crossed by the straight line `a -> b`.
    pub fn walls_crossed(&self, a: Point2, b: Point2) -> usize {
        self.unique_walls
            .iter()
            .filter(|w| w.intersects(a, b))
            .count()
    }
}

/// Removes exact duplicate segments (shared edges of neighbouring shops), direction-agnostic,
/// keeping the first occurrence (deterministic).
fn merge_walls(walls: &[Segment]) -> Vec<Segment> {
    let key = |s: &Segment| {
        let (a, b) = if (s.a.x, s.a.y) <= (s.b.x, s.b.y) {
            (s.a, s.b)
        } else {
            (s.b, s.a)
        };
        [a.x.to_bits(), a.y.to_bits(), b.x.to_bits(), b.y.to_bits()]
    };
    let mut seen = std::collections::BTreeSet::new();
    walls
        .iter()
        .filter(|s| seen.insert(key(s)))
        .copied()
        .collect()
}

fn corridor_graph(xs: &[f64; 3], ys: &[f64; 3], hall: &Rect) -> CorridorGraph {
    let mut nodes = Vec::new();
    for &y in ys {
        for &x in xs {
            nodes.push(Point2::new(x, y));
        }
    }
    let id = |i: usize, j: usize| j * 3 + i; // column i (x), row j (y)
    let mut edges = Vec::new();
    for j in 0..3 {
        for i in 0..2 {
            edges.push((id(i, j), id(i + 1, j)));
        }
    }
    for i in 0..3 {
        for j in 0..2 {
            edges.push((id(i, j), id(i, j + 1)));
        }
    }
    // Hall: four inner points on the diagonals, linked to the centre, to the corridor node on
    // their side (bottom or top middle) and to each other around the hall (a loop).
    let centre = id(1, 1);
    let (cx, cy) = (xs[1], ys[1]);
    let dx = (hall.x1 - hall.x0) / 2.0 * 0.55;
    let dy = (hall.y1 - hall.y0) / 2.0 * 0.55;
    let first_inner = nodes.len();
    for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
        let k = nodes.len();
        nodes.push(Point2::new(cx + sx * dx, cy + sy * dy));
        edges.push((centre.min(k), centre.max(k)));
        let side = if sy < 0.0 { id(1, 0) } else { id(1, 2) };
        edges.push((side.min(k), side.max(k)));
    }
    let inner = |k: usize| first_inner + k;
    for (a, b) in [(0, 1), (2, 3), (0, 2), (1, 3)] {
        edges.push((inner(a), inner(b)));
    }
    edges.sort_unstable();
    edges.dedup();
    let mut neighbours = vec![Vec::new(); nodes.len()];
    for &(a, b) in &edges {
        neighbours[a].push(b);
        neighbours[b].push(a);
    }
    for n in &mut neighbours {
        n.sort_unstable();
    }
    CorridorGraph {
        nodes,
        edges,
        neighbours,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn graph_edges_lie_in_walkable_space_and_cross_no_wall() {
        let f = SimFloorPlan::build(&FloorConfig::default()).unwrap();
        assert!(f.plan.units.len() >= 20, "{} shops", f.plan.units.len());
        for &(a, b) in &f.graph.edges {
            let (pa, pb) = (f.graph.nodes[a], f.graph.nodes[b]);
            for k in 0..=200 {
                let p = pa + (pb - pa) * (k as f64 / 200.0);
                assert!(f.is_walkable(p), "edge {a}-{b} leaves the corridors at {p}");
                assert!(f.plan.is_walkable(p), "edge {a}-{b} enters a shop at {p}");
            }
            assert!(!f.plan.crosses_wall(pa, pb), "edge {a}-{b} crosses a wall");
        }
        for n in &f.graph.neighbours {
            assert!(n.len() >= 2, "dead end in the graph");
        }
    }

    #[test]
    fn shops_and_walkable_space_are_disjoint() {
        let f = SimFloorPlan::build(&FloorConfig::default()).unwrap();
        for i in 0..120 {
            for j in 0..80 {
                let p = Point2::new(i as f64 + 0.3, j as f64 + 0.3);
                let shop = f.plan.unit_at(p).is_some();
                assert_ne!(shop, f.is_walkable(p), "at {p}");
            }
        }
        assert!(f.unique_walls.len() < f.plan.walls.len());
        // From a corridor through a row of shops to the outer wall crosses walls.
        assert!(f.walls_crossed(Point2::new(30.0, 15.0), Point2::new(30.0, 40.0)) >= 2);
        assert_eq!(
            f.walls_crossed(Point2::new(10.0, 15.0), Point2::new(110.0, 15.0)),
            0
        );
    }
}
