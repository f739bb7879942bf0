//! ILC floor folders: `floor_info.json`, `geojson_map.json` and `path_data_files/*.txt[.gz]`.

use crate::geojson::{self, LonLatBox};
use crate::trace::{self, ParseReport, ParsedWalk};
use crate::{IoError, Limits};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::path::{Path, PathBuf};
use wipdr_core::{FloorPlan, Walk};

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
    /// Fail the whole floor on the first walk file that cannot be read (by file name),
    /// instead of skipping it into [`FloorData::skipped_walks`] (default false).
    pub strict: bool,
}

/// A walk file that could not be read and was left out of [`FloorData::walks`] (logged with
/// `tracing::warn!`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SkippedWalk {
    /// The walk file.
    pub path: PathBuf,
    /// The whole error chain ([`IoError::full_message`]), naming the file and, where it
    /// applies, the line, e.g. `.../w.txt.gz: line 3: longer than the limit of 64 bytes`.
    pub error: String,
    /// The failure may not come from the file's content: it could not be opened, or the
    /// operating system failed a read. The cache does not store a floor with such a skip,
    /// so the walk is tried again on the next read.
    pub transient: bool,
}

impl SkippedWalk {
    pub(crate) fn new(path: &Path, error: &IoError) -> Self {
        let transient = match error {
            IoError::File { .. } => true,
            IoError::Read { source, .. } => !matches!(
                source.kind(),
                std::io::ErrorKind::InvalidData
                    | std::io::ErrorKind::InvalidInput
                    | std::io::ErrorKind::UnexpectedEof
            ),
            _ => false,
        };
        Self {
            path: path.to_path_buf(),
            error: error.full_message(),
            transient,
        }
    }
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
    /// The walk files that could not be read (too long a line, too many records, a corrupt
    /// gzip stream, ...), sorted by file name; empty when every walk was read. Not empty
    /// only when [`ReadOptions::strict`] is off and at least one walk was read.
    #[serde(default)]
    pub skipped_walks: Vec<SkippedWalk>,
    /// The WGS84 frame of the metre coordinates, for folders of IPIN logfiles (ground truth
    /// in degrees; see [`crate::logfile_folder`]); `None` for ILC floors, whose frame is the
    /// GeoJSON box of [`FloorData::lonlat_box`].
    #[serde(default)]
    pub geo_frame: Option<wipdr_core::GeoFrame>,
}

impl FloorData {
    /// The floor in the core vocabulary (name, plan, walks), as the evaluation takes it; the
    /// parse reports and the GeoJSON frame stay here.
    pub fn into_floor(self) -> wipdr_core::Floor {
        let floor = wipdr_core::Floor::new(
            self.name,
            self.plan,
            self.walks.into_iter().map(|w| w.walk).collect(),
        );
        match self.geo_frame {
            Some(frame) => floor.with_geo_frame(frame),
            None => floor,
        }
    }

    /// Everything the readers left out of this floor, by kind: walk files that could not
    /// be read, plan features that are not usable polygons (degenerate, self-crossing),
    /// records skipped by [`trace::SkipKind`] (blank lines are not counted: they hold no data),
    /// and Wi-Fi entries whose BSSID repeated in a scan. Kinds with no skip are left out.
    ///
    /// ```
    /// # use wipdr_io::floor::FloorData;
    /// # fn f(data: &FloorData) {
    /// for (kind, count) in data.skip_counts() {
    ///     println!("{}: {kind}: {count}", data.name);
    /// }
    /// # }
    /// ```
    pub fn skip_counts(&self) -> std::collections::BTreeMap<String, usize> {
        let mut out = std::collections::BTreeMap::new();
        let mut add = |kind: String, n: usize| {
            if n > 0 {
                *out.entry(kind).or_insert(0) += n;
            }
        };
        add("walk file unreadable".into(), self.skipped_walks.len());
        add(
            "plan feature unusable (degenerate or self-crossing)".into(),
            self.skipped_features,
        );
        let total = self.total_report();
        for (kind, count) in &total.skipped {
            if *kind != trace::SkipKind::Blank {
                add(format!("record: {}", kind.label()), count.count);
            }
        }
        add(
            "Wi-Fi entry: BSSID repeated in a scan".into(),
            total.duplicate_bssids_removed,
        );
        out
    }

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

/// Smallest floor side accepted in `floor_info.json`, metres.
pub const MIN_FLOOR_SIDE_M: f64 = 0.1;
/// Largest floor side accepted in `floor_info.json`, metres (100 km).
pub const MAX_FLOOR_SIDE_M: f64 = 100_000.0;
/// How far outside `[0, width] x [0, height]` a waypoint may lie before it is skipped as
/// [`trace::SkipKind::WaypointOffFloor`]: 10 m plus half the larger floor side (surveyed
/// waypoints sit on the floor; the margin only allows for a plan not quite covering it).
pub const OFF_FLOOR_MARGIN_M: f64 = 10.0;

/// Skips the waypoints of `walk` lying off a floor of `width` x `height` metres (see
/// [`OFF_FLOOR_MARGIN_M`]), counting them in its report; returns how many.
fn skip_off_floor_waypoints(walk: &mut ParsedWalk, width: f64, height: f64) -> usize {
    let m = OFF_FLOOR_MARGIN_M + 0.5 * width.max(height);
    let on = |p: &wipdr_core::Point2| {
        (-m..=width + m).contains(&p.x) && (-m..=height + m).contains(&p.y)
    };
    let before = walk.walk.waypoints.len();
    walk.walk.waypoints.retain(|w| on(&w.position));
    let off = before - walk.walk.waypoints.len();
    if off > 0 {
        tracing::warn!(walk = %walk.walk.meta.id, off, width, height, "waypoints off the floor skipped");
        walk.report
            .skipped
            .entry(trace::SkipKind::WaypointOffFloor)
            .or_default()
            .count += off;
        if let Some(c) = walk.report.records.get_mut("TYPE_WAYPOINT") {
            *c = c.saturating_sub(off);
        }
    }
    off
}

/// Reads `floor_info.json`: `(width, height)` in metres from `map_info`.
pub fn read_floor_info(path: impl AsRef<Path>, limits: &Limits) -> Result<(f64, f64), IoError> {
    let path = path.as_ref();
    let value =
        geojson::read_json_bounded(path, limits.max_json_bytes, Some(limits.max_json_values))?;
    let get = |key: &str| -> Result<f64, IoError> {
        let field = format!("map_info.{key}");
        let v = value
            .get("map_info")
            .and_then(|m| m.get(key))
            .ok_or_else(|| IoError::invalid(path, &field, "missing"))?;
        match v.as_f64() {
            Some(x) if (MIN_FLOOR_SIDE_M..=MAX_FLOOR_SIDE_M).contains(&x) => Ok(x),
            _ => Err(IoError::invalid(
                path,
                &field,
                format!(
                    "expected a floor side between {MIN_FLOOR_SIDE_M} and {MAX_FLOOR_SIDE_M} m, found {v}"
                ),
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

/// Writes a floor folder in the ILC layout, creating `dir` if needed: `floor_info.json`
/// (the plan's width and height), `geojson_map.json` (the plan placed in `lonlat_box`, see
/// [`geojson::write_floor_plan`]) and one `path_data_files/<walk id>.txt.gz` per walk
/// ([`trace::write_walk_file`]), the file named from `walk.meta.id`. Deterministic output,
/// so the same inputs give byte-identical files; [`read_floor_dir`] reads it back.
///
/// Every walk id is checked before anything is written: an empty id, one with a path
/// separator (`/`, `\`) or a NUL, `.` or `..`, or an id given twice is refused with
/// [`IoError::Unwritable`] naming the id.
///
/// ```
/// use wipdr_core::{FloorPlan, Point2, Walk, Waypoint};
/// use wipdr_io::floor::{read_floor_dir, write_floor_dir, ReadOptions};
/// use wipdr_io::LonLatBox;
///
/// let tmp = tempfile::tempdir().unwrap();
/// let dir = tmp.path().join("site").join("F1");
/// let plan = FloorPlan::rectangle(20.0, 10.0).unwrap();
/// let mut walk = Walk::default();
/// walk.meta.id = "w1".into();
/// walk.waypoints.push(Waypoint::new(1_000, Point2::new(3.0, 4.0)));
/// write_floor_dir(&dir, &plan, LonLatBox::around(8.0, 47.0, 20.0, 10.0), [&walk]).unwrap();
///
/// let floor = read_floor_dir(&dir, &ReadOptions::default()).unwrap();
/// assert_eq!((floor.name.as_str(), floor.width, floor.height), ("site/F1", 20.0, 10.0));
/// assert_eq!(floor.walks.len(), 1);
/// assert_eq!(floor.walks[0].walk.meta.id, "w1");
/// assert_eq!(floor.walks[0].walk.waypoints, walk.waypoints);
/// ```
pub fn write_floor_dir<'w>(
    dir: impl AsRef<Path>,
    plan: &FloorPlan,
    lonlat_box: LonLatBox,
    walks: impl IntoIterator<Item = &'w Walk>,
) -> Result<(), IoError> {
    let dir = dir.as_ref();
    let walks: Vec<&Walk> = walks.into_iter().collect();
    let mut ids = std::collections::BTreeSet::new();
    for (i, walk) in walks.iter().enumerate() {
        let id = walk.meta.id.as_str();
        let problem = if id.is_empty() || id == "." || id == ".." {
            Some("is not a file name")
        } else if id.contains(['/', '\\', '\0']) {
            Some("contains a path separator or a NUL")
        } else if !ids.insert(id) {
            Some("is used by an earlier walk")
        } else {
            None
        };
        if let Some(problem) = problem {
            return Err(IoError::Unwritable {
                field: format!("walks[{i}].meta.id"),
                message: format!("walk id {id:?} {problem}"),
            });
        }
    }
    let walks_dir = dir.join(WALKS_DIR);
    std::fs::create_dir_all(&walks_dir).map_err(|e| IoError::file(&walks_dir, e))?;
    write_floor_info(dir.join(FLOOR_INFO), plan.width, plan.height)?;
    geojson::write_floor_plan(dir.join(GEOJSON_MAP), plan, lonlat_box)?;
    for walk in walks {
        trace::write_walk_file(walk, walks_dir.join(format!("{}.txt.gz", walk.meta.id)))?;
    }
    Ok(())
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

/// Splits walk files (sorted by name) into the first file of each walk id and the later
/// files with an id already seen (`w.txt` and `w.txt.gz` are both walk `w`), each later
/// file paired with the first one.
fn split_duplicate_ids(files: &[PathBuf]) -> (Vec<PathBuf>, Vec<(PathBuf, PathBuf)>) {
    let mut first_of: std::collections::HashMap<String, &PathBuf> = Default::default();
    let mut unique = Vec::with_capacity(files.len());
    let mut duplicates = Vec::new();
    for f in files {
        match first_of.entry(trace::walk_id_of(f)) {
            std::collections::hash_map::Entry::Occupied(e) => {
                duplicates.push((f.clone(), (*e.get()).clone()));
            }
            std::collections::hash_map::Entry::Vacant(e) => {
                e.insert(f);
                unique.push(f.clone());
            }
        }
    }
    (unique, duplicates)
}

/// Reads a whole floor folder; the walks in parallel (rayon).
///
/// A walk file that cannot be read is skipped: logged with `tracing::warn!` and kept in
/// [`FloorData::skipped_walks`] with its error. The read fails when `floor_info.json` or
/// `geojson_map.json` is missing or bad, when the folder has walk files and none of them can
/// be read ([`IoError::NoReadableWalk`]), and, with [`ReadOptions::strict`], on the first
/// walk file (by name) that cannot be read. A folder without walk files reads as a floor
/// with no walks.
///
/// Two files of one walk id (`w.txt` and `w.txt.gz`) are never both read, as the walk could
/// then be a training and a test walk at once: the first by name (`w.txt`) is read, the
/// later one is skipped into [`FloorData::skipped_walks`] with an
/// [`IoError::DuplicateWalk`] naming both files (with [`ReadOptions::strict`], the read
/// fails with that error).
///
/// ```no_run
/// use wipdr_io::floor::{read_floor_dir, ReadOptions};
/// let dir = wipdr_io::data_root().join("ilc20/site1/F1");
/// let floor = read_floor_dir(dir, &ReadOptions::default()).unwrap();
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
    let listed = walk_files(dir)?;
    let (files, duplicates) = split_duplicate_ids(&listed);
    if options.strict
        && let Some((dup, first)) = duplicates.first()
    {
        return Err(IoError::DuplicateWalk {
            id: trace::walk_id_of(dup),
            first: first.clone(),
            second: dup.clone(),
        });
    }
    let results: Vec<Result<ParsedWalk, IoError>> = files
        .par_iter()
        .map(|f| {
            let w = trace::read_walk_with(f, limits);
            on_walk();
            w
        })
        .collect();
    let mut walks = Vec::with_capacity(results.len());
    let mut skipped_walks = Vec::new();
    let mut first_error = None;
    for (file, result) in files.iter().zip(results) {
        match result {
            Ok(mut walk) => {
                skip_off_floor_waypoints(&mut walk, width, height);
                walks.push(walk);
            }
            Err(e) if options.strict => return Err(e),
            Err(e) => {
                let skip = SkippedWalk::new(file, &e);
                tracing::warn!(file = %file.display(), error = %skip.error, "walk file skipped");
                skipped_walks.push(skip);
                first_error.get_or_insert(e);
            }
        }
    }
    for (dup, first) in &duplicates {
        let e = IoError::DuplicateWalk {
            id: trace::walk_id_of(dup),
            first: first.clone(),
            second: dup.clone(),
        };
        let skip = SkippedWalk::new(dup, &e);
        tracing::warn!(file = %dup.display(), first = %first.display(), "walk file skipped: same walk id as an earlier file");
        skipped_walks.push(skip);
    }
    skipped_walks.sort_by(|a, b| a.path.cmp(&b.path));
    if walks.is_empty()
        && let Some(first) = first_error
    {
        return Err(IoError::NoReadableWalk {
            path: dir.to_path_buf(),
            files: listed.len(),
            first: Box::new(first),
        });
    }
    walks.sort_by(|a, b| a.walk.meta.id.cmp(&b.walk.meta.id));
    if !skipped_walks.is_empty() {
        tracing::warn!(
            floor = %dir.display(),
            walks = walks.len(),
            skipped = skipped_walks.len(),
            "floor read with unreadable walk files skipped"
        );
    }
    tracing::info!(floor = %dir.display(), walks = walks.len(), skipped = skipped_walks.len(), "floor read");
    Ok(FloorData {
        name: floor_name(dir),
        dir: dir.to_path_buf(),
        width,
        height,
        plan: plan_read.plan,
        lonlat_box: plan_read.lonlat_box,
        geo_frame: None,
        skipped_features: plan_read.skipped_features,
        walks,
        skipped_walks,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use wipdr_core::{Point2, Waypoint};

    #[test]
    fn floor_folder_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let floor = dir.path().join("siteX").join("F9");
        let walks: Vec<Walk> = ["b", "a"]
            .iter()
            .enumerate()
            .map(|(i, id)| {
                let mut w = Walk::default();
                w.meta.id = id.to_string();
                w.waypoints.push(Waypoint::new(
                    10 + i as i64,
                    Point2::new(1.0 + i as f64, 2.0),
                ));
                w
            })
            .collect();
        let plan = FloorPlan::rectangle(30.0, 10.0).unwrap();
        write_floor_dir(
            &floor,
            &plan,
            LonLatBox::around(10.0, 50.0, 30.0, 10.0),
            &walks,
        )
        .unwrap();
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

    /// A floor folder `root/site/F1` with `floor_info.json` and `geojson_map.json`, and
    /// good walks `ids` with `n` waypoints each.
    fn fixture_floor(root: &Path, ids: &[&str], n: usize) -> PathBuf {
        let floor = root.join("site").join("F1");
        let walks: Vec<Walk> = ids
            .iter()
            .map(|id| {
                let mut w = Walk::default();
                w.meta.id = id.to_string();
                for i in 0..n {
                    w.waypoints.push(Waypoint::new(
                        1000 * i as i64,
                        Point2::new(1.0 + i as f64, 2.0),
                    ));
                }
                w
            })
            .collect();
        let plan = FloorPlan::rectangle(20.0, 10.0).unwrap();
        write_floor_dir(
            &floor,
            &plan,
            LonLatBox::around(10.0, 50.0, 20.0, 10.0),
            &walks,
        )
        .unwrap();
        floor
    }

    /// Writes two bad walk files into `floor`: `c.txt.gz`, gzip magic bytes then garbage
    /// (a corrupt gzip stream), and `d.txt`, a plain trace whose second line is 1000 bytes
    /// (crosses a `max_line_bytes` of 256, far above the fixture walks' lines).
    fn write_bad_walks(floor: &Path) -> (PathBuf, PathBuf) {
        let corrupt = floor.join(WALKS_DIR).join("c.txt.gz");
        let mut bytes = vec![0x1f, 0x8b, 0x08, 0x00];
        bytes.extend_from_slice(&[0xAB; 64]);
        std::fs::write(&corrupt, bytes).unwrap();
        let long = floor.join(WALKS_DIR).join("d.txt");
        std::fs::write(
            &long,
            format!(
                "1000\tTYPE_WAYPOINT\t1.0\t2.0\n2000\tTYPE_WAYPOINT\t1.0\t2.0{}\n",
                " ".repeat(1000)
            ),
        )
        .unwrap();
        (corrupt, long)
    }

    fn tight_limits() -> ReadOptions {
        let mut options = ReadOptions::default();
        options.limits.max_line_bytes = 256;
        options
    }

    #[test]
    fn bad_walks_are_skipped_counted_and_named() {
        let dir = tempfile::tempdir().unwrap();
        let floor = fixture_floor(dir.path(), &["a", "b"], 3);
        let (corrupt, long) = write_bad_walks(&floor);
        let data = read_floor_dir(&floor, &tight_limits()).unwrap();
        let ids: Vec<_> = data.walks.iter().map(|w| w.walk.meta.id.as_str()).collect();
        assert_eq!(ids, ["a", "b"]);
        assert_eq!(data.total_report().records["TYPE_WAYPOINT"], 6);
        assert_eq!(data.skipped_walks.len(), 2, "{:?}", data.skipped_walks);
        let (gz, line) = (&data.skipped_walks[0], &data.skipped_walks[1]);
        assert_eq!(gz.path, corrupt);
        assert!(gz.error.contains("c.txt.gz"), "{}", gz.error);
        assert!(
            gz.error.contains("read failed after line 0"),
            "{}",
            gz.error
        );
        assert!(
            !gz.transient,
            "a corrupt gzip stream is content: {}",
            gz.error
        );
        assert_eq!(line.path, long);
        assert!(
            line.error
                .contains("d.txt: line 2: longer than the limit of 256 bytes"),
            "{}",
            line.error
        );
        assert!(!line.transient);
        // With the default limits only the corrupt gzip is skipped.
        let data = read_floor_dir(&floor, &ReadOptions::default()).unwrap();
        assert_eq!(data.walks.len(), 3);
        assert_eq!(data.skipped_walks.len(), 1);
        assert_eq!(data.skipped_walks[0].path, corrupt);
    }

    #[test]
    fn a_walk_present_as_txt_and_txt_gz_is_read_once() {
        let dir = tempfile::tempdir().unwrap();
        let floor = fixture_floor(dir.path(), &["a", "b"], 3);
        // `a` again, plain text, with other waypoints: the same walk id.
        let walks = floor.join(WALKS_DIR);
        let plain = walks.join("a.txt");
        std::fs::write(&plain, "5\tTYPE_WAYPOINT\t9\t9\n").unwrap();
        let gz = walks.join("a.txt.gz");
        let data = read_floor_dir(&floor, &ReadOptions::default()).unwrap();
        let ids: Vec<_> = data.walks.iter().map(|w| w.walk.meta.id.as_str()).collect();
        assert_eq!(ids, ["a", "b"], "one walk per id");
        // The first by name (`a.txt`) is read, `a.txt.gz` is a counted skip naming both.
        assert_eq!(data.walks[0].walk.waypoints.len(), 1);
        assert_eq!(data.skipped_walks.len(), 1, "{:?}", data.skipped_walks);
        let skip = &data.skipped_walks[0];
        assert_eq!(skip.path, gz);
        assert!(!skip.transient);
        assert!(skip.error.contains("a.txt.gz"), "{}", skip.error);
        assert!(
            skip.error
                .contains(&format!("already read from {}", plain.display())),
            "{}",
            skip.error
        );
        // Strict: a typed error naming both files.
        let strict = ReadOptions {
            strict: true,
            ..ReadOptions::default()
        };
        match read_floor_dir(&floor, &strict).unwrap_err() {
            IoError::DuplicateWalk { id, first, second } => {
                assert_eq!((id.as_str(), first, second), ("a", plain, gz));
            }
            e => panic!("{e}"),
        }
    }

    #[test]
    fn strict_fails_on_the_first_bad_walk_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let floor = fixture_floor(dir.path(), &["a", "b"], 2);
        let (corrupt, long) = write_bad_walks(&floor);
        let strict = ReadOptions {
            strict: true,
            ..tight_limits()
        };
        let e = read_floor_dir(&floor, &strict).unwrap_err();
        assert!(
            matches!(&e, IoError::Read { path, line: 0, .. } if *path == corrupt),
            "{e}"
        );
        std::fs::remove_file(&corrupt).unwrap();
        let e = read_floor_dir(&floor, &strict).unwrap_err();
        assert!(
            matches!(&e, IoError::LineTooLong { path, line: 2, limit: 256 } if *path == long),
            "{e}"
        );
        std::fs::remove_file(&long).unwrap();
        let data = read_floor_dir(&floor, &strict).unwrap();
        assert_eq!((data.walks.len(), data.skipped_walks.len()), (2, 0));
    }

    #[test]
    fn a_floor_without_a_readable_walk_fails() {
        let dir = tempfile::tempdir().unwrap();
        let floor = fixture_floor(dir.path(), &[], 0);
        // No walk files at all: a floor with no walks, as before.
        let data = read_floor_dir(&floor, &tight_limits()).unwrap();
        assert!(data.walks.is_empty() && data.skipped_walks.is_empty());
        let (corrupt, _) = write_bad_walks(&floor);
        let e = read_floor_dir(&floor, &tight_limits()).unwrap_err();
        match &e {
            IoError::NoReadableWalk { path, files, first } => {
                assert_eq!((path, *files), (&floor, 2));
                assert!(
                    matches!(first.as_ref(), IoError::Read { path, .. } if *path == corrupt),
                    "{first}"
                );
            }
            other => panic!("expected NoReadableWalk, got {other}"),
        }
        let message = e.full_message();
        assert!(
            message.contains("none of the 2 walk files could be read"),
            "{message}"
        );
        assert!(
            message.contains("c.txt.gz: read failed after line 0: "),
            "{message}"
        );
    }

    #[test]
    fn bad_walk_ids_are_refused_before_writing() {
        let tmp = tempfile::tempdir().unwrap();
        let plan = FloorPlan::rectangle(20.0, 10.0).unwrap();
        let bbox = LonLatBox::around(10.0, 50.0, 20.0, 10.0);
        let walk = |id: &str| {
            let mut w = Walk::default();
            w.meta.id = id.into();
            w
        };
        let good = walk("ok");
        for (k, (bad, problem)) in [
            ("", "is not a file name"),
            ("..", "is not a file name"),
            ("../escape", "contains a path separator"),
            ("sub/w", "contains a path separator"),
            ("sub\\w", "contains a path separator"),
            ("ok", "is used by an earlier walk"),
        ]
        .into_iter()
        .enumerate()
        {
            let floor = tmp.path().join(format!("floor{k}"));
            let bad_walk = walk(bad);
            let e = write_floor_dir(&floor, &plan, bbox, [&good, &bad_walk]).unwrap_err();
            match &e {
                IoError::Unwritable { field, message } => {
                    assert_eq!(field, "walks[1].meta.id");
                    assert!(message.contains(&format!("{bad:?}")), "{message}");
                    assert!(message.contains(problem), "{message}");
                }
                other => panic!("expected Unwritable for {bad:?}, got {other}"),
            }
            assert!(!floor.exists(), "nothing is written for {bad:?}");
        }
        assert!(!tmp.path().join("escape.txt.gz").exists());
        // No walks at all: a floor folder with an empty walk folder.
        let floor = tmp.path().join("empty");
        write_floor_dir(&floor, &plan, bbox, []).unwrap();
        let data = read_floor_dir(&floor, &ReadOptions::default()).unwrap();
        assert!(data.walks.is_empty() && floor.join(WALKS_DIR).is_dir());
    }

    #[test]
    fn open_failures_are_transient() {
        let path = Path::new("w.txt.gz");
        let open = IoError::file(path, std::io::Error::from(std::io::ErrorKind::NotFound));
        assert!(SkippedWalk::new(path, &open).transient);
        let os_read = IoError::Read {
            path: path.into(),
            line: 7,
            source: std::io::Error::from(std::io::ErrorKind::Interrupted),
        };
        assert!(SkippedWalk::new(path, &os_read).transient);
        let limit = IoError::TooManyRecords {
            path: path.into(),
            line: 9,
            limit: 8,
        };
        let skip = SkippedWalk::new(path, &limit);
        assert!(!skip.transient);
        assert_eq!(
            skip.error,
            "w.txt.gz: line 9: more than the limit of 8 records"
        );
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
