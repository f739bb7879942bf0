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
use crate::floor::{self, FloorData, ReadOptions, SkippedWalk};
use crate::geojson::LonLatBox;
use crate::trace::{ParseReport, ParsedWalk};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::UNIX_EPOCH;
use wipdr_core::{
    BeaconSample, FloorPlan, ImuStreams, RotationVectorSample, UncalibratedSample, Vec3Sample,
    Walk, WalkMeta, Waypoint, WifiScan,
};

/// Default cache folder, relative to the working directory.
pub const DEFAULT_CACHE_DIR: &str = "target/wipdr-cache";

/// Bumped whenever the cached types or the reader's behaviour change.
const FORMAT_VERSION: u32 = 6;
const MAGIC: &[u8; 8] = b"WIPDRFC6";

/// What [`read_floor_dir_cached_with`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CacheOutcome {
    /// The floor came from the cache.
    Hit,
    /// No usable cache file: the floor was read from source and the cache written.
    Miss,
    /// Read from source and not cached: writing the cache failed (logged), or a walk file
    /// was skipped for a possibly transient reason ([`SkippedWalk::transient`]); the result
    /// is still good.
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

/// Fixed-size integers: the many 13-digit Unix-ms times take 8 bytes instead of 9 and
/// decode faster than as varints.
fn config() -> bincode::config::Configuration<bincode::config::LittleEndian, bincode::config::Fixint>
{
    bincode::config::standard().with_fixed_int_encoding()
}

/// Reads a `u64`-length-prefixed blob, refusing lengths beyond `max` bytes.
fn read_blob(r: &mut impl Read, max: u64) -> Option<Vec<u8>> {
    let mut len = [0u8; 8];
    r.read_exact(&mut len).ok()?;
    let len = u64::from_le_bytes(len);
    if len > max {
        return None;
    }
    let mut blob = vec![0u8; usize::try_from(len).ok()?];
    r.read_exact(&mut blob).ok()?;
    Some(blob)
}

/// File layout: magic, key blob, head blob, index blob (the walk blobs' lengths), then the
/// walk blobs, which are read and decoded in parallel.
fn try_load(file: &Path, key: &CacheKey) -> Option<FloorData> {
    let size = std::fs::metadata(file).ok()?.len();
    let mut r = std::io::BufReader::new(std::fs::File::open(file).ok()?);
    let mut magic = [0u8; 8];
    r.read_exact(&mut magic).ok()?;
    if &magic != MAGIC {
        return None;
    }
    let key_bytes = read_blob(&mut r, size)?;
    let (stored, _): (CacheKey, usize) = match bincode::serde::decode_from_slice(
        &key_bytes,
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
    let floor = (|| {
        let head = read_blob(&mut r, size)?;
        let (head, _): (FloorHead, usize) =
            bincode::serde::decode_from_slice(&head, config()).ok()?;
        let index = read_blob(&mut r, size)?;
        let mut start = r.stream_position().ok()?;
        let mut spans = Vec::with_capacity(index.len() / 8);
        for len in index.chunks_exact(8) {
            let len = u64::from_le_bytes(len.try_into().ok()?);
            let end = start.checked_add(len)?;
            if end > size {
                return None;
            }
            spans.push((start, len));
            start = end;
        }
        if start != size {
            return None;
        }
        let walks = spans
            .par_iter()
            .map(|&(at, len)| {
                let mut f = std::fs::File::open(file).ok()?;
                f.seek(SeekFrom::Start(at)).ok()?;
                let mut blob = vec![0u8; usize::try_from(len).ok()?];
                f.read_exact(&mut blob).ok()?;
                decode_walk(&blob)
            })
            .collect::<Option<Vec<_>>>()?;
        let (name, dir, width, height, plan, lonlat_box, skipped_features, skipped_walks) = head;
        Some(FloorData {
            name,
            dir,
            width,
            height,
            plan,
            lonlat_box,
            skipped_features,
            walks,
            skipped_walks,
        })
    })();
    if floor.is_none() {
        tracing::warn!(file = %file.display(), "unreadable cache, re-reading");
    }
    floor
}

/// The floor without its walks, as encoded in the cache.
type FloorHead = (
    String,
    PathBuf,
    f64,
    f64,
    FloorPlan,
    LonLatBox,
    usize,
    Vec<SkippedWalk>,
);

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

/// A walk without its IMU streams, as encoded with bincode in the cache.
type WalkRest = (
    WalkMeta,
    Vec<Waypoint>,
    Vec<WifiScan>,
    Vec<BeaconSample>,
    ParseReport,
);

/// One walk: a bincode blob of everything but the IMU, then the IMU streams in a raw
/// little-endian layout (most of the bytes; decoding them is a tight loop instead of
/// serde's per-field calls).
fn encode_walk(p: &ParsedWalk) -> Result<Vec<u8>, String> {
    let w = &p.walk;
    let rest = (&w.meta, &w.waypoints, &w.wifi, &w.beacons, &p.report);
    let rest = bincode::serde::encode_to_vec(rest, config()).map_err(|e| e.to_string())?;
    let imu = &w.imu;
    let mut out = Vec::with_capacity(rest.len() + 8 + imu.accelerometer.len() * 7 * 60);
    push_blob(&mut out, &rest);
    for s in [&imu.accelerometer, &imu.gyroscope, &imu.magnetometer] {
        out.extend_from_slice(&(s.len() as u64).to_le_bytes());
        for x in s.iter() {
            put_sample(&mut out, x.t, &x.v, None, x.accuracy);
        }
    }
    out.extend_from_slice(&(imu.rotation_vector.len() as u64).to_le_bytes());
    for x in &imu.rotation_vector {
        put_sample(&mut out, x.t, &x.v, None, x.accuracy);
    }
    for s in [
        &imu.accelerometer_uncalibrated,
        &imu.gyroscope_uncalibrated,
        &imu.magnetometer_uncalibrated,
    ] {
        out.extend_from_slice(&(s.len() as u64).to_le_bytes());
        for x in s.iter() {
            put_sample(&mut out, x.t, &x.v, Some(&x.bias), x.accuracy);
        }
    }
    Ok(out)
}

fn put_sample(out: &mut Vec<u8>, t: i64, v: &[f64; 3], bias: Option<&[f64; 3]>, acc: i8) {
    out.extend_from_slice(&t.to_le_bytes());
    for x in v.iter().chain(bias.into_iter().flatten()) {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out.extend_from_slice(&acc.to_le_bytes());
}

/// Bytes of one raw sample: time, 3 (or 6) f64, accuracy.
const SAMPLE_BYTES: usize = 8 + 24 + 1;
const UNCAL_SAMPLE_BYTES: usize = 8 + 48 + 1;

fn f64_at(b: &[u8], at: usize) -> f64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[at..at + 8]);
    f64::from_le_bytes(a)
}

fn i64_at(b: &[u8], at: usize) -> i64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[at..at + 8]);
    i64::from_le_bytes(a)
}

/// The raw samples of one stream: `(count, bytes)` split off the front of `bytes`.
fn take_samples<'a>(bytes: &mut &'a [u8], size: usize) -> Option<&'a [u8]> {
    let (n, rest) = bytes.split_at_checked(8)?;
    let n = usize::try_from(u64::from_le_bytes(n.try_into().ok()?)).ok()?;
    let (raw, rest) = rest.split_at_checked(n.checked_mul(size)?)?;
    *bytes = rest;
    Some(raw)
}

fn decode_walk(mut b: &[u8]) -> Option<ParsedWalk> {
    let rest = take_blob(&mut b)?;
    let ((meta, waypoints, wifi, beacons, report), _): (WalkRest, usize) =
        bincode::serde::decode_from_slice(rest, config()).ok()?;
    let vec3 = |raw: &[u8]| -> Vec<Vec3Sample> {
        raw.chunks_exact(SAMPLE_BYTES)
            .map(|c| Vec3Sample {
                t: i64_at(c, 0),
                v: [f64_at(c, 8), f64_at(c, 16), f64_at(c, 24)],
                accuracy: c[32] as i8,
            })
            .collect()
    };
    let uncal = |raw: &[u8]| -> Vec<UncalibratedSample> {
        raw.chunks_exact(UNCAL_SAMPLE_BYTES)
            .map(|c| UncalibratedSample {
                t: i64_at(c, 0),
                v: [f64_at(c, 8), f64_at(c, 16), f64_at(c, 24)],
                bias: [f64_at(c, 32), f64_at(c, 40), f64_at(c, 48)],
                accuracy: c[56] as i8,
            })
            .collect()
    };
    let accelerometer = vec3(take_samples(&mut b, SAMPLE_BYTES)?);
    let gyroscope = vec3(take_samples(&mut b, SAMPLE_BYTES)?);
    let magnetometer = vec3(take_samples(&mut b, SAMPLE_BYTES)?);
    let rotation_vector = vec3(take_samples(&mut b, SAMPLE_BYTES)?)
        .into_iter()
        .map(|s| RotationVectorSample {
            t: s.t,
            v: s.v,
            accuracy: s.accuracy,
        })
        .collect();
    let accelerometer_uncalibrated = uncal(take_samples(&mut b, UNCAL_SAMPLE_BYTES)?);
    let gyroscope_uncalibrated = uncal(take_samples(&mut b, UNCAL_SAMPLE_BYTES)?);
    let magnetometer_uncalibrated = uncal(take_samples(&mut b, UNCAL_SAMPLE_BYTES)?);
    if !b.is_empty() {
        return None;
    }
    Some(ParsedWalk {
        walk: Walk {
            meta,
            waypoints,
            wifi,
            beacons,
            imu: ImuStreams {
                accelerometer,
                gyroscope,
                magnetometer,
                rotation_vector,
                accelerometer_uncalibrated,
                gyroscope_uncalibrated,
                magnetometer_uncalibrated,
            },
        },
        report,
    })
}

/// Everything after the key: head blob, index blob, walk blobs (see [`try_load`]).
fn encode_body(floor: &FloorData) -> Result<Vec<u8>, String> {
    let head = (
        &floor.name,
        &floor.dir,
        floor.width,
        floor.height,
        &floor.plan,
        &floor.lonlat_box,
        floor.skipped_features,
        &floor.skipped_walks,
    );
    let head = bincode::serde::encode_to_vec(head, config()).map_err(|e| e.to_string())?;
    let walks = floor
        .walks
        .par_iter()
        .map(encode_walk)
        .collect::<Result<Vec<_>, _>>()?;
    let index: Vec<u8> = walks
        .iter()
        .flat_map(|w| (w.len() as u64).to_le_bytes())
        .collect();
    let mut out = Vec::with_capacity(
        head.len() + index.len() + walks.iter().map(Vec::len).sum::<usize>() + 16,
    );
    push_blob(&mut out, &head);
    push_blob(&mut out, &index);
    for w in &walks {
        out.extend_from_slice(w);
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
    if floor.skipped_walks.iter().any(|s| s.transient) {
        // The walk may read next time although its size and time are unchanged.
        tracing::info!(floor = %dir.display(), "a walk file failed to open or read: cache not written");
        return Ok((floor, CacheOutcome::MissNotStored));
    }
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
    use wipdr_core::{FloorPlan, Point2, Walk, Waypoint};

    fn make_floor(dir: &Path) {
        let plan = FloorPlan::rectangle(10.0, 10.0).unwrap();
        let bbox = geojson::LonLatBox::around(1.0, 1.0, 10.0, 10.0);
        floor::write_floor_dir(dir, &plan, bbox, []).unwrap();
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
        std::fs::write(&file, [&MAGIC[..], b"garbage"].concat()).unwrap();
        let (e, o) = read_floor_dir_cached_with(&dir, &cache, &other, &|| {}).unwrap();
        assert_eq!(o, CacheOutcome::Miss);
        assert_eq!(e.walks, d.walks);
        let (_, o) = read_floor_dir_cached_with(&dir, &cache, &other, &|| {}).unwrap();
        assert_eq!(o, CacheOutcome::Hit);
        // A truncated body too.
        let bytes = std::fs::read(&file).unwrap();
        std::fs::write(&file, &bytes[..bytes.len() - 3]).unwrap();
        let (f, o) = read_floor_dir_cached_with(&dir, &cache, &other, &|| {}).unwrap();
        assert_eq!(o, CacheOutcome::Miss);
        assert_eq!(f.walks, d.walks);
        assert_eq!(std::fs::read(&file).unwrap(), bytes);
    }

    #[test]
    fn skipped_walks_survive_the_cache() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("floor");
        let cache = tmp.path().join("cache");
        make_floor(&dir);
        let bad = dir.join(floor::WALKS_DIR).join("w0.txt");
        std::fs::write(&bad, format!("1\tTYPE_WAYPOINT\t1\t2{}\n", " ".repeat(500))).unwrap();
        let mut opts = ReadOptions::default();
        opts.limits.max_line_bytes = 256;
        let (a, o) = read_floor_dir_cached_with(&dir, &cache, &opts, &|| {}).unwrap();
        assert_eq!(o, CacheOutcome::Miss);
        assert_eq!(a.walks.len(), 1);
        assert_eq!(a.skipped_walks.len(), 1);
        assert_eq!(a.skipped_walks[0].path, bad);
        assert!(!a.skipped_walks[0].transient);
        let (b, o) = read_floor_dir_cached_with(&dir, &cache, &opts, &|| {}).unwrap();
        assert_eq!(o, CacheOutcome::Hit);
        assert_eq!(a, b);
        // Strict options are another key, and fail.
        opts.strict = true;
        let e = read_floor_dir_cached_with(&dir, &cache, &opts, &|| {}).unwrap_err();
        assert!(matches!(e, IoError::LineTooLong { line: 1, .. }), "{e}");
    }

    #[test]
    fn walk_blob_round_trips_every_stream() {
        let text = "#\tstartTime:100\tBrand:B\n\
100\tTYPE_ACCELEROMETER\t1.5\t-2.0\t9.81\t3\n\
101\tTYPE_GYROSCOPE\t0.1\t0.2\t0.3\n\
102\tTYPE_MAGNETIC_FIELD\t30\t-5\t-40\t2\n\
103\tTYPE_ROTATION_VECTOR\t0.06\t0.07\t0.57\t3\n\
104\tTYPE_ACCELEROMETER_UNCALIBRATED\t1\t2\t3\t0.1\t0.2\t0.3\t3\n\
105\tTYPE_GYROSCOPE_UNCALIBRATED\t1\t2\t3\t0.1\t0.2\t0.3\n\
106\tTYPE_MAGNETIC_FIELD_UNCALIBRATED\t1\t2\t3\t-0.1\t-0.2\t-0.3\t1\n\
107\tTYPE_WIFI\tnet\ta8:0c:ca:03:9d:d7\t-49\t2422\t90\n\
108\tTYPE_BEACON\tU\t0\t0\t-56\t-93\t45.03\tE0:78:A3:3D:B5:D6\t108\n\
109\tTYPE_WAYPOINT\t1\t2\n\
99\tTYPE_BLUE\tx\n";
        let p = trace::read_walk_from(text.as_bytes(), "w", &crate::Limits::default()).unwrap();
        assert_eq!(p.walk.imu.magnetometer_uncalibrated.len(), 1);
        let blob = encode_walk(&p).unwrap();
        assert_eq!(decode_walk(&blob), Some(p.clone()));
        // Truncated or padded blobs are refused, never a panic.
        for n in 0..blob.len() {
            assert_eq!(decode_walk(&blob[..n]), None, "cut at {n}");
        }
        let mut padded = blob.clone();
        padded.push(0);
        assert_eq!(decode_walk(&padded), None);
        // A count claiming more samples than there are bytes.
        let mut huge = blob[..blob.len() - 8 - UNCAL_SAMPLE_BYTES].to_vec();
        huge.extend_from_slice(&u64::MAX.to_le_bytes());
        assert_eq!(decode_walk(&huge), None);
    }
}
