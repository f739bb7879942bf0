//! A folder of IPIN logfiles (one building, several floors) read as one [`FloorData`].
//!
//! The folder is `DIR` itself or `DIR/trials` when that exists; every `*.txt` / `*.txt.gz`
//! in it is a logfile ([`crate::logfile`]), read in parallel. Unreadable files are skipped
//! into [`FloorData::skipped_walks`] as for ILC floors.
//!
//! **The metre frame** ([`FloorData::geo_frame`]): a [`GeoFrame`] whose origin is the
//! south-west corner of the bounding box of every `POSI` point of the folder, moved
//! [`FRAME_MARGIN_M`] further south and west; the plan is that box grown by the margin on
//! every side (`x` east, `y` north, all coordinates positive). The plan has no outline and
//! no walls: the competition gives no floor plan. Walks keep their `POSI` floor on every
//! waypoint, so one folder holds all floors of the building.

use crate::floor::{FloorData, ReadOptions, SkippedWalk, floor_name, walk_files};
use crate::geojson::LonLatBox;
use crate::logfile::{ParsedLogfile, read_logfile};
use crate::{IoError, ParsedWalk};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use wipdr_core::{FloorPlan, GeoFrame, Point2};

/// Margin around the ground truth's bounding box, metres.
pub const FRAME_MARGIN_M: f64 = 30.0;

/// The folder holding the logfiles of `dir`: `dir/trials` when it is a folder, else `dir`.
pub fn logfile_dir(dir: &Path) -> PathBuf {
    let trials = dir.join("trials");
    if trials.is_dir() {
        trials
    } else {
        dir.to_path_buf()
    }
}

/// Whether `dir` (or `dir/trials`) holds GetSensorData logfiles: its first walk file by name
/// starts with a `%` header.
pub fn is_logfile_dir(dir: &Path) -> bool {
    walk_files(logfile_dir(dir))
        .ok()
        .and_then(|files| files.first().cloned())
        .is_some_and(crate::logfile::is_logfile)
}

/// The frame and plan size of a folder from its ground-truth points (degrees): origin
/// [`FRAME_MARGIN_M`] south-west of their bounding box.
pub fn frame_of(points: impl IntoIterator<Item = (f64, f64)>) -> Option<(GeoFrame, f64, f64)> {
    let (mut lat0, mut lon0, mut lat1, mut lon1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for (lat, lon) in points {
        lat0 = lat0.min(lat);
        lon0 = lon0.min(lon);
        lat1 = lat1.max(lat);
        lon1 = lon1.max(lon);
    }
    if lat0 > lat1 {
        return None;
    }
    let corner = GeoFrame::new(lat0, lon0).ok()?;
    let frame = corner
        .shifted_to(Point2::new(-FRAME_MARGIN_M, -FRAME_MARGIN_M))
        .ok()?;
    let far = frame.to_local(lat1, lon1);
    Some((frame, far.x + FRAME_MARGIN_M, far.y + FRAME_MARGIN_M))
}

/// Reads a folder of logfiles as one [`FloorData`] (all floors; see the module docs).
///
/// Fails when the folder has no logfile, when none can be read, or when no logfile has a
/// `POSI` point (the metre frame is placed on them).
///
/// ```no_run
/// use wipdr_io::{logfile_folder::read_logfile_dir, ReadOptions};
/// let dir = wipdr_io::data_root().join("ipin2023");
/// let data = read_logfile_dir(&dir, &ReadOptions::default()).unwrap();
/// println!("{} walks, frame {:?}", data.walks.len(), data.geo_frame);
/// ```
pub fn read_logfile_dir(dir: &Path, options: &ReadOptions) -> Result<FloorData, IoError> {
    read_logfile_dir_with_progress(dir, options, &|| {})
}

/// [`read_logfile_dir`], calling `on_walk` after each logfile is read.
pub fn read_logfile_dir_with_progress(
    dir: &Path,
    options: &ReadOptions,
    on_walk: &(dyn Fn() + Sync),
) -> Result<FloorData, IoError> {
    let folder = logfile_dir(dir);
    let files = walk_files(&folder)?;
    if files.is_empty() {
        return Err(IoError::NotAFloor {
            path: dir.to_path_buf(),
            message: "no *.txt or *.txt.gz logfile".into(),
        });
    }
    let results: Vec<Result<ParsedLogfile, IoError>> = files
        .par_iter()
        .map(|f| {
            let r = read_logfile(f, &options.limits);
            on_walk();
            r
        })
        .collect();
    let mut logs = Vec::with_capacity(results.len());
    let mut skipped_walks = Vec::new();
    let mut first_error = None;
    for (file, result) in files.iter().zip(results) {
        match result {
            Ok(log) => logs.push(log),
            Err(e) if options.strict => return Err(e),
            Err(e) => {
                let skip = SkippedWalk::new(file, &e);
                tracing::warn!(file = %file.display(), error = %skip.error, "logfile skipped");
                skipped_walks.push(skip);
                first_error.get_or_insert(e);
            }
        }
    }
    if logs.is_empty()
        && let Some(first) = first_error
    {
        return Err(IoError::NoReadableWalk {
            path: dir.to_path_buf(),
            files: files.len(),
            first: Box::new(first),
        });
    }
    let (frame, width, height) = frame_of(
        logs.iter()
            .flat_map(|l| l.ground_truth.iter().map(|g| (g.lat_deg, g.lon_deg))),
    )
    .ok_or_else(|| IoError::NotAFloor {
        path: dir.to_path_buf(),
        message: "no POSI ground truth in any logfile: the metre frame is placed on it".into(),
    })?;
    let plan =
        FloorPlan::new(width, height, Vec::new(), Vec::new()).map_err(|e| IoError::Invalid {
            path: dir.to_path_buf(),
            field: "POSI latitude/longitude".into(),
            message: e.to_string(),
        })?;
    let (south, west) = frame.to_lat_lon(Point2::new(0.0, 0.0));
    let (north, east) = frame.to_lat_lon(Point2::new(width, height));
    let mut walks: Vec<ParsedWalk> = logs.into_iter().map(|l| l.into_walk(&frame)).collect();
    walks.sort_by(|a, b| a.walk.meta.id.cmp(&b.walk.meta.id));
    tracing::info!(folder = %folder.display(), walks = walks.len(), skipped = skipped_walks.len(), "logfile folder read");
    Ok(FloorData {
        name: floor_name(dir),
        dir: dir.to_path_buf(),
        width,
        height,
        plan,
        lonlat_box: LonLatBox {
            min_lon: west,
            min_lat: south,
            max_lon: east,
            max_lat: north,
        },
        skipped_features: 0,
        walks,
        skipped_walks,
        geo_frame: Some(frame),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_frame_puts_every_point_inside_the_margin() {
        let pts = [(49.4610, 11.1100), (49.4615, 11.1120), (49.4612, 11.1105)];
        let (frame, w, h) = frame_of(pts).unwrap();
        // Moving the origin changes the radii of curvature a little: sub-millimetre here.
        let tol = 1e-3;
        for (lat, lon) in pts {
            let p = frame.to_local(lat, lon);
            assert!(
                p.x >= FRAME_MARGIN_M - tol && p.x <= w - FRAME_MARGIN_M + tol,
                "{p:?}"
            );
            assert!(
                p.y >= FRAME_MARGIN_M - tol && p.y <= h - FRAME_MARGIN_M + tol,
                "{p:?}"
            );
        }
        assert!(frame_of(std::iter::empty()).is_none());
    }

    #[test]
    fn a_folder_reads_with_skips_and_a_frame() {
        let dir = std::env::temp_dir().join(format!("wipdr-logfolder-{}", std::process::id()));
        let trials = dir.join("trials");
        std::fs::create_dir_all(&trials).unwrap();
        std::fs::write(
            trials.join("X_Trial01_repetition01.txt"),
            "% GetSensorData\nPOSI;1;1;49.4611;11.1109;0;100\nPOSI;9;2;49.4612;11.1110;0;100\n",
        )
        .unwrap();
        std::fs::write(
            trials.join("X_Trial02_repetition01.txt"),
            format!("% h\n{}\n", "x".repeat(100)),
        )
        .unwrap();
        let options = ReadOptions {
            limits: crate::Limits {
                max_line_bytes: 64,
                ..Default::default()
            },
            strict: false,
        };
        assert!(is_logfile_dir(&dir));
        let data = read_logfile_dir(&dir, &options).unwrap();
        assert_eq!(data.walks.len(), 1);
        assert_eq!(data.skipped_walks.len(), 1);
        let w = &data.walks[0].walk;
        assert_eq!(w.meta.route.as_deref(), Some("Trial01"));
        assert_eq!(w.waypoints[0].floor, Some(0));
        assert!((w.waypoints[0].position.x - FRAME_MARGIN_M).abs() < 1e-3);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
