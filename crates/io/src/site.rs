//! An ILC site folder (`site1/` holding `F1/`, `F2/`, ...) read as one building: every floor's
//! walks together, each waypoint on its floor's level, so that the floor estimate and the
//! floor-aware radio map are evaluated as with IPIN logfiles.
//!
//! **Levels** from the floor folder names ([`level_of_floor_name`]): `F1`/`1F` = 0 (ground),
//! `F2`/`2F` = 1, ...; `B1`/`1B` = -1, `B2` = -2, ... A floor folder whose name is not of
//! these forms fails the read with [`IoError::NotAFloor`].
//!
//! **Frames and plans.** ILC floors of one site each have their own metre frame (their
//! GeoJSON box), so positions are comparable only within a floor; scoring is 2D within the
//! walk's floor plus the floor error, which is what the building evaluation measures. The
//! building's plan is the largest floor's extent without outline or walls (walls are per
//! floor; the per-floor evaluation keeps them).

use crate::IoError;
use crate::cache::{self, CacheSettings};
use crate::floor::{self, FloorData, ReadOptions};
use crate::geojson::LonLatBox;
use std::path::{Path, PathBuf};
use wipdr_core::FloorPlan;

/// The level of an ILC floor folder name: `F1`/`1F` = 0, `F2` = 1, `B1`/`1B` = -1, ...
/// (case-insensitive); `None` for other names.
///
/// ```
/// use wipdr_io::site::level_of_floor_name;
/// assert_eq!(level_of_floor_name("F1"), Some(0));
/// assert_eq!(level_of_floor_name("3F"), Some(2));
/// assert_eq!(level_of_floor_name("B2"), Some(-2));
/// assert_eq!(level_of_floor_name("lobby"), None);
/// ```
pub fn level_of_floor_name(name: &str) -> Option<i32> {
    let upper = name.trim().to_ascii_uppercase();
    let (kind, digits) = if let Some(d) = upper.strip_prefix('F').or(upper.strip_suffix('F')) {
        ('F', d)
    } else if let Some(d) = upper.strip_prefix('B').or(upper.strip_suffix('B')) {
        ('B', d)
    } else {
        return None;
    };
    if digits.is_empty() || digits.len() > 3 || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let n: i32 = digits.parse().ok()?;
    match kind {
        'F' if n >= 1 => Some(n - 1),
        'B' if n >= 1 => Some(-n),
        _ => None,
    }
}

/// The floor folders of a site folder (sub-folders with a `floor_info.json`), sorted by name;
/// empty when `dir` is not a site folder.
pub fn floor_dirs(dir: &Path) -> Vec<PathBuf> {
    if dir.join(floor::FLOOR_INFO).is_file() {
        return Vec::new();
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut dirs: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join(floor::FLOOR_INFO).is_file())
        .collect();
    dirs.sort();
    dirs
}

/// Whether `dir` is an ILC site folder (holds floor folders, is not one itself).
pub fn is_site_dir(dir: &Path) -> bool {
    !floor_dirs(dir).is_empty()
}

/// Reads a site folder as one building ([`FloorData`] named after the site), each floor
/// through the parse cache as `cache` says (the outcome of each floor's read is returned in
/// folder-name order); `on_walk` after each walk read from source.
pub fn read_site_dir(
    dir: &Path,
    cache_settings: &CacheSettings,
    options: &ReadOptions,
    on_walk: &(dyn Fn() + Sync),
) -> Result<(FloorData, Vec<cache::CacheOutcome>), IoError> {
    let floors = floor_dirs(dir);
    if floors.is_empty() {
        return Err(IoError::NotAFloor {
            path: dir.to_path_buf(),
            message: "no floor folders (with floor_info.json) in this site folder".into(),
        });
    }
    let mut walks = Vec::new();
    let mut skipped_walks = Vec::new();
    let (mut width, mut height) = (0.0f64, 0.0f64);
    let mut lonlat_box: Option<LonLatBox> = None;
    let mut outcomes = Vec::with_capacity(floors.len());
    for f in &floors {
        let name = f
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let level = level_of_floor_name(&name).ok_or_else(|| IoError::NotAFloor {
            path: f.clone(),
            message: format!(
                "floor folder name {name:?} gives no level (expected F1, F2, ... or B1, B2, ...)"
            ),
        })?;
        let (data, outcome) = cache::read_floor(f, cache_settings, options, on_walk)?;
        outcomes.push(outcome);
        width = width.max(data.width);
        height = height.max(data.height);
        lonlat_box.get_or_insert(data.lonlat_box);
        for mut w in data.walks {
            for p in &mut w.walk.waypoints {
                p.floor = Some(level);
            }
            w.walk.meta.floor_name.get_or_insert_with(|| name.clone());
            walks.push(w);
        }
        skipped_walks.extend(data.skipped_walks);
    }
    walks.sort_by(|a, b| a.walk.meta.id.cmp(&b.walk.meta.id));
    let plan =
        FloorPlan::new(width, height, Vec::new(), Vec::new()).map_err(|e| IoError::Invalid {
            path: dir.to_path_buf(),
            field: "floor_info.json".into(),
            message: e.to_string(),
        })?;
    let data = FloorData {
        name: floor::floor_name(dir),
        dir: dir.to_path_buf(),
        width,
        height,
        plan,
        lonlat_box: lonlat_box.unwrap_or(LonLatBox {
            min_lon: 0.0,
            min_lat: 0.0,
            max_lon: 0.0,
            max_lat: 0.0,
        }),
        skipped_features: 0,
        walks,
        skipped_walks,
        geo_frame: None,
    };
    Ok((data, outcomes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_of_names() {
        for (name, level) in [
            ("F1", Some(0)),
            ("f2", Some(1)),
            ("1F", Some(0)),
            ("B1", Some(-1)),
            ("2B", Some(-2)),
        ] {
            assert_eq!(level_of_floor_name(name), level, "{name}");
        }
        for name in ["F0", "F", "B", "Fx", "F1234", "G", ""] {
            assert_eq!(level_of_floor_name(name), None, "{name}");
        }
    }

    #[test]
    fn a_site_reads_as_one_building_with_levels() {
        let tmp = tempfile::tempdir().unwrap();
        let site = tmp.path().join("site");
        for (name, x) in [("F1", 1.0), ("F2", 2.0)] {
            let plan = FloorPlan::rectangle(20.0, 10.0).unwrap();
            let mut walk = wipdr_core::Walk::default();
            walk.meta.id = format!("w{name}");
            walk.waypoints.push(wipdr_core::Waypoint::new(
                1000,
                wipdr_core::Point2::new(x, 1.0),
            ));
            floor::write_floor_dir(
                site.join(name),
                &plan,
                LonLatBox::around(8.0, 47.0, 20.0, 10.0),
                [&walk],
            )
            .unwrap();
        }
        assert!(is_site_dir(&site));
        assert!(!is_site_dir(&site.join("F1")));
        let (data, outcomes) = read_site_dir(
            &site,
            &CacheSettings::disabled(),
            &ReadOptions::default(),
            &|| {},
        )
        .unwrap();
        assert_eq!(outcomes.len(), 2);
        let floors: Vec<Option<i32>> = data
            .walks
            .iter()
            .map(|w| w.walk.waypoints[0].floor)
            .collect();
        assert_eq!(floors, vec![Some(0), Some(1)]);
        std::fs::create_dir_all(site.join("lobby")).unwrap();
        std::fs::copy(
            site.join("F1").join(floor::FLOOR_INFO),
            site.join("lobby").join(floor::FLOOR_INFO),
        )
        .unwrap();
        let e = read_site_dir(
            &site,
            &CacheSettings::disabled(),
            &ReadOptions::default(),
            &|| {},
        )
        .unwrap_err();
        assert!(e.to_string().contains("lobby"), "{e}");
    }
}
