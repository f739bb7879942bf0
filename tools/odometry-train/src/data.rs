//! Dataset extraction: every ILC walk's IMU windows (through `wipdr_pdr::odometry::features`,
//! the library's own code), its waypoint segments, and the step model's displacement on the
//! same segments under the evaluation's within-floor folds.

use anyhow::{Context, Result, bail};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use wipdr_core::Walk;
use wipdr_core::angle::step_displacement;
use wipdr_pdr::calibrate::{CalibrationConfig, WalkSteps, calibrate_config};
use wipdr_pdr::odometry::features::{CHANNELS, ImuGrid, WINDOW};
use wipdr_pdr::odometry::{INTERVAL_MS, rotate_heading};
use wipdr_pdr::{CheckedPdrConfig, Pdr, PdrConfig};

/// Folds of the evaluation protocol within a floor (walks sorted by id, walk i in fold i % 5).
pub const FOLDS: usize = 5;

/// Version of the dataset file: 2 added the per-window step labels (`WalkRec::dense`).
/// `load` refuses other versions (re-run `extract`).
pub const DATASET_VERSION: u32 = 2;

/// One segment between consecutive waypoints.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Segment {
    /// Start and end waypoint times, ms.
    pub t_a: i64,
    /// End waypoint time, ms.
    pub t_b: i64,
    /// Waypoint displacement in the map frame, m.
    pub truth: [f64; 2],
    /// The step model's displacement over `(t_a, t_b]` (calibrated on the walk's training
    /// folds of its floor, as the evaluation's `pdr` track), map frame, m.
    pub steps: [f64; 2],
}

/// One walk of the dataset.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct WalkRec {
    /// Floor (`site1/F1`).
    pub floor: String,
    /// Walk id.
    pub id: String,
    /// Fold within the floor.
    pub fold: usize,
    /// Heading offset (rotation vector frame -> map frame) fitted by the step model's
    /// calibration on the walk's training folds, rad: both sources use it on this walk.
    pub offset_fold: f64,
    /// Heading offset fitted on every walk of the floor, rad (training labels only).
    pub offset_floor: f64,
    /// First waypoint (time, position), the start of PDR from the true start.
    pub first_waypoint: (i64, [f64; 2]),
    /// First Wi-Fi scan time (PDR from the true start is scored after it).
    pub first_wifi: Option<i64>,
    /// Waypoints after the first: (time, position).
    pub waypoints: Vec<(i64, [f64; 2])>,
    /// The step model's position at each of `waypoints` from the true first waypoint.
    pub steps_positions: Vec<[f64; 2]>,
    /// Window end times, ms.
    pub t_end: Vec<i64>,
    /// Window frame headings, rad.
    pub heading: Vec<f64>,
    /// Window data, `t_end.len() * CHANNELS * WINDOW` values.
    pub data: Vec<f32>,
    /// Segments covered by the windows.
    pub segments: Vec<Segment>,
    /// Dense pseudo-labels, one per window: the calibrated step model's displacement over
    /// the window's output interval `(t_end - 1 s, t_end]` (the steps with `t` in it, as a
    /// segment's `steps`), turned from the map frame into the rotation vector's frame by
    /// `offset_floor` (as the segment labels, `label_rv`) and then into the window's yawed
    /// frame (forward, right), the frame of the network's first two outputs, m.
    pub dense: Vec<[f32; 2]>,
}

/// The whole dataset.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Dataset {
    /// [`DATASET_VERSION`] (first, so that an older file fails the check on load).
    pub version: u32,
    /// Floors in order.
    pub floors: Vec<String>,
    /// Walks, floor by floor, sorted by id within a floor.
    pub walks: Vec<WalkRec>,
}

/// The base PDR configuration of the evaluation (`EvalConfig::default`): the library's
/// defaults with heading snapping on (`snap = true`; off: a diagnostic).
pub fn base_pdr_snap(snap: bool) -> PdrConfig {
    let mut cfg = PdrConfig::default();
    cfg.heading.snap.enabled = snap;
    cfg
}

fn floor_dirs(root: &Path) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for site in std::fs::read_dir(root).with_context(|| format!("{}", root.display()))? {
        let site = site?.path();
        if !site.is_dir() {
            continue;
        }
        for f in std::fs::read_dir(&site)? {
            let f = f?.path();
            if f.join("path_data_files").is_dir() {
                out.push(f);
            }
        }
    }
    out.sort();
    Ok(out)
}

fn displacement_of_steps(ev: &[wipdr_core::StepEvent], t_a: i64, t_b: i64) -> [f64; 2] {
    let a = ev.partition_point(|s| s.t <= t_a);
    let b = ev.partition_point(|s| s.t <= t_b);
    let d = ev[a..b]
        .iter()
        .map(|s| step_displacement(s.length, s.heading))
        .fold(wipdr_core::Vector2::zeros(), |x, y| x + y);
    [d.x, d.y]
}

fn extract_floor(name: &str, walks: &[Walk], snap: bool) -> Result<Vec<WalkRec>> {
    let base = base_pdr_snap(snap).check().context("the base PDR config")?;
    let cal = CalibrationConfig::default();
    // walks come sorted by id: fold = rank % 5
    let runs: Vec<_> = walks
        .par_iter()
        .map(|w| Pdr::run_detailed(base, w).0)
        .collect();
    let steps_of = |keep: &dyn Fn(usize) -> bool| -> Vec<WalkSteps<'_>> {
        (0..walks.len())
            .filter(|&i| keep(i))
            .map(|i| WalkSteps {
                steps: &runs[i],
                waypoints: &walks[i].waypoints,
            })
            .collect()
    };
    let (all_cfg, _) = calibrate_config(&base, &cal, &steps_of(&|_| true));
    let offset_floor = all_cfg.heading.map_offset_rad;
    let fold_cfgs: Vec<CheckedPdrConfig> = (0..FOLDS)
        .map(|f| {
            calibrate_config(&base, &cal, &steps_of(&|i| i % FOLDS != f))
                .0
                .check()
        })
        .collect::<Result<_, _>>()
        .context("a calibrated PDR config")?;
    Ok(walks
        .par_iter()
        .enumerate()
        .filter_map(|(i, w)| {
            let fold = i % FOLDS;
            let cfg = fold_cfgs[fold];
            let events = Pdr::run(cfg, w);
            let grid = ImuGrid::from_walk(w)?;
            let wins = grid.windows();
            let (first, last) = (wins.first()?, wins.last()?);
            let (lo, hi) = (first.t_end - INTERVAL_MS, last.t_end);
            let mut rec = WalkRec {
                floor: name.to_string(),
                id: w.meta.id.clone(),
                fold,
                offset_fold: cfg.heading.map_offset_rad,
                offset_floor,
                first_waypoint: (0, [0.0; 2]),
                first_wifi: w.wifi.first().map(|s| s.t),
                waypoints: Vec::new(),
                steps_positions: Vec::new(),
                t_end: wins.iter().map(|x| x.t_end).collect(),
                heading: wins.iter().map(|x| x.heading).collect(),
                data: Vec::with_capacity(wins.len() * CHANNELS * WINDOW),
                segments: Vec::new(),
                dense: wins
                    .iter()
                    .map(|x| {
                        let d = displacement_of_steps(&events, x.t_end - INTERVAL_MS, x.t_end);
                        let d = world_to_local(x.heading, rotate_heading(d, -offset_floor));
                        [d[0] as f32, d[1] as f32]
                    })
                    .collect(),
            };
            for x in &wins {
                rec.data.extend_from_slice(&x.data);
            }
            // waypoints inside the windows' span
            let wps: Vec<_> = w
                .waypoints
                .iter()
                .filter(|p| p.t >= lo && p.t <= hi)
                .collect();
            let w0 = wps.first()?;
            rec.first_waypoint = (w0.t, [w0.position.x, w0.position.y]);
            let mut pos = [w0.position.x, w0.position.y];
            for pair in wps.windows(2) {
                let (a, b) = (pair[0], pair[1]);
                let d = displacement_of_steps(&events, a.t.max(w0.t), b.t);
                pos = [pos[0] + d[0], pos[1] + d[1]];
                rec.waypoints.push((b.t, [b.position.x, b.position.y]));
                rec.steps_positions.push(pos);
                if b.t > a.t {
                    rec.segments.push(Segment {
                        t_a: a.t,
                        t_b: b.t,
                        truth: [b.position.x - a.position.x, b.position.y - a.position.y],
                        steps: d,
                    });
                }
            }
            Some(rec)
        })
        .collect())
}

/// Reads every floor under `root` (through the io cache in `cache/io`) and extracts the
/// dataset (`snap`: the step model's heading snapping, on in the evaluation).
pub fn extract(root: &Path, cache: &Path, snap: bool) -> Result<Dataset> {
    let dirs = floor_dirs(root)?;
    if dirs.is_empty() {
        bail!("no floor folders under {}", root.display());
    }
    let mut ds = Dataset {
        version: DATASET_VERSION,
        floors: Vec::new(),
        walks: Vec::new(),
    };
    for d in dirs {
        let fd = wipdr_io::read_floor_dir_cached(&d, cache.join("io"), &Default::default())
            .with_context(|| format!("reading {}", d.display()))?;
        let name = fd.name.clone();
        let walks: Vec<Walk> = fd.walks.into_iter().map(|p| p.walk).collect();
        let recs = extract_floor(&name, &walks, snap)?;
        eprintln!(
            "{name}: {} walks read, {} kept, {} windows, {} segments",
            walks.len(),
            recs.len(),
            recs.iter().map(|r| r.t_end.len()).sum::<usize>(),
            recs.iter().map(|r| r.segments.len()).sum::<usize>()
        );
        ds.floors.push(name);
        ds.walks.extend(recs);
    }
    Ok(ds)
}

/// Writes the dataset (bincode) and returns its SHA-256.
pub fn save(ds: &Dataset, path: &Path) -> Result<String> {
    let bytes = bincode::serde::encode_to_vec(ds, bincode::config::standard())?;
    std::fs::write(path, &bytes)?;
    Ok(hex(&Sha256::digest(&bytes)))
}

/// Reads the dataset and its SHA-256.
pub fn load(path: &Path) -> Result<(Dataset, String)> {
    let bytes = std::fs::read(path).with_context(|| format!("{}", path.display()))?;
    let hash = hex(&Sha256::digest(&bytes));
    let (ds, _): (Dataset, _) =
        bincode::serde::decode_from_slice(&bytes, bincode::config::standard()).with_context(
            || {
                format!(
                    "{}: not a version {DATASET_VERSION} dataset, re-run `extract`",
                    path.display()
                )
            },
        )?;
    if ds.version != DATASET_VERSION {
        bail!(
            "{}: dataset version {}, want {DATASET_VERSION}: re-run `extract`",
            path.display(),
            ds.version
        );
    }
    Ok((ds, hash))
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// A displacement `(east, north)` in the rotation vector's frame turned into the yawed frame
/// of a window of heading `psi` (forward, right): the inverse of
/// `wipdr_pdr::odometry::features::local_to_world`.
pub fn world_to_local(psi: f64, d: [f64; 2]) -> [f64; 2] {
    let (s, c) = psi.sin_cos();
    // world = F (s, c) + R (c, -s)
    [d[0] * s + d[1] * c, d[0] * c - d[1] * s]
}

/// The label of a segment for training: the waypoint displacement turned from the map frame
/// into the rotation vector's frame by the floor's offset.
pub fn label_rv(w: &WalkRec, s: &Segment) -> [f64; 2] {
    rotate_heading(s.truth, -w.offset_floor)
}

/// The waypoint track's position at `t` (map frame), linear between consecutive waypoints;
/// `None` outside the waypoints' span.
fn track_at(w: &WalkRec, t: i64) -> Option<[f64; 2]> {
    let mut prev = w.first_waypoint;
    if t < prev.0 {
        return None;
    }
    for &(tb, pb) in &w.waypoints {
        if t <= tb {
            if tb <= prev.0 {
                return Some(pb);
            }
            let f = (t - prev.0) as f64 / (tb - prev.0) as f64;
            return Some([
                prev.1[0] + f * (pb[0] - prev.1[0]),
                prev.1[1] + f * (pb[1] - prev.1[1]),
            ]);
        }
        prev = (tb, pb);
    }
    (t == prev.0).then_some(prev.1)
}

/// Dense labels from the waypoints: the displacement of the waypoint track (linear in time
/// between consecutive waypoints) over each window's output interval, turned into the
/// window's yawed frame as `WalkRec::dense`; `None` for a window outside the waypoints' span.
pub fn truth_dense(w: &WalkRec) -> Vec<Option<[f32; 2]>> {
    w.t_end
        .iter()
        .zip(&w.heading)
        .map(|(&t, &h)| {
            let a = track_at(w, t - INTERVAL_MS)?;
            let b = track_at(w, t)?;
            let d = rotate_heading([b[0] - a[0], b[1] - a[1]], -w.offset_floor);
            let d = world_to_local(h, d);
            Some([d[0] as f32, d[1] as f32])
        })
        .collect()
}
