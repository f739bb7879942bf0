//! ILC floor folders: `floor_info.json`, `geojson_map.json` and `path_data_files/*.txt[.gz]`.

use crate::geojson::{self, LonLatBox};
use crate::trace::{self, ParseReport, ParsedWalk};
use crate::{IoError, Limits};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::path::{Path, PathBuf};
use wipdr_core::FloorPlan;

/// The floor size file.
pub const FLOOR_INFO: &str = "floor_info.json";
/// The floor plan file.
pub const GEOJSON_MAP: &str = "geojson_map.json";
/// The folder of walk traces.
pub const WALKS_DIR: &str = "path_data_files";

/// How to read a floor folder.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct ReadOptions {
    /// Resource limits per file.
    pub limits: Limits,
}

/// Everything in one floor folder, parsed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FloorData {
    /// Display name: the folder name with its parent (`site1/F1`).
    pub name: String,
    /// The folder.
    pub dir: PathBuf,
    /// Floor width (x extent), metres.
    pub width: f64,
    /// Floor height (y extent), metres.
    pub height: f64,
    /// The floor plan in metres.
    pub plan: FloorPlan,
    /// The GeoJSON bounding box mapped onto `[0, width] x [0, height]`.
    pub lonlat_box: LonLatBox,
    /// GeoJSON features skipped (not polygons, degenerate).
    pub skipped_features: usize,
    /// The walks, sorted by walk id.
    pub walks: Vec<ParsedWalk>,
}

impl FloorData {
    /// The parse reports of all walks added up (line numbers are per walk and not merged).
    pub fn total_report(&self) -> ParseReport {
        let mut total = ParseReport::default();
        for w in &self.walks {
            total.merge_counts(&w.report);
        }
        total
    }
}

/// A display name for a floor folder: `parent/name`.
pub fn floor_name(dir: &Path) -> String {
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| dir.display().to_string());
    match dir.parent().and_then(Path::file_name) {
        Some(parent) => format!("{}/{name}", parent.to_string_lossy()),
        None => name,
    }
}

/// Reads `floor_info.json`: `(width, height)` in metres from `map_info`.
pub fn read_floor_info(path: impl AsRef<Path>, limits: &Limits) -> Result<(f64, f64), IoError> {
    let path = path.as_ref();
    let value = geojson::read_json_bounded(path, limits.max_json_bytes)?;
    let get = |key: &str| -> Result<f64, IoError> {
        let field = format!("map_info.{key}");
        let v = value
            .get("map_info")
            .and_then(|m| m.get(key))
            .ok_or_else(|| IoError::invalid(path, &field, "missing"))?;
        match v.as_f64() {
            Some(x) if x.is_finite() && x > 0.0 => Ok(x),
            _ => Err(IoError::invalid(
                path,
                &field,
                format!("expected a positive number, found {v}"),
            )),
        }
    };
    Ok((get("width")?, get("height")?))
}

/// Writes `floor_info.json`: `{"map_info": {"height": h, "width": w}}`.
pub fn write_floor_info(path: impl AsRef<Path>, width: f64, height: f64) -> Result<(), IoError> {
    let path = path.as_ref();
    if !(width.is_finite() && height.is_finite() && width > 0.0 && height > 0.0) {
        return Err(IoError::Unwritable {
            field: "map_info".into(),
            message: format!("invalid floor size {width} x {height}"),
        });
    }
    let value: Value = serde_json::json!({"map_info": {"height": height, "width": width}});
    let text = serde_json::to_string_pretty(&value).map_err(|e| IoError::file(path, e.into()))?;
    std::fs::write(path, text).map_err(|e| IoError::file(path, e))
}

/// The walk traces of a floor folder (`path_data_files/*.txt` and `*.txt.gz`, or the folder
/// itself when it has no `path_data_files`), sorted by file name.
pub fn walk_files(dir: impl AsRef<Path>) -> Result<Vec<PathBuf>, IoError> {
    let dir = dir.as_ref();
    let walks = dir.join(WALKS_DIR);
    let walks = if walks.is_dir() {
        walks
    } else {
        dir.to_path_buf()
    };
    let entries = std::fs::read_dir(&walks).map_err(|e| IoError::file(&walks, e))?;
    let mut files = Vec::new();
    for entry in entries {
        let path = entry.map_err(|e| IoError::file(&walks, e))?.path();
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        if (name.ends_with(".txt") || name.ends_with(".txt.gz")) && path.is_file() {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

/// Reads a whole floor folder; the walks in parallel (rayon).
///
/// ```no_run
/// use wipdr_io::floor::{read_floor_dir, ReadOptions};
/// let floor = read_floor_dir("../shared/data/ilc20/site1/F1", &ReadOptions::default()).unwrap();
/// println!("{}: {} walks, {} units", floor.name, floor.walks.len(), floor.plan.units.len());
/// ```
pub fn read_floor_dir(dir: impl AsRef<Path>, options: &ReadOptions) -> Result<FloorData, IoError> {
    read_floor_dir_with_progress(dir, options, &|| {})
}

/// [`read_floor_dir`], calling `on_walk` after each walk is read (for progress bars).
pub fn read_floor_dir_with_progress(
    dir: impl AsRef<Path>,
    options: &ReadOptions,
    on_walk: &(dyn Fn() + Sync),
) -> Result<FloorData, IoError> {
    let dir = dir.as_ref();
    let info = dir.join(FLOOR_INFO);
    let map = dir.join(GEOJSON_MAP);
    for needed in [&info, &map] {
        if !needed.is_file() {
            return Err(IoError::NotAFloor {
                path: dir.to_path_buf(),
                message: format!(
                    "no {}",
                    needed.file_name().unwrap_or_default().to_string_lossy()
                ),
            });
        }
    }
    let limits = &options.limits;
    let (width, height) = read_floor_info(&info, limits)?;
    let plan_read = geojson::read_floor_plan(&map, width, height, limits)?;
    let files = walk_files(dir)?;
    let mut walks = files
        .par_iter()
        .map(|f| {
            let w = trace::read_walk_with(f, limits);
            on_walk();
            w
        })
        .collect::<Result<Vec<_>, _>>()?;
    walks.sort_by(|a, b| a.walk.meta.id.cmp(&b.walk.meta.id));
    tracing::info!(floor = %dir.display(), walks = walks.len(), "floor read");
    Ok(FloorData {
        name: floor_name(dir),
        dir: dir.to_path_buf(),
        width,
        height,
        plan: plan_read.plan,
        lonlat_box: plan_read.lonlat_box,
        skipped_features: plan_read.skipped_features,
        walks,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use wipdr_core::{Point2, Polygon, Walk, Waypoint};

    #[test]
    fn floor_folder_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let floor = dir.path().join("siteX").join("F9");
        std::fs::create_dir_all(floor.join(WALKS_DIR)).unwrap();
        write_floor_info(floor.join(FLOOR_INFO), 30.0, 10.0).unwrap();
        let outline = Polygon::new(
            vec![
                Point2::new(0.0, 0.0),
                Point2::new(30.0, 0.0),
                Point2::new(30.0, 10.0),
                Point2::new(0.0, 10.0),
            ],
            vec![],
        )
        .unwrap();
        let plan = FloorPlan::new(30.0, 10.0, vec![outline], vec![]).unwrap();
        geojson::write_floor_plan(
            floor.join(GEOJSON_MAP),
            &plan,
            LonLatBox::around(10.0, 50.0, 30.0, 10.0),
        )
        .unwrap();
        for (i, id) in ["b", "a"].iter().enumerate() {
            let mut w = Walk::default();
            w.waypoints.push(Waypoint {
                t: 10 + i as i64,
                position: Point2::new(1.0 + i as f64, 2.0),
            });
            trace::write_walk_file(&w, floor.join(WALKS_DIR).join(format!("{id}.txt.gz"))).unwrap();
        }
        let data = read_floor_dir(&floor, &ReadOptions::default()).unwrap();
        assert_eq!(data.name, "siteX/F9");
        assert_eq!((data.width, data.height), (30.0, 10.0));
        let ids: Vec<_> = data.walks.iter().map(|w| w.walk.meta.id.as_str()).collect();
        assert_eq!(ids, ["a", "b"]);
        assert_eq!(data.walks[0].walk.waypoints[0].t, 11);
        let c = data.plan.outline[0].bbox();
        assert!((c.1.x - 30.0).abs() < 1e-9 && (c.1.y - 10.0).abs() < 1e-9 && c.0.x.abs() < 1e-9);
        assert_eq!(data.total_report().records["TYPE_WAYPOINT"], 2);
    }

    #[test]
    fn missing_files_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let e = read_floor_dir(dir.path(), &ReadOptions::default()).unwrap_err();
        assert!(matches!(e, IoError::NotAFloor { .. }), "{e}");
        std::fs::write(dir.path().join(FLOOR_INFO), r#"{"map_info": {"width": 3}}"#).unwrap();
        let e = read_floor_info(dir.path().join(FLOOR_INFO), &Limits::default()).unwrap_err();
        assert!(e.to_string().contains("map_info.height"), "{e}");
    }
}
