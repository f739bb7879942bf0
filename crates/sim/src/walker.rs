//! The walker: a route along the corridor graph, a smooth path with rounded corners, and a
//! step-by-step timeline (standing periods and steps) that fixes where the walker is at every
//! instant.
//!
//! The path is a sequence of straight pieces and circular arcs (constant curvature), so its
//! heading is continuous and the gyroscope sees smooth turns. Cadence `f` is drawn per walker
//! in `[step_frequency_min_hz, step_frequency_max_hz]`, scaled per leg (slow / normal / fast);
//! the step length is `scale * (a + b f)` with per-step jitter; the vertical bounce of a step
//! follows the inverted pendulum `h = L - sqrt(L² - (l/2)²)` (paper 004 eq. 6 solved for `h`).

use crate::config::{FloorConfig, WalkerConfig};
use crate::floor::SimFloorPlan;
use crate::rng::Draw;
use rand::rngs::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use wipdr_core::{Point2, Vector2, angle};

/// One piece of the walked path: a straight line (`curvature == 0`) or a circular arc.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathPiece {
    /// Arc length at the start of the piece, metres.
    pub s0: f64,
    /// Length of the piece, metres.
    pub length: f64,
    /// Start position.
    pub p0: Point2,
    /// Heading at the start (clockwise from `+y`, unwrapped), radians.
    pub psi0: f64,
    /// Curvature `d psi / d s`, 1/m (positive turns clockwise, to the right).
    pub curvature: f64,
}

impl PathPiece {
    /// Position and unwrapped heading at arc length `u` from the piece start.
    pub fn at(&self, u: f64) -> (Point2, f64) {
        let k = self.curvature;
        let psi = self.psi0 + k * u;
        if k.abs() < 1e-12 {
            (self.p0 + angle::step_displacement(u, self.psi0), psi)
        } else {
            let d = Vector2::new(
                (self.psi0.cos() - psi.cos()) / k,
                (psi.sin() - self.psi0.sin()) / k,
            );
            (self.p0 + d, psi)
        }
    }
}

/// A corner of the path: where the route turns at a junction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Corner {
    /// Arc length where the turn starts.
    pub s_start: f64,
    /// Arc length where the turn ends.
    pub s_end: f64,
    /// Signed turn angle (positive to the right), radians.
    pub angle: f64,
}

/// The walked path: pieces, corners and the junction marks (arc lengths of the route's nodes).
#[derive(Debug, Clone, PartialEq)]
pub struct WalkPath {
    /// Pieces in order; contiguous in arc length.
    pub pieces: Vec<PathPiece>,
    /// Corners, in order (every interior route node, including tiny turns).
    pub corners: Vec<Corner>,
    /// Arc length of each leg's start (leg `i` runs from `legs[i]` to `legs[i + 1]`).
    pub legs: Vec<f64>,
    /// Total length, metres.
    pub length: f64,
}

impl WalkPath {
    /// Builds the rounded path through `points` (consecutive points distinct).
    pub fn through(points: &[Point2], corner_cut_m: f64) -> Self {
        let n = points.len();
        let mut pieces = Vec::new();
        let mut corners = Vec::new();
        let mut legs = vec![0.0];
        if n < 2 {
            return Self {
                pieces,
                corners,
                legs,
                length: 0.0,
            };
        }
        let headings: Vec<f64> = points
            .windows(2)
            .map(|w| angle::heading_of(w[1] - w[0]))
            .collect();
        let lengths: Vec<f64> = points.windows(2).map(|w| (w[1] - w[0]).norm()).collect();
        // Cut at each interior vertex.
        let mut cut = vec![0.0; n];
        let mut turn = vec![0.0; n];
        for i in 1..n - 1 {
            let th = angle::diff(headings[i], headings[i - 1]);
            turn[i] = th;
            if th.abs() > 1e-6 {
                cut[i] = corner_cut_m
                    .min(0.45 * lengths[i - 1])
                    .min(0.45 * lengths[i]);
            }
        }
        let mut s = 0.0;
        let mut p = points[0];
        let mut psi = headings[0];
        for i in 0..n - 1 {
            // Straight part of segment i.
            let straight = (lengths[i] - cut[i] - cut[i + 1]).max(0.0);
            let piece = PathPiece {
                s0: s,
                length: straight,
                p0: p,
                psi0: psi,
                curvature: 0.0,
            };
            (p, psi) = piece.at(straight);
            pieces.push(piece);
            s += straight;
            let v = i + 1;
            if v < n - 1 {
                let th = turn[v];
                let (arc_len, k) = if cut[v] > 0.0 {
                    let r = cut[v] / (th.abs() / 2.0).tan();
                    (r * th.abs(), th.signum() / r)
                } else {
                    (0.0, 0.0)
                };
                let s_start = s;
                if arc_len > 0.0 {
                    let arc = PathPiece {
                        s0: s,
                        length: arc_len,
                        p0: p,
                        psi0: psi,
                        curvature: k,
                    };
                    (p, psi) = arc.at(arc_len);
                    pieces.push(arc);
                    s += arc_len;
                }
                // Tiny turns below the cut threshold: snap the heading (no arc).
                psi = arc_end_heading(psi, th, arc_len);
                corners.push(Corner {
                    s_start,
                    s_end: s,
                    angle: th,
                });
                legs.push((s_start + s) / 2.0);
            }
        }
        Self {
            pieces,
            corners,
            legs,
            length: s,
        }
    }

    fn piece_at(&self, s: f64) -> &PathPiece {
        let i = self.pieces.partition_point(|p| p.s0 <= s).saturating_sub(1);
        &self.pieces[i.min(self.pieces.len() - 1)]
    }

    /// Position and unwrapped heading at arc length `s` (clamped to the path).
    pub fn at(&self, s: f64) -> (Point2, f64) {
        if self.pieces.is_empty() {
            return (Point2::origin(), 0.0);
        }
        let s = s.clamp(0.0, self.length);
        let piece = self.piece_at(s);
        piece.at((s - piece.s0).min(piece.length))
    }

    /// Curvature at arc length `s`.
    pub fn curvature(&self, s: f64) -> f64 {
        if self.pieces.is_empty() || s < 0.0 || s > self.length {
            return 0.0;
        }
        self.piece_at(s).curvature
    }

    /// Index of the leg containing arc length `s`.
    pub fn leg_at(&self, s: f64) -> usize {
        self.legs.partition_point(|&l| l <= s).saturating_sub(1)
    }
}

fn arc_end_heading(psi_after_arc: f64, turn: f64, arc_len: f64) -> f64 {
    if arc_len > 0.0 {
        psi_after_arc
    } else {
        psi_after_arc + turn
    }
}

/// A random route on the corridor graph from a random node, long enough for `min_length_m`:
/// no U-turns, turns above `max_turn_deg` avoided when possible. Returns jittered points.
pub fn random_route(
    floor: &SimFloorPlan,
    floor_cfg: &FloorConfig,
    walker: &WalkerConfig,
    min_length_m: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<Point2> {
    let g = &floor.graph;
    let mut node = rng.index(g.nodes.len());
    let mut prev: Option<usize> = None;
    let mut nodes = vec![node];
    let mut length = 0.0;
    let max_turn = walker.max_turn_deg.to_radians();
    while length < min_length_m && nodes.len() < 100_000 {
        let here = g.nodes[node];
        let incoming = prev.map(|p| angle::heading_of(here - g.nodes[p]));
        let turn_of = |next: usize| {
            incoming.map_or(0.0, |h| {
                angle::diff(angle::heading_of(g.nodes[next] - here), h).abs()
            })
        };
        let allowed: Vec<usize> = g.neighbours[node]
            .iter()
            .copied()
            .filter(|&n| Some(n) != prev && turn_of(n) <= max_turn)
            .collect();
        let (lo, hi) = (
            walker.avoid_turn_deg[0].to_radians(),
            walker.avoid_turn_deg[1].to_radians(),
        );
        let clear: Vec<usize> = allowed
            .iter()
            .copied()
            .filter(|&n| !(lo..=hi).contains(&turn_of(n)))
            .collect();
        let options = if clear.is_empty() { allowed } else { clear };
        let next = if options.is_empty() {
            // Least-turning way on, back only from a dead end.
            g.neighbours[node]
                .iter()
                .copied()
                .filter(|&n| Some(n) != prev || g.neighbours[node].len() == 1)
                .min_by(|&a, &b| turn_of(a).total_cmp(&turn_of(b)))
                .unwrap_or(node)
        } else {
            options[rng.index(options.len())]
        };
        if next == node {
            break;
        }
        length += (g.nodes[next] - here).norm();
        prev = Some(node);
        node = next;
        nodes.push(node);
    }
    let lane = floor_cfg.lane_offset_m;
    nodes
        .iter()
        .map(|&k| g.nodes[k] + Vector2::new(rng.uniform(-lane, lane), rng.uniform(-lane, lane)))
        .collect()
}

/// Per-walker parameters, drawn once per walk.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WalkerParams {
    /// Base cadence, steps per second.
    pub step_frequency_hz: f64,
    /// Step-length scale.
    pub step_length_scale: f64,
    /// Leg length of the inverted pendulum, metres.
    pub leg_length_m: f64,
}

/// One interval of the walker's timeline (times in seconds from the walk start).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Motion {
    /// Standing at arc length `s`.
    Stand {
        /// Start time, s.
        t0: f64,
        /// End time, s.
        t1: f64,
        /// Arc length.
        s: f64,
    },
    /// One step from `s0` to `s1`, ending with the heel strike at `t1`.
    Step {
        /// Start time, s.
        t0: f64,
        /// End time (heel strike), s.
        t1: f64,
        /// Arc length at the start.
        s0: f64,
        /// Arc length at the end.
        s1: f64,
        /// Vertical bounce of this step (peak to peak), metres.
        bounce_m: f64,
        /// Index of the step in the walk (0-based).
        index: usize,
        /// Whether the step starts from standing (its waveform ramps up).
        first_of_bout: bool,
        /// Per-step factor on the vertical acceleration amplitude.
        amplitude_factor: f64,
    },
}

impl Motion {
    /// Start time.
    pub fn t0(&self) -> f64 {
        match *self {
            Motion::Stand { t0, .. } | Motion::Step { t0, .. } => t0,
        }
    }
    /// End time.
    pub fn t1(&self) -> f64 {
        match *self {
            Motion::Stand { t1, .. } | Motion::Step { t1, .. } => t1,
        }
    }
}

/// The walker's whole timeline over a path.
#[derive(Debug, Clone, PartialEq)]
pub struct Timeline {
    /// Contiguous motions from `0` to `duration_s`.
    pub motions: Vec<Motion>,
    /// Duration, seconds.
    pub duration_s: f64,
}

/// What the walker is doing at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kinematics {
    /// Arc length along the path.
    pub s: f64,
    /// Speed along the path, m/s.
    pub speed: f64,
    /// Step phase in `[0, 1)` while walking.
    pub phase: f64,
    /// Step index while walking.
    pub step_index: usize,
    /// Step frequency while walking, Hz.
    pub step_frequency: f64,
    /// Vertical bounce of the current step, metres (0 when standing).
    pub bounce_m: f64,
    /// Waveform ramp factor in `[0, 1]` (rises over the first step of a bout).
    pub ramp: f64,
    /// Per-step factor on the vertical acceleration amplitude (1 when standing).
    pub amplitude_factor: f64,
    /// Whether walking.
    pub walking: bool,
}

impl Timeline {
    /// Draws the timeline: optional standing start, steps along the path, stops at junctions
    /// with probability `stop_probability`, standing until `duration_s` once the path ends.
    pub fn generate(
        path: &WalkPath,
        cfg: &WalkerConfig,
        params: &WalkerParams,
        duration_s: f64,
        rng: &mut ChaCha8Rng,
    ) -> Self {
        let mut motions = Vec::new();
        let mut t = 0.0;
        let mut s = 0.0;
        let stand = |motions: &mut Vec<Motion>, t: &mut f64, s: f64, d: f64| {
            let t1 = (*t + d).min(duration_s);
            if t1 > *t {
                motions.push(Motion::Stand { t0: *t, t1, s });
                *t = t1;
            }
        };
        if rng.chance(cfg.static_start_probability) {
            let d = rng.uniform(cfg.stop_duration_s[0], cfg.stop_duration_s[1]);
            stand(&mut motions, &mut t, s, d);
        }
        let leg_factor: Vec<f64> = (0..path.legs.len())
            .map(|_| {
                let r = rng.uniform(0.0, 1.0);
                if r < cfg.slow_fast_probability {
                    cfg.slow_factor
                } else if r < 2.0 * cfg.slow_fast_probability {
                    cfg.fast_factor
                } else {
                    1.0
                }
            })
            .collect();
        let mut index = 0;
        let mut first_of_bout = true;
        let mut next_corner = 0;
        while t < duration_s {
            let f = (params.step_frequency_hz
                * leg_factor[path.leg_at(s)]
                * (1.0 + cfg.step_period_jitter * rng.normal()))
            .clamp(0.5, 4.0);
            let period = 1.0 / f;
            let l = (params.step_length_scale
                * (cfg.step_length_intercept_m + cfg.step_length_slope_m_per_hz * f)
                * (1.0 + cfg.step_length_jitter * rng.normal()))
            .clamp(0.2, 1.5);
            if t + period > duration_s || s + l > path.length {
                break;
            }
            let amplitude_factor =
                (1.0 + cfg.bounce_amplitude_jitter * rng.normal()).clamp(0.5, 1.5);
            let leg = params.leg_length_m.max(l);
            let bounce_m = leg - (leg * leg - l * l / 4.0).max(0.0).sqrt();
            motions.push(Motion::Step {
                t0: t,
                t1: t + period,
                s0: s,
                s1: s + l,
                bounce_m,
                index,
                first_of_bout,
                amplitude_factor,
            });
            index += 1;
            first_of_bout = false;
            t += period;
            s += l;
            // A stop at a junction just passed (before its turn starts).
            while next_corner < path.corners.len() && path.corners[next_corner].s_start <= s {
                next_corner += 1;
                if rng.chance(cfg.stop_probability) {
                    let d = rng.uniform(cfg.stop_duration_s[0], cfg.stop_duration_s[1]);
                    stand(&mut motions, &mut t, s, d);
                    first_of_bout = true;
                }
            }
        }
        let rest = duration_s - t;
        stand(&mut motions, &mut t, s, rest);
        Self {
            motions,
            duration_s,
        }
    }

    fn motion_at(&self, t: f64) -> Option<&Motion> {
        let i = self
            .motions
            .partition_point(|m| m.t0() <= t)
            .saturating_sub(1);
        self.motions.get(i)
    }

    /// The walker's state at time `t` (seconds from the start, clamped to the timeline).
    pub fn at(&self, t: f64) -> Kinematics {
        let idle = |s| Kinematics {
            s,
            speed: 0.0,
            phase: 0.0,
            step_index: 0,
            step_frequency: 0.0,
            bounce_m: 0.0,
            ramp: 0.0,
            amplitude_factor: 1.0,
            walking: false,
        };
        match self.motion_at(t.clamp(0.0, self.duration_s)) {
            None => idle(0.0),
            Some(&Motion::Stand { s, .. }) => idle(s),
            Some(&Motion::Step {
                t0,
                t1,
                s0,
                s1,
                bounce_m,
                index,
                first_of_bout,
                amplitude_factor,
            }) => {
                let period = (t1 - t0).max(1e-6);
                let u = ((t - t0) / period).clamp(0.0, 1.0);
                let ramp = if first_of_bout {
                    0.5 - 0.5 * (std::f64::consts::PI * u).cos()
                } else {
                    1.0
                };
                Kinematics {
                    s: s0 + (s1 - s0) * u,
                    speed: (s1 - s0) / period,
                    phase: u,
                    step_index: index,
                    step_frequency: 1.0 / period,
                    bounce_m,
                    ramp,
                    amplitude_factor,
                    walking: true,
                }
            }
        }
    }

    /// The first time (seconds) at which the walker reaches arc length `s`.
    pub fn time_at_arc(&self, s: f64) -> f64 {
        for m in &self.motions {
            if let Motion::Step { t0, t1, s0, s1, .. } = *m
                && s1 >= s
            {
                if s <= s0 {
                    return t0;
                }
                return t0 + (t1 - t0) * (s - s0) / (s1 - s0).max(1e-9);
            }
        }
        // Never reached while walking: the end of the last step (or the start).
        self.motions
            .iter()
            .rev()
            .find_map(|m| match *m {
                Motion::Step { t1, .. } => Some(t1),
                _ => None,
            })
            .unwrap_or(0.0)
    }

    /// The steps, in order.
    pub fn steps(&self) -> impl Iterator<Item = &Motion> {
        self.motions
            .iter()
            .filter(|m| matches!(m, Motion::Step { .. }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng;

    #[test]
    fn rounded_path_is_continuous_and_turns_smoothly() {
        let pts = [
            Point2::new(0.0, 0.0),
            Point2::new(0.0, 10.0),
            Point2::new(10.0, 10.0),
            Point2::new(10.0, 0.0),
        ];
        let path = WalkPath::through(&pts, 1.5);
        assert_eq!(path.corners.len(), 2);
        assert!((path.corners[0].angle - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
        let mut prev = path.at(0.0);
        let mut s = 0.0;
        while s < path.length {
            s += 0.05;
            let cur = path.at(s);
            assert!((cur.0 - prev.0).norm() <= 0.0501, "jump at s = {s}");
            assert!((cur.1 - prev.1).abs() < 0.05, "heading jump at s = {s}");
            prev = cur;
        }
        let end = path.at(path.length).0;
        assert!((end - Point2::new(10.0, 0.0)).norm() < 1e-6, "{end}");
    }

    #[test]
    fn timeline_is_contiguous_with_realistic_gait() {
        let pts = [Point2::new(0.0, 0.0), Point2::new(0.0, 200.0)];
        let path = WalkPath::through(&pts, 1.5);
        let mut r = rng::stream(7, 3);
        let params = WalkerParams {
            step_frequency_hz: 1.8,
            step_length_scale: 1.0,
            leg_length_m: 0.9,
        };
        let tl = Timeline::generate(&path, &WalkerConfig::default(), &params, 60.0, &mut r);
        let mut t = 0.0;
        for m in &tl.motions {
            assert!((m.t0() - t).abs() < 1e-9);
            t = m.t1();
        }
        assert!((t - 60.0).abs() < 1e-9);
        let n = tl.steps().count();
        assert!((95..=115).contains(&n), "{n} steps in 60 s at 1.8 Hz");
        for m in tl.steps() {
            if let Motion::Step {
                s0, s1, bounce_m, ..
            } = *m
            {
                assert!((0.5..0.95).contains(&(s1 - s0)));
                assert!(bounce_m > 0.02 && bounce_m < 0.15);
            }
        }
    }
}
