//! A binary cache of parsed floors (bincode 2.0.1 and a raw IMU layout, kept behind this one
//! module so it can be swapped for another encoding).
//!
//! ## Where
//!
//! The library never reads the environment: callers choose the cache with a
//! [`CacheSettings`] (folder, on/off, size cap). [`DEFAULT_CACHE_DIR`] is the documented
//! default folder (relative to the working directory, i.e. the workspace's `target/` when
//! run with cargo); the `wipdr` tool moves it with `--cache-dir DIR` or `WIPDR_CACHE_DIR`,
//! turns it off with `--no-cache`, and reports or empties it with `wipdr cache info|clear`.
//! Never put it inside `../shared`. Only files named `floor-*.bin` (and their temporary
//! `floor-*.tmp*` siblings) are ever written, evicted or removed in the folder.
//!
//! ## Layout
//!
//! One file per floor folder, `<cache dir>/floor-<hash of the folder path>.bin`:
//!
//! - a fixed header of [`HEADER_BYTES`]: magic `WIPDRFC\0`, the format version (`u32`), the
//!   offset and length of the table (`u64` each), the table's CRC-32 and the header's own
//!   CRC-32;
//! - the walk blobs, then the floor head blob (name, size, plan, skipped walks), one after
//!   the other;
//! - the table at the end (bincode): the key, and the length and CRC-32 of every blob.
//!
//! The key holds the format version, this crate's version, the [`ReadOptions`], and for
//! every source file (`floor_info.json`, `geojson_map.json`, each walk) its name, size and
//! modification time. A cache file is used only when its key equals the key of the folder as
//! it is now, so a changed, added or removed source file makes the floor be re-read (and the
//! cache rewritten).
//!
//! ## Bad files
//!
//! No length read from a cache file is trusted before the checksum covering it passes: the
//! header's CRC covers the table's offset, length and CRC; the table's length must match the
//! file size and stay below [`MAX_TABLE_BYTES`]; each blob is checked against the CRC in the
//! table before it is decoded, and bincode decodes with a size limit. A file that fails any
//! check (flipped byte, truncated, padded, another version, another program's file) is
//! logged with `tracing::warn!`, removed, and rebuilt from source ([`CacheOutcome::Rebuilt`]);
//! reading never aborts on a cache file.
//!
//! ## Size
//!
//! After writing a file, the folder is trimmed to [`CacheSettings::max_bytes`] (default
//! [`DEFAULT_MAX_BYTES`], 2 GiB) by removing the least recently used cache files (a hit
//! refreshes its file's modification time). The file just written is never evicted, so one
//! floor larger than the cap still caches. The encoder streams each walk to a buffered file
//! writer: writing a cache needs no memory beyond the floor being cached.

use crate::IoError;
use crate::floor::{self, FloorData, ReadOptions, SkippedWalk};
use crate::geojson::LonLatBox;
use crate::logfile_folder;
use crate::trace::{ParseReport, ParsedWalk};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};
use wipdr_core::{
    BeaconSample, FloorPlan, GeoFrame, ImuStreams, PressureSample, RotationVectorSample,
    UncalibratedSample, Vec3Sample, Walk, WalkMeta, Waypoint, WifiScan,
};

/// Default cache folder, relative to the working directory.
pub const DEFAULT_CACHE_DIR: &str = "target/wipdr-cache";

/// Default size cap of the cache folder: 2 GiB.
pub const DEFAULT_MAX_BYTES: u64 = 2 * 1024 * 1024 * 1024;

/// Bumped whenever the cached types, the file layout or the reader's behaviour change.
pub const FORMAT_VERSION: u32 = 9;
const MAGIC: &[u8; 8] = b"WIPDRFC\0";
/// Bytes of the fixed file header: magic, version, table offset, table length, table CRC,
/// header CRC.
pub const HEADER_BYTES: usize = 8 + 4 + 8 + 8 + 4 + 4;
/// Largest table (key and blob index) a cache file may have: 64 MiB (a floor of 10 000 walk
/// files needs about 1 MiB).
pub const MAX_TABLE_BYTES: u64 = 64 * 1024 * 1024;
/// Most bytes bincode may claim (allocate) while decoding one blob: 2 GiB, checked before
/// each container is allocated.
const DECODE_LIMIT: usize = 1 << 31;

/// Where the cache lives, whether it is used, and how large it may grow.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CacheSettings {
    /// The cache folder (created when first written).
    pub dir: PathBuf,
    /// Read and write the cache (`false`: always read from source, never write).
    pub enabled: bool,
    /// Size cap of the folder's cache files, bytes; least recently used files beyond it are
    /// removed after each write (default [`DEFAULT_MAX_BYTES`]).
    pub max_bytes: u64,
}

impl Default for CacheSettings {
    fn default() -> Self {
        Self::in_dir(DEFAULT_CACHE_DIR)
    }
}

impl CacheSettings {
    /// An enabled cache in `dir` with the default size cap.
    pub fn in_dir(dir: impl Into<PathBuf>) -> Self {
        Self {
            dir: dir.into(),
            enabled: true,
            max_bytes: DEFAULT_MAX_BYTES,
        }
    }

    /// A disabled cache: floors are always read from source.
    pub fn disabled() -> Self {
        Self {
            enabled: false,
            ..Self::default()
        }
    }
}

/// What [`read_floor`] (or [`read_floor_dir_cached_with`]) did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CacheOutcome {
    /// The floor came from the cache.
    Hit,
    /// No cache file, or one of an older state of the folder (stale key): the floor was read
    /// from source and the cache written.
    Miss,
    /// The cache file was bad (failed a checksum, truncated, another version, undecodable):
    /// it was logged and removed, the floor read from source and the cache written anew.
    Rebuilt,
    /// Read from source and not cached: writing the cache failed (logged), or a walk file
    /// was skipped for a possibly transient reason ([`SkippedWalk::transient`]); the result
    /// is still good.
    MissNotStored,
    /// The cache is turned off ([`CacheSettings::enabled`]): read from source.
    Disabled,
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

/// Length and CRC-32 of one blob.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
struct Span {
    len: u64,
    crc: u32,
}

/// The table at the end of a cache file.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
struct Table {
    key: CacheKey,
    walks: Vec<Span>,
    head: Span,
}

fn stamp(path: &Path) -> Result<SourceStamp, IoError> {
    let meta = std::fs::metadata(path).map_err(|e| IoError::file(path, e))?;
    let modified_ns = meta
        .modified()
        .ok()
        .map(|m| match m.duration_since(UNIX_EPOCH) {
            Ok(d) => i128::try_from(d.as_nanos()).unwrap_or(i128::MAX),
            Err(e) => i128::try_from(e.duration().as_nanos()).map_or(i128::MIN, |n| -n),
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
    let mut sources = Vec::new();
    let walks = if logfile_folder::is_logfile_dir(dir) {
        floor::walk_files(logfile_folder::logfile_dir(dir))?
    } else {
        sources.push(stamp(&dir.join(floor::FLOOR_INFO))?);
        sources.push(stamp(&dir.join(floor::GEOJSON_MAP))?);
        floor::walk_files(dir)?
    };
    for f in walks {
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

type EncodeConfig =
    bincode::config::Configuration<bincode::config::LittleEndian, bincode::config::Fixint>;
type DecodeConfig<const N: usize> = bincode::config::Configuration<
    bincode::config::LittleEndian,
    bincode::config::Fixint,
    bincode::config::Limit<N>,
>;

/// Fixed-size integers: the many 13-digit Unix-ms times take 8 bytes instead of 9 and
/// decode faster than as varints.
fn config() -> EncodeConfig {
    bincode::config::standard().with_fixed_int_encoding()
}

/// The same wire format, decoded with a limit on what bincode may allocate.
fn decode_config() -> DecodeConfig<DECODE_LIMIT> {
    config().with_limit::<DECODE_LIMIT>()
}

fn table_config() -> DecodeConfig<{ MAX_TABLE_BYTES as usize * 4 }> {
    config().with_limit::<{ MAX_TABLE_BYTES as usize * 4 }>()
}

fn crc(bytes: &[u8]) -> u32 {
    crc32fast::hash(bytes)
}

/// Why a cache file was not used.
#[derive(Debug)]
enum LoadFail {
    /// No file (or it cannot be opened).
    Missing,
    /// A sound file of another state of the folder.
    Stale,
    /// A bad file: the reason.
    Bad(String),
}

fn bad(reason: impl Into<String>) -> LoadFail {
    LoadFail::Bad(reason.into())
}

fn read_header(r: &mut impl Read, size: u64) -> Result<(u64, u64, u32), LoadFail> {
    let mut h = [0u8; HEADER_BYTES];
    r.read_exact(&mut h)
        .map_err(|_| bad("shorter than the header"))?;
    if &h[..8] != MAGIC {
        return Err(bad("not a wipdr cache file (magic)"));
    }
    let u32_at = |at: usize| u32::from_le_bytes([h[at], h[at + 1], h[at + 2], h[at + 3]]);
    let u64_at = |at: usize| {
        let mut a = [0u8; 8];
        a.copy_from_slice(&h[at..at + 8]);
        u64::from_le_bytes(a)
    };
    if u32_at(HEADER_BYTES - 4) != crc(&h[..HEADER_BYTES - 4]) {
        return Err(bad("header checksum mismatch"));
    }
    let version = u32_at(8);
    if version != FORMAT_VERSION {
        return Err(bad(format!(
            "format version {version}, this build reads {FORMAT_VERSION}"
        )));
    }
    let (offset, len, table_crc) = (u64_at(12), u64_at(20), u32_at(28));
    if len > MAX_TABLE_BYTES
        || offset.checked_add(len) != Some(size)
        || offset < HEADER_BYTES as u64
    {
        return Err(bad(format!(
            "table at {offset}+{len} does not end the {size}-byte file"
        )));
    }
    Ok((offset, len, table_crc))
}

/// Reads exactly `len` bytes (already checked against the file size) at `at`.
fn read_at(file: &Path, at: u64, len: u64) -> Result<Vec<u8>, LoadFail> {
    let mut f = std::fs::File::open(file).map_err(|e| bad(format!("reopen: {e}")))?;
    f.seek(SeekFrom::Start(at))
        .map_err(|e| bad(format!("seek: {e}")))?;
    let len = usize::try_from(len).map_err(|_| bad("blob larger than memory"))?;
    let mut blob = vec![0u8; len];
    f.read_exact(&mut blob)
        .map_err(|e| bad(format!("read: {e}")))?;
    Ok(blob)
}

fn verified(blob: Vec<u8>, span: Span, what: &str) -> Result<Vec<u8>, LoadFail> {
    if crc(&blob) == span.crc {
        Ok(blob)
    } else {
        Err(bad(format!("{what}: checksum mismatch")))
    }
}

fn try_load(file: &Path, key: &CacheKey) -> Result<FloorData, LoadFail> {
    let Ok(f) = std::fs::File::open(file) else {
        return Err(LoadFail::Missing);
    };
    let size = f
        .metadata()
        .map_err(|e| bad(format!("metadata: {e}")))?
        .len();
    let mut r = std::io::BufReader::new(f);
    let (offset, len, table_crc) = read_header(&mut r, size)?;
    let table = read_at(file, offset, len)?;
    let table = verified(
        table,
        Span {
            len,
            crc: table_crc,
        },
        "table",
    )?;
    let (table, used): (Table, usize) = bincode::serde::decode_from_slice(&table, table_config())
        .map_err(|e| bad(format!("table: {e}")))?;
    if used as u64 != len {
        return Err(bad("table: trailing bytes"));
    }
    if &table.key != key {
        return Err(LoadFail::Stale);
    }
    // Lay the blobs out from the (checksummed) lengths; they must fill the file up to the table.
    let mut at = HEADER_BYTES as u64;
    let mut spans = Vec::with_capacity(table.walks.len());
    for span in table.walks.iter().chain([&table.head]) {
        let end = at
            .checked_add(span.len)
            .filter(|&e| e <= offset)
            .ok_or_else(|| bad("blob beyond the table"))?;
        spans.push((at, *span));
        at = end;
    }
    if at != offset {
        return Err(bad("blobs do not fill the file"));
    }
    let (head_at, head_span) = spans.pop().ok_or_else(|| bad("no head"))?;
    let head_bytes = verified(read_at(file, head_at, head_span.len)?, head_span, "head")?;
    let (head, used): (FloorHead, usize) =
        bincode::serde::decode_from_slice(&head_bytes, decode_config())
            .map_err(|e| bad(format!("head: {e}")))?;
    if used != head_bytes.len() {
        return Err(bad("head: trailing bytes"));
    }
    let walks = spans
        .par_iter()
        .enumerate()
        .map(|(i, &(at, span))| {
            let blob = verified(read_at(file, at, span.len)?, span, &format!("walk {i}"))?;
            decode_walk(&blob).ok_or_else(|| bad(format!("walk {i}: undecodable")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let (name, dir, width, height, plan, lonlat_box, skipped_features, skipped_walks, geo_frame) =
        head;
    Ok(FloorData {
        name,
        dir,
        width,
        height,
        plan,
        lonlat_box,
        geo_frame,
        skipped_features,
        walks,
        skipped_walks,
    })
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
    Option<GeoFrame>,
);

/// A walk without its IMU streams, as encoded with bincode in the cache.
type WalkRest = (
    WalkMeta,
    Vec<Waypoint>,
    Vec<WifiScan>,
    Vec<BeaconSample>,
    Vec<PressureSample>,
    ParseReport,
);

/// Counts and checksums what goes through it (beneath a `BufWriter`, so it sees large
/// chunks).
struct Tap<W> {
    inner: W,
    crc: crc32fast::Hasher,
    len: u64,
}

impl<W: Write> Tap<W> {
    fn take_span(&mut self) -> Span {
        let crc = std::mem::take(&mut self.crc).finalize();
        Span {
            len: std::mem::take(&mut self.len),
            crc,
        }
    }
}

impl<W: Write> Write for Tap<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.crc.update(&buf[..n]);
        self.len += n as u64;
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

fn encode_err(e: bincode::error::EncodeError) -> std::io::Error {
    std::io::Error::other(e.to_string())
}

/// One walk: bincode of everything but the IMU, then the IMU streams in a raw little-endian
/// layout (most of the bytes; decoding them is a tight loop instead of serde's per-field
/// calls), each stream a `u64` count then its samples. Streamed into `out`.
fn encode_walk_into(p: &ParsedWalk, out: &mut impl Write) -> std::io::Result<()> {
    let w = &p.walk;
    let rest = (
        &w.meta,
        &w.waypoints,
        &w.wifi,
        &w.beacons,
        &w.pressure,
        &p.report,
    );
    bincode::serde::encode_into_std_write(rest, out, config()).map_err(encode_err)?;
    let imu = &w.imu;
    for s in [&imu.accelerometer, &imu.gyroscope, &imu.magnetometer] {
        out.write_all(&(s.len() as u64).to_le_bytes())?;
        for x in s.iter() {
            put_sample(out, x.t, &x.v, None, x.accuracy)?;
        }
    }
    out.write_all(&(imu.rotation_vector.len() as u64).to_le_bytes())?;
    for x in &imu.rotation_vector {
        put_sample(out, x.t, &x.v, None, x.accuracy)?;
    }
    for s in [
        &imu.accelerometer_uncalibrated,
        &imu.gyroscope_uncalibrated,
        &imu.magnetometer_uncalibrated,
    ] {
        out.write_all(&(s.len() as u64).to_le_bytes())?;
        for x in s.iter() {
            put_sample(out, x.t, &x.v, Some(&x.bias), x.accuracy)?;
        }
    }
    Ok(())
}

fn put_sample(
    out: &mut impl Write,
    t: i64,
    v: &[f64; 3],
    bias: Option<&[f64; 3]>,
    acc: i8,
) -> std::io::Result<()> {
    let mut buf = [0u8; UNCAL_SAMPLE_BYTES];
    buf[..8].copy_from_slice(&t.to_le_bytes());
    let mut at = 8;
    for x in v.iter().chain(bias.into_iter().flatten()) {
        buf[at..at + 8].copy_from_slice(&x.to_le_bytes());
        at += 8;
    }
    buf[at] = acc.to_le_bytes()[0];
    out.write_all(&buf[..=at])
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

fn decode_walk(b: &[u8]) -> Option<ParsedWalk> {
    let ((meta, waypoints, wifi, beacons, pressure, report), used): (WalkRest, usize) =
        bincode::serde::decode_from_slice(b, decode_config()).ok()?;
    let mut b = b.get(used..)?;
    let vec3 = |raw: &[u8]| -> Vec<Vec3Sample> {
        raw.chunks_exact(SAMPLE_BYTES)
            .map(|c| Vec3Sample {
                t: i64_at(c, 0),
                v: [f64_at(c, 8), f64_at(c, 16), f64_at(c, 24)],
                accuracy: i8::from_le_bytes([c[32]]),
            })
            .collect()
    };
    let uncal = |raw: &[u8]| -> Vec<UncalibratedSample> {
        raw.chunks_exact(UNCAL_SAMPLE_BYTES)
            .map(|c| UncalibratedSample {
                t: i64_at(c, 0),
                v: [f64_at(c, 8), f64_at(c, 16), f64_at(c, 24)],
                bias: [f64_at(c, 32), f64_at(c, 40), f64_at(c, 48)],
                accuracy: i8::from_le_bytes([c[56]]),
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
            pressure,
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

/// Writes the cache file: header placeholder, walk blobs and head streamed through one
/// buffered writer (CRC and length taken per blob), the table, then the real header.
fn store(file: &Path, key: &CacheKey, floor: &FloorData) -> std::io::Result<()> {
    if let Some(parent) = file.parent() {
        std::fs::create_dir_all(parent)?;
    }
    let tmp = file.with_extension(format!("tmp{}", std::process::id()));
    let write = || -> std::io::Result<()> {
        let f = std::fs::File::create(&tmp)?;
        let mut w = BufWriter::with_capacity(
            1 << 20,
            Tap {
                inner: f,
                crc: crc32fast::Hasher::new(),
                len: 0,
            },
        );
        w.write_all(&[0u8; HEADER_BYTES])?;
        w.flush()?;
        w.get_mut().take_span();
        let mut walks = Vec::with_capacity(floor.walks.len());
        for p in &floor.walks {
            encode_walk_into(p, &mut w)?;
            w.flush()?;
            walks.push(w.get_mut().take_span());
        }
        let head = (
            &floor.name,
            &floor.dir,
            floor.width,
            floor.height,
            &floor.plan,
            &floor.lonlat_box,
            floor.skipped_features,
            &floor.skipped_walks,
            &floor.geo_frame,
        );
        bincode::serde::encode_into_std_write(head, &mut w, config()).map_err(encode_err)?;
        w.flush()?;
        let head = w.get_mut().take_span();
        let offset = HEADER_BYTES as u64 + walks.iter().map(|s| s.len).sum::<u64>() + head.len;
        let table = Table {
            key: key.clone(),
            walks,
            head,
        };
        let table = bincode::serde::encode_to_vec(&table, config()).map_err(encode_err)?;
        if table.len() as u64 > MAX_TABLE_BYTES {
            return Err(std::io::Error::other(format!(
                "cache table of {} bytes exceeds {MAX_TABLE_BYTES}",
                table.len()
            )));
        }
        w.write_all(&table)?;
        let mut header = [0u8; HEADER_BYTES];
        header[..8].copy_from_slice(MAGIC);
        header[8..12].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
        header[12..20].copy_from_slice(&offset.to_le_bytes());
        header[20..28].copy_from_slice(&(table.len() as u64).to_le_bytes());
        header[28..32].copy_from_slice(&crc(&table).to_le_bytes());
        let own = crc(&header[..HEADER_BYTES - 4]);
        header[HEADER_BYTES - 4..].copy_from_slice(&own.to_le_bytes());
        let mut f = w.into_inner().map_err(|e| e.into_error())?.inner;
        f.seek(SeekFrom::Start(0))?;
        f.write_all(&header)?;
        drop(f);
        std::fs::rename(&tmp, file)
    };
    write().inspect_err(|_| {
        let _ = std::fs::remove_file(&tmp);
    })
}

/// Reads a floor folder through the cache in `cache_dir` (see the module doc), with the
/// default size cap.
///
/// ```no_run
/// use wipdr_io::{cache, floor::ReadOptions};
/// let floor = cache::read_floor_dir_cached(
///     wipdr_io::data_root().join("ilc20/site1/F1"),
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
    read_floor(
        dir,
        &CacheSettings::in_dir(cache_dir.as_ref()),
        options,
        on_walk,
    )
}

/// Reads a folder from its source files: a folder of IPIN logfiles
/// ([`logfile_folder::read_logfile_dir`]) or an ILC floor folder
/// ([`floor::read_floor_dir`]).
pub fn read_source(
    dir: &Path,
    options: &ReadOptions,
    on_walk: &(dyn Fn() + Sync),
) -> Result<FloorData, IoError> {
    if logfile_folder::is_logfile_dir(dir) {
        logfile_folder::read_logfile_dir_with_progress(dir, options, on_walk)
    } else {
        floor::read_floor_dir_with_progress(dir, options, on_walk)
    }
}

/// Reads a floor folder (ILC) or a folder of IPIN logfiles as `cache` says: through the cache when enabled (see the module
/// doc), from source otherwise; `on_walk` is called after each walk read from source.
///
/// ```
/// use wipdr_core::FloorPlan;
/// use wipdr_io::cache::{self, CacheOutcome, CacheSettings};
/// use wipdr_io::{floor, LonLatBox, ReadOptions};
///
/// let tmp = tempfile::tempdir().unwrap();
/// let dir = tmp.path().join("site").join("F1");
/// let plan = FloorPlan::rectangle(20.0, 10.0).unwrap();
/// floor::write_floor_dir(&dir, &plan, LonLatBox::around(8.0, 47.0, 20.0, 10.0), []).unwrap();
/// let settings = CacheSettings::in_dir(tmp.path().join("cache"));
/// let opts = ReadOptions::default();
/// let (_, o) = cache::read_floor(&dir, &settings, &opts, &|| {}).unwrap();
/// assert_eq!(o, CacheOutcome::Miss);
/// let (_, o) = cache::read_floor(&dir, &settings, &opts, &|| {}).unwrap();
/// assert_eq!(o, CacheOutcome::Hit);
/// let (_, o) = cache::read_floor(&dir, &CacheSettings::disabled(), &opts, &|| {}).unwrap();
/// assert_eq!(o, CacheOutcome::Disabled);
/// ```
pub fn read_floor(
    dir: impl AsRef<Path>,
    cache: &CacheSettings,
    options: &ReadOptions,
    on_walk: &(dyn Fn() + Sync),
) -> Result<(FloorData, CacheOutcome), IoError> {
    let dir = dir.as_ref();
    if !cache.enabled {
        return read_source(dir, options, on_walk).map(|f| (f, CacheOutcome::Disabled));
    }
    if !logfile_folder::is_logfile_dir(dir)
        && (!dir.join(floor::FLOOR_INFO).is_file() || !dir.join(floor::GEOJSON_MAP).is_file())
    {
        // Let the reader produce its typed error.
        return floor::read_floor_dir(dir, options).map(|f| (f, CacheOutcome::MissNotStored));
    }
    let key = key_of(dir, options)?;
    let file = cache_file(dir, &cache.dir);
    let mut rebuilt = false;
    match try_load(&file, &key) {
        Ok(floor) => {
            tracing::debug!(file = %file.display(), "floor from cache");
            touch(&file);
            return Ok((floor, CacheOutcome::Hit));
        }
        Err(LoadFail::Missing) => {}
        Err(LoadFail::Stale) => {
            tracing::info!(file = %file.display(), "cache is stale, re-reading the floor");
        }
        Err(LoadFail::Bad(reason)) => {
            tracing::warn!(file = %file.display(), %reason, "bad cache file removed; re-reading the floor");
            if let Err(e) = std::fs::remove_file(&file) {
                tracing::warn!(file = %file.display(), error = %e, "could not remove the bad cache file");
            }
            rebuilt = true;
        }
    }
    let floor = read_source(dir, options, on_walk)?;
    if floor.skipped_walks.iter().any(|s| s.transient) {
        // The walk may read next time although its size and time are unchanged.
        tracing::info!(floor = %dir.display(), "a walk file failed to open or read: cache not written");
        return Ok((floor, CacheOutcome::MissNotStored));
    }
    match store(&file, &key, &floor) {
        Ok(()) => {
            if let Err(e) = evict(&cache.dir, cache.max_bytes, Some(&file)) {
                tracing::warn!(dir = %cache.dir.display(), error = %e.full_message(), "cache eviction failed");
            }
            let outcome = if rebuilt {
                CacheOutcome::Rebuilt
            } else {
                CacheOutcome::Miss
            };
            Ok((floor, outcome))
        }
        Err(e) => {
            tracing::warn!(file = %file.display(), error = %e, "could not write the cache");
            Ok((floor, CacheOutcome::MissNotStored))
        }
    }
}

/// Marks a cache file as just used (its modification time is the LRU clock).
fn touch(file: &Path) {
    let r = std::fs::OpenOptions::new()
        .write(true)
        .open(file)
        .and_then(|f| f.set_modified(SystemTime::now()));
    if let Err(e) = r {
        tracing::debug!(file = %file.display(), error = %e, "could not refresh the cache file's time");
    }
}

/// One file in the cache folder.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CacheFile {
    /// The file.
    pub path: PathBuf,
    /// Its size, bytes.
    pub bytes: u64,
    /// When it was last used (written or hit).
    pub last_used: SystemTime,
    /// A leftover temporary file of an interrupted write (`floor-*.tmp*`).
    pub temporary: bool,
}

/// What the cache folder holds ([`info`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CacheInfo {
    /// The folder.
    pub dir: PathBuf,
    /// Whether the folder exists.
    pub exists: bool,
    /// The cache files, least recently used first.
    pub files: Vec<CacheFile>,
}

impl CacheInfo {
    /// Total size of the cache files, bytes.
    pub fn total_bytes(&self) -> u64 {
        self.files.iter().map(|f| f.bytes).sum()
    }
}

/// Whether `name` is one of this module's files: `floor-<16 hex>.bin` or a temporary
/// `floor-<16 hex>.tmp<pid>`.
fn cache_file_kind(name: &str) -> Option<bool> {
    let rest = name.strip_prefix("floor-")?;
    let (hash, ext) = rest.split_at_checked(16)?;
    if !hash.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    if ext == ".bin" {
        Some(false)
    } else {
        let pid = ext.strip_prefix(".tmp")?;
        (!pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit())).then_some(true)
    }
}

/// Lists the cache folder's files (only this module's, see the module doc), least recently
/// used first. A missing folder is an empty cache.
pub fn info(cache_dir: impl AsRef<Path>) -> Result<CacheInfo, IoError> {
    let dir = cache_dir.as_ref();
    let mut files = Vec::new();
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Ok(CacheInfo {
                dir: dir.to_path_buf(),
                exists: false,
                files,
            });
        }
        Err(e) => return Err(IoError::file(dir, e)),
    };
    for entry in entries {
        let entry = entry.map_err(|e| IoError::file(dir, e))?;
        let name = entry.file_name();
        let Some(temporary) = name.to_str().and_then(cache_file_kind) else {
            continue;
        };
        let Ok(meta) = entry.metadata() else {
            continue;
        };
        if !meta.is_file() {
            continue;
        }
        files.push(CacheFile {
            path: entry.path(),
            bytes: meta.len(),
            last_used: meta.modified().unwrap_or(UNIX_EPOCH),
            temporary,
        });
    }
    files.sort_by(|a, b| a.last_used.cmp(&b.last_used).then(a.path.cmp(&b.path)));
    Ok(CacheInfo {
        dir: dir.to_path_buf(),
        exists: true,
        files,
    })
}

/// What [`evict`] or [`clear`] removed.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Removed {
    /// The files removed.
    pub files: Vec<PathBuf>,
    /// Their total size, bytes.
    pub bytes: u64,
}

/// Removes the least recently used cache files until the rest fit in `max_bytes`, never
/// `keep` (the file just written). Temporary files of other processes are left alone.
pub fn evict(
    cache_dir: impl AsRef<Path>,
    max_bytes: u64,
    keep: Option<&Path>,
) -> Result<Removed, IoError> {
    let info = info(cache_dir)?;
    let mut total = info.total_bytes();
    let mut removed = Removed::default();
    for f in &info.files {
        if total <= max_bytes {
            break;
        }
        if f.temporary || keep.is_some_and(|k| k == f.path) {
            continue;
        }
        match std::fs::remove_file(&f.path) {
            Ok(()) => {
                tracing::info!(file = %f.path.display(), bytes = f.bytes, max_bytes, "cache file evicted (least recently used)");
                total -= f.bytes;
                removed.bytes += f.bytes;
                removed.files.push(f.path.clone());
            }
            Err(e) => return Err(IoError::file(&f.path, e)),
        }
    }
    Ok(removed)
}

/// Removes every cache file (and leftover temporary file) from the folder; other files
/// and the folder itself stay.
pub fn clear(cache_dir: impl AsRef<Path>) -> Result<Removed, IoError> {
    let info = info(cache_dir)?;
    let mut removed = Removed::default();
    for f in info.files {
        std::fs::remove_file(&f.path).map_err(|e| IoError::file(&f.path, e))?;
        removed.bytes += f.bytes;
        removed.files.push(f.path);
    }
    Ok(removed)
}

#[cfg(test)]
#[path = "cache_tests.rs"]
mod tests;
