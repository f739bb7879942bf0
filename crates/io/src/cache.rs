//! A binary cache of parsed floors (bincode 2.0.1, kept behind this one module so it can be
//! swapped for another encoding).
//!
//! One file per floor folder, `<cache dir>/floor-<hash of the folder path>.bin`. It starts
//! with a key: a format version, this crate's version, the [`ReadOptions`], and for every
//! source file (`floor_info.json`, `geojson_map.json`, each walk) its name, size and
//! modification time. A cache file is used only when its key equals the key of the folder as
//! it is now, so a changed, added or removed source file makes the floor be re-read (and the
//! cache rewritten). A cache file that cannot be decoded is ignored (logged) and rewritten.
//!
//! The library never reads the environment: callers choose the cache folder;
//! [`DEFAULT_CACHE_DIR`] is the documented default (relative to the working directory, i.e.
//! the workspace's `target/` when run with cargo). Never put it inside `../shared`.

use crate::IoError;
use crate::floor::{self, FloorData, ReadOptions};
use crate::geojson::LonLatBox;
use crate::trace::ParsedWalk;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::UNIX_EPOCH;
use wipdr_core::FloorPlan;

/// Default cache folder, relative to the working directory.
pub const DEFAULT_CACHE_DIR: &str = "target/wipdr-cache";

/// Bumped whenever the cached types or the reader's behaviour change.
const FORMAT_VERSION: u32 = 2;
const MAGIC: &[u8; 8] = b"WIPDRFC2";

/// What [`read_floor_dir_cached_with`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CacheOutcome {
    /// The floor came from the cache.
    Hit,
    /// No usable cache file: the floor was read from source and the cache written.
    Miss,
    /// Read from source; writing the cache failed (logged), the result is still good.
    MissNotStored,
}

#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
struct SourceStamp {
    name: String,
    size: u64,
    modified_ns: i128,
}

#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
struct CacheKey {
    format: u32,
    crate_version: String,
    dir: String,
    options: ReadOptions,
    sources: Vec<SourceStamp>,
}

fn stamp(path: &Path) -> Result<SourceStamp, IoError> {
    let meta = std::fs::metadata(path).map_err(|e| IoError::file(path, e))?;
    let modified_ns = meta
        .modified()
        .ok()
        .map(|m| match m.duration_since(UNIX_EPOCH) {
            Ok(d) => d.as_nanos() as i128,
            Err(e) => -(e.duration().as_nanos() as i128),
        })
        .unwrap_or(0);
    Ok(SourceStamp {
        name: path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        size: meta.len(),
        modified_ns,
    })
}

fn key_of(dir: &Path, options: &ReadOptions) -> Result<CacheKey, IoError> {
    let mut sources = vec![
        stamp(&dir.join(floor::FLOOR_INFO))?,
        stamp(&dir.join(floor::GEOJSON_MAP))?,
    ];
    for f in floor::walk_files(dir)? {
        sources.push(stamp(&f)?);
    }
    Ok(CacheKey {
        format: FORMAT_VERSION,
        crate_version: env!("CARGO_PKG_VERSION").to_string(),
        dir: dir.display().to_string(),
        options: options.clone(),
        sources,
    })
}

/// FNV-1a, 64 bit: a stable hash for cache file names (std's hasher may change between
/// Rust versions).
fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The cache file of a floor folder.
pub fn cache_file(dir: &Path, cache_dir: &Path) -> PathBuf {
    let canonical = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    let h = fnv1a(canonical.to_string_lossy().as_bytes());
    cache_dir.join(format!("floor-{h:016x}.bin"))
}

fn config() -> bincode::config::Configuration {
    bincode::config::standard()
}

fn try_load(file: &Path, key: &CacheKey) -> Option<FloorData> {
    let bytes = std::fs::read(file).ok()?;
    let rest = bytes.strip_prefix(MAGIC.as_slice())?;
    let (len_bytes, rest) = rest.split_at_checked(8)?;
    let key_len = usize::try_from(u64::from_le_bytes(len_bytes.try_into().ok()?)).ok()?;
    let (key_bytes, body) = rest.split_at_checked(key_len)?;
    let (stored, _): (CacheKey, usize) = match bincode::serde::decode_from_slice(
        key_bytes,
        config(),
    ) {
        Ok(k) => k,
        Err(e) => {
            tracing::warn!(file = %file.display(), error = %e, "unreadable cache key, re-reading");
            return None;
        }
    };
    if &stored != key {
        tracing::info!(file = %file.display(), "cache is stale, re-reading the floor");
        return None;
    }
    match decode_body(body) {
        Some(floor) => Some(floor),
        None => {
            tracing::warn!(file = %file.display(), "unreadable cache, re-reading");
            None
        }
    }
}

/// The floor without its walks, as encoded in the cache.
type FloorHead = (String, PathBuf, f64, f64, FloorPlan, LonLatBox, usize);

/// Splits a `u64`-length-prefixed blob off the front of `bytes`.
fn take_blob<'a>(bytes: &mut &'a [u8]) -> Option<&'a [u8]> {
    let (len, rest) = bytes.split_at_checked(8)?;
    let len = usize::try_from(u64::from_le_bytes(len.try_into().ok()?)).ok()?;
    let (blob, rest) = rest.split_at_checked(len)?;
    *bytes = rest;
    Some(blob)
}

fn push_blob(out: &mut Vec<u8>, blob: &[u8]) {
    out.extend_from_slice(&(blob.len() as u64).to_le_bytes());
    out.extend_from_slice(blob);
}

/// Body: the head blob, then one blob per walk; the walks decode in parallel.
fn decode_body(mut body: &[u8]) -> Option<FloorData> {
    let head = take_blob(&mut body)?;
    let (head, _): (FloorHead, usize) = bincode::serde::decode_from_slice(head, config()).ok()?;
    let mut blobs = Vec::new();
    while !body.is_empty() {
        blobs.push(take_blob(&mut body)?);
    }
    let walks = blobs
        .par_iter()
        .map(|b| {
            bincode::serde::decode_from_slice::<ParsedWalk, _>(b, config())
                .ok()
                .map(|(w, _)| w)
        })
        .collect::<Option<Vec<_>>>()?;
    let (name, dir, width, height, plan, lonlat_box, skipped_features) = head;
    Some(FloorData {
        name,
        dir,
        width,
        height,
        plan,
        lonlat_box,
        skipped_features,
        walks,
    })
}

fn encode_body(floor: &FloorData) -> Result<Vec<u8>, String> {
    let head = (
        &floor.name,
        &floor.dir,
        floor.width,
        floor.height,
        &floor.plan,
        &floor.lonlat_box,
        floor.skipped_features,
    );
    let head = bincode::serde::encode_to_vec(head, config()).map_err(|e| e.to_string())?;
    let walks = floor
        .walks
        .par_iter()
        .map(|w| bincode::serde::encode_to_vec(w, config()).map_err(|e| e.to_string()))
        .collect::<Result<Vec<_>, _>>()?;
    let mut out =
        Vec::with_capacity(head.len() + walks.iter().map(|w| w.len() + 8).sum::<usize>() + 8);
    push_blob(&mut out, &head);
    for w in &walks {
        push_blob(&mut out, w);
    }
    Ok(out)
}

fn store(file: &Path, key: &CacheKey, floor: &FloorData) -> Result<(), String> {
    let key_bytes = bincode::serde::encode_to_vec(key, config()).map_err(|e| e.to_string())?;
    let body = encode_body(floor)?;
    if let Some(parent) = file.parent() {
        std::fs::create_dir_all(parent).map_err(|e| e.to_string())?;
    }
    let tmp = file.with_extension(format!("tmp{}", std::process::id()));
    let write = || -> std::io::Result<()> {
        let mut f = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
        f.write_all(MAGIC)?;
        f.write_all(&(key_bytes.len() as u64).to_le_bytes())?;
        f.write_all(&key_bytes)?;
        f.write_all(&body)?;
        f.flush()?;
        drop(f);
        std::fs::rename(&tmp, file)
    };
    write().map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        e.to_string()
    })
}

/// Reads a floor folder through the cache in `cache_dir` (see the module doc).
///
/// ```no_run
/// use wipdr_io::{cache, floor::ReadOptions};
/// let floor = cache::read_floor_dir_cached(
///     "../shared/data/ilc20/site1/F1",
///     cache::DEFAULT_CACHE_DIR,
///     &ReadOptions::default(),
/// ).unwrap();
/// assert!(!floor.walks.is_empty());
/// ```
pub fn read_floor_dir_cached(
    dir: impl AsRef<Path>,
    cache_dir: impl AsRef<Path>,
    options: &ReadOptions,
) -> Result<FloorData, IoError> {
    read_floor_dir_cached_with(dir, cache_dir, options, &|| {}).map(|(f, _)| f)
}

/// [`read_floor_dir_cached`] saying whether the cache was used, with a per-walk callback
/// for progress bars (called only when walks are read from source).
pub fn read_floor_dir_cached_with(
    dir: impl AsRef<Path>,
    cache_dir: impl AsRef<Path>,
    options: &ReadOptions,
    on_walk: &(dyn Fn() + Sync),
) -> Result<(FloorData, CacheOutcome), IoError> {
    let dir = dir.as_ref();
    if !dir.join(floor::FLOOR_INFO).is_file() || !dir.join(floor::GEOJSON_MAP).is_file() {
        // Let the reader produce its typed error.
        return floor::read_floor_dir(dir, options).map(|f| (f, CacheOutcome::MissNotStored));
    }
    let key = key_of(dir, options)?;
    let file = cache_file(dir, cache_dir.as_ref());
    if let Some(floor) = try_load(&file, &key) {
        tracing::debug!(file = %file.display(), "floor from cache");
        return Ok((floor, CacheOutcome::Hit));
    }
    let floor = floor::read_floor_dir_with_progress(dir, options, on_walk)?;
    match store(&file, &key, &floor) {
        Ok(()) => Ok((floor, CacheOutcome::Miss)),
        Err(e) => {
            tracing::warn!(file = %file.display(), error = %e, "could not write the cache");
            Ok((floor, CacheOutcome::MissNotStored))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{geojson, trace};
    use wipdr_core::{FloorPlan, Point2, Polygon, Walk, Waypoint};

    fn make_floor(dir: &Path) {
        std::fs::create_dir_all(dir.join(floor::WALKS_DIR)).unwrap();
        floor::write_floor_info(dir.join(floor::FLOOR_INFO), 10.0, 10.0).unwrap();
        let sq = Polygon::new(
            vec![
                Point2::new(0.0, 0.0),
                Point2::new(10.0, 0.0),
                Point2::new(10.0, 10.0),
                Point2::new(0.0, 10.0),
            ],
            vec![],
        )
        .unwrap();
        let plan = FloorPlan::new(10.0, 10.0, vec![sq], vec![]).unwrap();
        geojson::write_floor_plan(
            dir.join(floor::GEOJSON_MAP),
            &plan,
            geojson::LonLatBox::around(1.0, 1.0, 10.0, 10.0),
        )
        .unwrap();
        write_walk(dir, "w1", 1);
    }

    fn write_walk(dir: &Path, id: &str, n: usize) {
        let mut w = Walk::default();
        for i in 0..n {
            w.waypoints.push(Waypoint {
                t: i as i64,
                position: Point2::new(1.0, 1.0),
            });
        }
        trace::write_walk_file(&w, dir.join(floor::WALKS_DIR).join(format!("{id}.txt"))).unwrap();
    }

    #[test]
    fn cache_hits_and_invalidates() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("floor");
        let cache = tmp.path().join("cache");
        make_floor(&dir);
        let opts = ReadOptions::default();
        let (a, o) = read_floor_dir_cached_with(&dir, &cache, &opts, &|| {}).unwrap();
        assert_eq!(o, CacheOutcome::Miss);
        let (b, o) = read_floor_dir_cached_with(&dir, &cache, &opts, &|| {}).unwrap();
        assert_eq!(o, CacheOutcome::Hit);
        assert_eq!(a, b);
        // A changed walk file (different size) is re-read.
        write_walk(&dir, "w1", 3);
        let (c, o) = read_floor_dir_cached_with(&dir, &cache, &opts, &|| {}).unwrap();
        assert_eq!(o, CacheOutcome::Miss);
        assert_eq!(c.walks[0].walk.waypoints.len(), 3);
        // An added walk too.
        write_walk(&dir, "w2", 2);
        let (d, o) = read_floor_dir_cached_with(&dir, &cache, &opts, &|| {}).unwrap();
        assert_eq!(o, CacheOutcome::Miss);
        assert_eq!(d.walks.len(), 2);
        // Other options, other key.
        let mut other = opts.clone();
        other.limits.max_scan_entries = 7;
        let (_, o) = read_floor_dir_cached_with(&dir, &cache, &other, &|| {}).unwrap();
        assert_eq!(o, CacheOutcome::Miss);
        // A corrupted cache file is ignored and rewritten.
        let file = cache_file(&dir, &cache);
        std::fs::write(&file, b"WIPDRFC2garbage").unwrap();
        let (e, o) = read_floor_dir_cached_with(&dir, &cache, &other, &|| {}).unwrap();
        assert_eq!(o, CacheOutcome::Miss);
        assert_eq!(e.walks, d.walks);
        let (_, o) = read_floor_dir_cached_with(&dir, &cache, &other, &|| {}).unwrap();
        assert_eq!(o, CacheOutcome::Hit);
    }
}
