//! Survey guidance: where a site model is weak, so that a surveyor knows where to walk next.
//!
//! Three measures per floor, on a raster over the floor:
//!
//! - the **expected Wi-Fi error**: each training walk left out of the radio map in turn, its
//!   scans located by the map of the other walks ([`leave_one_walk_out`]; on a site of many
//!   walks, groups of walks left out together; measured at fit time and saved in the
//!   model), interpolated between the scans by inverse distance and left blank farther than
//!   [`SurveySettings::error_radius_m`] from any of them;
//! - the **distance to the nearest measured reference point** on the floor;
//! - the **APs heard** at that nearest reference point.
//!
//! Only the radio map and the matcher are fit again for each left-out walk (not the PDR
//! calibration, the barometric references or the trails): the Wi-Fi error is what the
//! matcher alone gives, without PDR. The scans are located as a stream of fixes without
//! steps ([`ScanContext::default`]), by the model's matcher and query filter.

use super::fit::{TrainingData, fit_radio_map};
use super::{SiteConfig, SiteModel, SiteModelError};
use rayon::prelude::*;
use rstar::RTree;
use rstar::primitives::GeomWithData;
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use wipdr_core::{GridSpec, Point2, Walk};
use wipdr_fingerprint::ScanContext;

/// Most leave-one-out points a model keeps: beyond it the points are thinned evenly (every
/// n-th in walk and time order). 20,000 points are 0.6 MB in the model file and more than
/// one every square metre of an ILC floor (the two ILC sites' 5 floors have about 10,000
/// scans together: `wipdr inspect s1.wipdr` prints the count).
pub const MAX_LEAVE_OUT_POINTS: usize = 20_000;

/// A training scan located by the radio map fit without its walk.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LeaveOutPoint {
    /// The true position at the scan's time (interpolated between the walk's waypoints).
    pub position: Point2,
    /// The true floor at the scan's time, where known.
    pub floor: Option<i32>,
    /// 2D distance from the fix to `position`, metres.
    pub error_m: f64,
}

/// The leave-one-walk-out Wi-Fi errors of a fit ([`leave_one_walk_out`]).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct LeaveOneOut {
    /// The located scans (at most [`MAX_LEAVE_OUT_POINTS`], thinned evenly beyond).
    pub points: Vec<LeaveOutPoint>,
    /// Radio maps fit: the walks were left out in this many groups (one walk each when
    /// there were no more walks than groups).
    pub groups: usize,
    /// Walks left out and located.
    pub walks: usize,
    /// Walks whose other walks gave no radio map (too few data), not located.
    pub skipped_walks: usize,
    /// Scans located (before thinning).
    pub scans: usize,
    /// Scans the map of the other walks could not match (no AP of the scan in it).
    pub unmatched_scans: usize,
}

impl LeaveOneOut {
    /// Checks a decoded value: at most [`MAX_LEAVE_OUT_POINTS`] points, finite positions,
    /// finite non-negative errors.
    pub fn validate(&self) -> Result<(), String> {
        if self.points.len() > MAX_LEAVE_OUT_POINTS {
            return Err(format!(
                "{} points, more than {MAX_LEAVE_OUT_POINTS}",
                self.points.len()
            ));
        }
        for (i, p) in self.points.iter().enumerate() {
            if !(p.position.x.is_finite() && p.position.y.is_finite()) {
                return Err(format!("point {i}: position not finite"));
            }
            if !(p.error_m.is_finite() && p.error_m >= 0.0) {
                return Err(format!(
                    "point {i}: error {} m is not finite and >= 0",
                    p.error_m
                ));
            }
        }
        Ok(())
    }

    /// The errors of the points on `floor` (every point when `floor` is `None`; a point
    /// without a floor counts on every floor), sorted.
    pub fn sorted_errors(&self, floor: Option<i32>) -> Vec<f64> {
        let mut e: Vec<f64> = self
            .points
            .iter()
            .filter(|p| on_floor(p.floor, floor))
            .map(|p| p.error_m)
            .collect();
        e.sort_by(f64::total_cmp);
        e
    }
}

/// Whether something on `at` counts on `floor` (a missing floor on either side matches).
fn on_floor(at: Option<i32>, floor: Option<i32>) -> bool {
    match (at, floor) {
        (Some(a), Some(f)) => a == f,
        _ => true,
    }
}

/// What one left-out walk gave.
#[derive(Default)]
struct WalkOut {
    points: Vec<LeaveOutPoint>,
    unmatched: usize,
    skipped: bool,
}

/// Most radio maps [`leave_one_walk_out`] fits by default: up to this many walks each is
/// left out alone; a site with more walks is split into this many interleaved groups left
/// out in turn, as many as the evaluation protocol's folds (`wipdr_eval::fold_rules::FOLDS`), so
/// that the errors compare with the `wifi` rows of `wipdr eval`. On `ilc20/site1` (208
/// walks, two cores shared with other builds) one map per walk ran for over 10 minutes
/// before it was stopped; 10 groups took 77 s, 5 groups 64 s, beside a fit of 10 to 24 s
/// (`wipdr fit --data $WIPDR_DATA/ilc20/site1 --out s1.wipdr [--leave-out-groups 10]`
/// prints both).
pub const DEFAULT_LEAVE_OUT_GROUPS: usize = 5;

/// Leaves the training walks out in turn: fits the radio map of the other walks under
/// `config.fit` (interpolation and path-loss extension included), builds
/// `config.positioner.matcher` on it and locates the left-out walks' scans with
/// `config.positioner.query`, each walk as its own stream; a scan's error is the distance
/// from the fix to the walk's true position at the scan's time.
///
/// With at most `max_groups` walks, each walk is left out alone (leave one walk out); with
/// more, walk `i` (in the given order) is in group `i mod max_groups` and each group is left
/// out together, so that no more than `max_groups` maps are fit (in parallel, rayon). A
/// group whose other walks give no radio map counts its walks in
/// [`LeaveOneOut::skipped_walks`]; a site of one walk, or one fit from a survey table, has
/// nothing to leave out (an empty result). Errors only on an invalid config or a
/// `max_groups` below 2.
pub fn leave_one_walk_out(
    data: &TrainingData<'_>,
    config: &SiteConfig,
    max_groups: usize,
) -> Result<LeaveOneOut, SiteModelError> {
    config.positioner.validate()?;
    if max_groups < 2 {
        return Err(SiteModelError::Survey(format!(
            "leave-one-out groups: {max_groups}, must be at least 2"
        )));
    }
    if data.survey.is_some() && !data.walks.is_empty() {
        return Err(SiteModelError::WalksAndSurvey);
    }
    if data.walks.len() < 2 {
        return Ok(LeaveOneOut::default());
    }
    let groups = data.walks.len().min(max_groups);
    let mut outs: Vec<(usize, WalkOut)> = (0..groups)
        .into_par_iter()
        .flat_map_iter(|g| leave_out_group(data, config, groups, g))
        .collect();
    outs.sort_by_key(|(i, _)| *i);
    let mut all = LeaveOneOut {
        groups,
        ..LeaveOneOut::default()
    };
    let mut points = Vec::new();
    for (_, out) in outs {
        if out.skipped {
            all.skipped_walks += 1;
            continue;
        }
        all.walks += 1;
        all.unmatched_scans += out.unmatched;
        points.extend(out.points);
    }
    all.scans = points.len();
    let step = points.len().div_ceil(MAX_LEAVE_OUT_POINTS).max(1);
    all.points = points.into_iter().step_by(step).collect();
    tracing::info!(
        site = data.name,
        groups,
        walks = all.walks,
        skipped = all.skipped_walks,
        scans = all.scans,
        kept = all.points.len(),
        "leave-one-walk-out Wi-Fi errors"
    );
    Ok(all)
}

/// The walks of group `g` of `groups` (walk `i` in group `i mod groups`), each located by
/// the map of the walks outside the group: `(walk index, what it gave)`.
fn leave_out_group(
    data: &TrainingData<'_>,
    config: &SiteConfig,
    groups: usize,
    g: usize,
) -> Vec<(usize, WalkOut)> {
    let left_out: Vec<usize> = (g..data.walks.len()).step_by(groups).collect();
    let others: Vec<&Walk> = data
        .walks
        .iter()
        .enumerate()
        .filter(|&(j, _)| j % groups != g)
        .map(|(_, w)| *w)
        .collect();
    let sub = TrainingData {
        walks: &others,
        survey: None,
        ..*data
    };
    let skipped = |reason: String| {
        tracing::debug!(site = data.name, group = g, %reason, "walks not left out");
        left_out
            .iter()
            .map(|&i| {
                (
                    i,
                    WalkOut {
                        skipped: true,
                        ..WalkOut::default()
                    },
                )
            })
            .collect()
    };
    let learned = match fit_radio_map(&sub, &config.fit) {
        Ok(l) => l,
        Err(e) => return skipped(e.to_string()),
    };
    let matcher = match config.positioner.matcher.build(Arc::new(learned.map)) {
        Ok(m) => m,
        Err(e) => return skipped(e.to_string()),
    };
    left_out
        .iter()
        .map(|&i| {
            let walk: &Walk = data.walks[i];
            let mut stream = matcher.stream(config.positioner.query);
            let mut out = WalkOut::default();
            for scan in &walk.wifi {
                let Some(truth) = walk.position_at(scan.t) else {
                    continue;
                };
                match stream.locate_online(scan, &ScanContext::default()) {
                    Ok(obs) => {
                        let error_m = (obs.estimate - truth).norm();
                        if error_m.is_finite() {
                            out.points.push(LeaveOutPoint {
                                position: truth,
                                floor: walk.floor_at(scan.t),
                                error_m,
                            });
                        }
                    }
                    Err(_) => out.unmatched += 1,
                }
            }
            (i, out)
        })
        .collect()
}

/// How the survey rasters of a floor are made ([`floor_survey`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurveySettings {
    /// Raster cell, metres.
    pub cell_m: f64,
    /// The expected error is interpolated from the leave-one-out points within this
    /// distance of a cell's centre, and left blank where there is none.
    pub error_radius_m: f64,
    /// Most raster cells (checked before allocating).
    pub max_cells: usize,
}

impl Default for SurveySettings {
    /// 1 m cells; a 5 m interpolation radius: a walk's scans lie a metre or two apart along
    /// it and neighbouring corridors a few metres apart, so the error measured along one
    /// corridor says little about places more than 5 m from it. At most 4 million cells.
    fn default() -> Self {
        Self {
            cell_m: 1.0,
            error_radius_m: 5.0,
            max_cells: 4_000_000,
        }
    }
}

/// The survey rasters of one floor (cells in [`GridSpec`] order; `None`: no value there).
#[derive(Debug, Clone, PartialEq)]
pub struct FloorSurvey {
    /// The floor (`None`: a model without floor numbers).
    pub floor: Option<i32>,
    /// The raster: the floor plan's box and the floor's points, with a margin.
    pub grid: GridSpec,
    /// Whether each cell's centre is inside the plan's outline (every cell without an
    /// outline).
    pub inside: Vec<bool>,
    /// Expected Wi-Fi error (metres) from the leave-one-out points within
    /// [`SurveySettings::error_radius_m`], weighted by inverse squared distance.
    pub expected_error_m: Vec<Option<f64>>,
    /// Distance to the nearest measured reference point on the floor, metres.
    pub distance_m: Vec<Option<f64>>,
    /// APs heard at the nearest measured reference point on the floor.
    pub aps_heard: Vec<Option<u32>>,
    /// The floor's measured reference points.
    pub reference_points: Vec<Point2>,
}

impl FloorSurvey {
    /// The share (0..1) of the cells inside the outline whose nearest reference point lies
    /// farther than `gap_m`, and the area (m²) it covers.
    pub fn farther_than(&self, gap_m: f64) -> (f64, f64) {
        let (mut inside, mut far) = (0usize, 0usize);
        for (d, &i) in self.distance_m.iter().zip(&self.inside) {
            if !i {
                continue;
            }
            inside += 1;
            if d.is_none_or(|d| d > gap_m) {
                far += 1;
            }
        }
        let cell_area = self.grid.cell_m() * self.grid.cell_m();
        let share = if inside == 0 {
            0.0
        } else {
            far as f64 / inside as f64
        };
        (share, far as f64 * cell_area)
    }
}

/// The floors a survey covers: the model's floors (or one unnumbered floor).
pub fn survey_floors(model: &SiteModel) -> Vec<Option<i32>> {
    let d = model.data();
    let mut floors: Vec<i32> = d.measured.iter().filter_map(|p| p.floor).collect();
    floors.extend(d.floors.iter().copied());
    floors.sort_unstable();
    floors.dedup();
    if floors.is_empty() {
        vec![None]
    } else {
        floors.into_iter().map(Some).collect()
    }
}

type Indexed = GeomWithData<[f64; 2], usize>;

/// The survey rasters of `floor` of `model`. Errors on a bad setting or a raster over
/// `settings.max_cells`.
pub fn floor_survey(
    model: &SiteModel,
    floor: Option<i32>,
    settings: &SurveySettings,
) -> Result<FloorSurvey, SiteModelError> {
    let bad = |reason: String| SiteModelError::Survey(reason);
    if !(settings.cell_m.is_finite() && settings.cell_m > 0.0) {
        return Err(bad(format!("cell {} m: must be > 0", settings.cell_m)));
    }
    if !(settings.error_radius_m.is_finite() && settings.error_radius_m > 0.0) {
        return Err(bad(format!(
            "error radius {} m: must be > 0",
            settings.error_radius_m
        )));
    }
    let d = model.data();
    let map = model.radio_map();
    // The measured points are the first of the map's (the extension appends its own).
    let refs: Vec<(Point2, Option<u32>)> = d
        .measured
        .iter()
        .enumerate()
        .filter(|(_, p)| on_floor(p.floor, floor))
        .map(|(i, p)| {
            let aps = (i < map.len() && map.point(i).position == p.position)
                .then(|| u32::try_from(map.heard(i).count()).unwrap_or(u32::MAX));
            (p.position, aps)
        })
        .collect();
    let loo: Vec<&LeaveOutPoint> = d
        .leave_one_out
        .iter()
        .flat_map(|l| &l.points)
        .filter(|p| on_floor(p.floor, floor))
        .collect();
    // The raster: the plan's box and every point of the floor, 2 m around.
    let mut lo = Point2::new(f64::INFINITY, f64::INFINITY);
    let mut hi = Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
    let mut grow = |p: Point2| {
        if p.x.is_finite() && p.y.is_finite() {
            lo = Point2::new(lo.x.min(p.x), lo.y.min(p.y));
            hi = Point2::new(hi.x.max(p.x), hi.y.max(p.y));
        }
    };
    if let Some(plan) = &d.plan
        && plan.width > 0.0
        && plan.height > 0.0
    {
        grow(Point2::new(0.0, 0.0));
        grow(Point2::new(plan.width, plan.height));
    }
    refs.iter().for_each(|r| grow(r.0));
    loo.iter().for_each(|p| grow(p.position));
    if !(lo.x <= hi.x && lo.y <= hi.y) {
        return Err(bad(format!(
            "floor {floor:?}: no plan and no point to draw"
        )));
    }
    let margin = nalgebra::Vector2::new(2.0, 2.0);
    let grid = GridSpec::covering(
        lo - margin,
        hi + margin,
        settings.cell_m,
        settings.max_cells,
    )
    .map_err(|e| bad(format!("floor {floor:?}: raster: {e}")))?;
    let inside: Vec<bool> = (0..grid.len())
        .map(|i| {
            let c = grid.centre_of_index(i);
            d.plan
                .as_ref()
                .is_none_or(|p| p.outline.is_empty() || p.inside_outline(c))
        })
        .collect();
    let ref_tree: RTree<Indexed> = RTree::bulk_load(
        refs.iter()
            .enumerate()
            .map(|(i, r)| GeomWithData::new([r.0.x, r.0.y], i))
            .collect(),
    );
    let loo_tree: RTree<Indexed> = RTree::bulk_load(
        loo.iter()
            .enumerate()
            .map(|(i, p)| GeomWithData::new([p.position.x, p.position.y], i))
            .collect(),
    );
    let r2 = settings.error_radius_m * settings.error_radius_m;
    let cells: Vec<(Option<f64>, Option<f64>, Option<u32>)> = (0..grid.len())
        .into_par_iter()
        .map(|i| {
            let c = grid.centre_of_index(i);
            let q = [c.x, c.y];
            let nearest = ref_tree
                .nearest_neighbor_iter_with_distance_2(&q)
                .next()
                .map(|(p, d2)| (p.data, d2.sqrt()));
            let error = idw(loo_tree.locate_within_distance(q, r2).map(|p| {
                let dx = p.geom()[0] - c.x;
                let dy = p.geom()[1] - c.y;
                (dx * dx + dy * dy, loo[p.data].error_m)
            }));
            (
                error,
                nearest.map(|(_, d)| d),
                nearest.and_then(|(j, _)| refs[j].1),
            )
        })
        .collect();
    let mut survey = FloorSurvey {
        floor,
        grid,
        inside,
        expected_error_m: Vec::with_capacity(cells.len()),
        distance_m: Vec::with_capacity(cells.len()),
        aps_heard: Vec::with_capacity(cells.len()),
        reference_points: refs.iter().map(|r| r.0).collect(),
    };
    for (e, dist, aps) in cells {
        survey.expected_error_m.push(e);
        survey.distance_m.push(dist);
        survey.aps_heard.push(aps);
    }
    Ok(survey)
}

/// The inverse-squared-distance mean of `(squared distance, value)` pairs; a value at
/// (almost) zero distance is taken as it is. `None` without pairs.
fn idw(pairs: impl Iterator<Item = (f64, f64)>) -> Option<f64> {
    /// Squared distances below this (1 mm²) count as zero: the weight would overflow.
    const AT_POINT_M2: f64 = 1e-6;
    let (mut sw, mut swv, mut at, mut n_at) = (0.0, 0.0, 0.0, 0usize);
    for (d2, v) in pairs {
        if d2 < AT_POINT_M2 {
            at += v;
            n_at += 1;
        } else {
            let w = 1.0 / d2;
            sw += w;
            swv += w * v;
        }
    }
    if n_at > 0 {
        Some(at / n_at as f64)
    } else if sw > 0.0 {
        Some(swv / sw)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wipdr_core::{Bssid, Waypoint, WifiEntry, WifiScan};

    /// A walk along y = `y` from x = 0 to 20 (a waypoint and a scan every second, one metre
    /// apart), hearing two APs whose RSSI changes with x (and a third with y).
    fn corridor(id: &str, y: f64) -> Walk {
        let mut walk = Walk::default();
        walk.meta.id = id.into();
        for i in 0..=20 {
            let (t, x) = (1000 * i64::from(i), f64::from(i));
            walk.waypoints.push(Waypoint::new(t, Point2::new(x, y)));
            walk.wifi.push(WifiScan {
                t,
                entries: vec![
                    WifiEntry::new(Bssid(1), -40.0 - 2.0 * x).seen_at(t),
                    WifiEntry::new(Bssid(2), -80.0 + 2.0 * x).seen_at(t),
                    WifiEntry::new(Bssid(3), -50.0 - 2.0 * y).seen_at(t),
                ],
            });
        }
        walk
    }

    /// The radio map of the measured fingerprints alone and a 1-NN matcher: a walk left out
    /// is located at the nearest point of the other walk by signal, whose position is known.
    fn nearest_neighbour_config() -> SiteConfig {
        let mut cfg = SiteConfig {
            fit: super::super::SiteFitConfig::paper(),
            ..SiteConfig::default()
        };
        cfg.fit.calibrate_pdr = false;
        cfg.positioner.matcher =
            wipdr_fingerprint::MatcherConfig::Wknn(wipdr_fingerprint::KnnConfig {
                k: 1,
                ..Default::default()
            });
        cfg
    }

    /// Two identical corridors 4 m apart: each scan of one walk matches the scan at the same
    /// x of the other (the same RSSI but for the third AP), 4 m away; so every error is 4 m.
    #[test]
    fn each_walk_is_located_by_the_map_of_the_others() {
        let (a, b) = (corridor("a", 0.0), corridor("b", 4.0));
        let walks = [&a, &b];
        let data = TrainingData {
            name: "two corridors",
            walks: &walks,
            ..Default::default()
        };
        let loo = leave_one_walk_out(&data, &nearest_neighbour_config(), 10).unwrap();
        assert_eq!(
            (loo.walks, loo.skipped_walks, loo.unmatched_scans),
            (2, 0, 0)
        );
        assert_eq!(loo.scans, 42);
        assert_eq!(loo.points.len(), 42);
        for p in &loo.points {
            assert!((p.error_m - 4.0).abs() < 1e-9, "{p:?}");
        }
        // The points sit where the left-out walk truly was.
        assert_eq!(loo.points[0].position, Point2::new(0.0, 0.0));
        assert_eq!(loo.points[21].position, Point2::new(0.0, 4.0));
        loo.validate().unwrap();
        // One walk: nothing to leave out.
        let one = TrainingData {
            walks: &walks[..1],
            ..data
        };
        let loo = leave_one_walk_out(&one, &nearest_neighbour_config(), 10).unwrap();
        assert_eq!(loo, LeaveOneOut::default());
        assert!(leave_one_walk_out(&data, &nearest_neighbour_config(), 1).is_err());
    }

    /// Corridors at y = 0, 16 and 4 in two groups: walks 0 and 2 (y = 0 and 4) are left
    /// out together and located on walk 1's corridor (16 and 12 m off); walk 1 alone, on
    /// the nearer of the other two (y = 4, 12 m off). Left out one by one, walks 0 and 2
    /// would find each other 4 m away.
    #[test]
    fn more_walks_than_groups_are_left_out_in_interleaved_groups() {
        let walks = [corridor("a", 0.0), corridor("b", 16.0), corridor("c", 4.0)];
        let refs: Vec<&Walk> = walks.iter().collect();
        let data = TrainingData {
            name: "three corridors",
            walks: &refs,
            ..Default::default()
        };
        let loo = leave_one_walk_out(&data, &nearest_neighbour_config(), 2).unwrap();
        assert_eq!((loo.groups, loo.walks, loo.scans), (2, 3, 63));
        let errors: Vec<f64> = loo.points.iter().map(|p| p.error_m).collect();
        for (k, e) in errors.iter().enumerate() {
            let expected = if k < 21 { 16.0 } else { 12.0 };
            assert!((e - expected).abs() < 1e-9, "scan {k}: {e}");
        }
        let one_by_one = leave_one_walk_out(&data, &nearest_neighbour_config(), 3).unwrap();
        assert_eq!(one_by_one.groups, 3);
        assert!((one_by_one.points[0].error_m - 4.0).abs() < 1e-9);
    }

    #[test]
    fn the_stored_errors_are_checked() {
        let point = |error_m| LeaveOutPoint {
            position: Point2::new(1.0, 2.0),
            floor: None,
            error_m,
        };
        for bad in [f64::NAN, -1.0, f64::INFINITY] {
            let loo = LeaveOneOut {
                points: vec![point(bad)],
                ..Default::default()
            };
            assert!(loo.validate().is_err(), "{bad}");
        }
        let many = LeaveOneOut {
            points: vec![point(1.0); MAX_LEAVE_OUT_POINTS + 1],
            ..Default::default()
        };
        assert!(many.validate().unwrap_err().contains("more than"));
    }

    #[test]
    fn inverse_distance_weights_the_nearer_value_more_and_takes_a_value_at_the_centre() {
        assert_eq!(idw(std::iter::empty()), None);
        // Distances 1 and 2 (squared 1 and 4): weights 1 and 1/4.
        let v = idw([(1.0, 2.0), (4.0, 7.0)].into_iter()).unwrap();
        assert!((v - (2.0 + 7.0 / 4.0) / 1.25).abs() < 1e-12, "{v}");
        assert_eq!(idw([(0.0, 3.0), (1.0, 100.0)].into_iter()), Some(3.0));
    }

    /// The rasters of a fitted model: the expected error is 4 m along both corridors (and
    /// blank far from them), the distance to the nearest reference point grows away from
    /// them, every reference point hears the three APs.
    #[test]
    fn floor_rasters_follow_the_points() {
        let (a, b) = (corridor("a", 0.0), corridor("b", 4.0));
        let walks = [&a, &b];
        let plan = wipdr_core::FloorPlan::rectangle(20.0, 14.0).unwrap();
        let data = TrainingData {
            name: "two corridors",
            walks: &walks,
            plan: Some(&plan),
            ..Default::default()
        };
        let cfg = nearest_neighbour_config();
        let mut model = SiteModel::fit(&data, &cfg).unwrap();
        model
            .set_leave_one_out(Some(leave_one_walk_out(&data, &cfg, 10).unwrap()))
            .unwrap();
        let floors = survey_floors(&model);
        assert_eq!(floors, vec![None]);
        let s = floor_survey(&model, None, &SurveySettings::default()).unwrap();
        let at = |x: f64, y: f64| s.grid.index_of(Point2::new(x, y)).unwrap();
        let e = s.expected_error_m[at(10.2, 0.3)].unwrap();
        assert!((e - 4.0).abs() < 1e-9, "{e}");
        assert_eq!(s.expected_error_m[at(10.2, 11.9)], None);
        let d = s.distance_m[at(10.0, 12.0)].unwrap();
        assert!(d > 7.0 && d < 9.0, "{d}");
        assert_eq!(s.aps_heard[at(10.0, 12.0)], Some(3));
        assert_eq!(s.reference_points.len(), 42);
        let (share, area) = s.farther_than(5.0);
        assert!(share > 0.0 && share < 1.0 && area > 0.0, "{share} {area}");
        let bad = SurveySettings {
            cell_m: 0.0,
            ..SurveySettings::default()
        };
        assert!(floor_survey(&model, None, &bad).is_err());
        // A NaN error (a damaged or crafted model) is refused, by the setter and on load.
        let mut loo = model.data().leave_one_out.clone().unwrap();
        loo.points[3].error_m = f64::NAN;
        assert!(matches!(
            model.clone().set_leave_one_out(Some(loo.clone())),
            Err(SiteModelError::Survey(_))
        ));
        let mut data = model.data().clone();
        data.leave_one_out = Some(loo);
        let e = SiteModel::from_data(data, None).unwrap_err();
        assert!(e.to_string().contains("point 3"), "{e}");
    }
}
