//! Any input path, whatever its format: one walk file (ILC trace or IPIN logfile) or one
//! folder (ILC floor, ILC site, folder of IPIN logfiles). The tools and the Python package
//! read paths through these two functions, so both read a path the same way.

use crate::cache::{self, CacheOutcome, CacheSettings};
use crate::floor::{FloorData, ReadOptions};
use crate::{IoError, Limits, ParsedWalk, logfile, logfile_folder, site, trace};
use std::path::Path;

/// Reads one walk file: a GetSensorData logfile ([`logfile::is_logfile`]: first line starts
/// with `%`), its ground truth placed in a metre frame of its own ([`logfile_folder::frame_of`]
/// over its `POSI` points; a logfile without any keeps no waypoints), or else an ILC trace
/// ([`trace::read_walk_with`]).
///
/// ```
/// let tmp = tempfile::tempdir().unwrap();
/// let path = tmp.path().join("w.txt");
/// std::fs::write(&path, "#\tstartTime:1000\n1000\tTYPE_WAYPOINT\t3.0\t4.0\n").unwrap();
/// let parsed = wipdr_io::any::read_walk_file(&path, &Default::default()).unwrap();
/// assert_eq!(parsed.walk.waypoints.len(), 1);
/// assert!(wipdr_io::any::read_walk_file(tmp.path().join("none.txt"), &Default::default()).is_err());
/// ```
pub fn read_walk_file(path: impl AsRef<Path>, limits: &Limits) -> Result<ParsedWalk, IoError> {
    let path = path.as_ref();
    if !logfile::is_logfile(path) {
        return trace::read_walk_with(path, limits);
    }
    let log = logfile::read_logfile(path, limits)?;
    let frame = logfile_folder::frame_of(log.ground_truth.iter().map(|g| (g.lat_deg, g.lon_deg)))
        .map(|(f, _, _)| f);
    Ok(match frame {
        Some(frame) => log.into_walk(&frame),
        None => ParsedWalk {
            walk: log.walk,
            report: log.report,
        },
    })
}

/// Reads an ILC floor folder or a folder of IPIN logfiles through the parse cache
/// ([`cache::read_floor`]), or an ILC site folder (floor folders inside) as one building
/// ([`site::read_site_dir`], each floor through the cache). The outcome of a site is a hit
/// when every floor came from the cache, else the first floor's that did not.
pub fn read_any_dir(
    dir: &Path,
    settings: &CacheSettings,
    options: &ReadOptions,
    on_walk: &(dyn Fn() + Sync),
) -> Result<(FloorData, CacheOutcome), IoError> {
    if site::is_site_dir(dir) {
        let (data, outcomes) = site::read_site_dir(dir, settings, options, on_walk)?;
        let outcome = outcomes
            .iter()
            .copied()
            .find(|o| *o != CacheOutcome::Hit)
            .unwrap_or(CacheOutcome::Hit);
        Ok((data, outcome))
    } else {
        cache::read_floor(dir, settings, options, on_walk)
    }
}
