//! Unit tests of `cache.rs`, kept in their own file.

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
        w.waypoints
            .push(Waypoint::new(i as i64, Point2::new(1.0, 1.0)));
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
    assert_eq!(o, CacheOutcome::Rebuilt);
    assert_eq!(e.walks, d.walks);
    let (_, o) = read_floor_dir_cached_with(&dir, &cache, &other, &|| {}).unwrap();
    assert_eq!(o, CacheOutcome::Hit);
    // A truncated body too.
    let bytes = std::fs::read(&file).unwrap();
    std::fs::write(&file, &bytes[..bytes.len() - 3]).unwrap();
    let (f, o) = read_floor_dir_cached_with(&dir, &cache, &other, &|| {}).unwrap();
    assert_eq!(o, CacheOutcome::Rebuilt);
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

fn encode_walk(p: &ParsedWalk) -> std::io::Result<Vec<u8>> {
    let mut out = Vec::new();
    encode_walk_into(p, &mut out)?;
    Ok(out)
}

/// A floor with two walks carrying IMU samples, so every part of the file has bytes.
fn make_rich_floor(dir: &Path) {
    make_floor(dir);
    let text = "#\tstartTime:100\n\
100\tTYPE_ACCELEROMETER\t1.5\t-2.0\t9.81\t3\n\
101\tTYPE_GYROSCOPE\t0.1\t0.2\t0.3\n\
104\tTYPE_ACCELEROMETER_UNCALIBRATED\t1\t2\t3\t0.1\t0.2\t0.3\t3\n\
107\tTYPE_WIFI\tnet\ta8:0c:ca:03:9d:d7\t-49\t2422\t90\n\
109\tTYPE_WAYPOINT\t1\t2\n";
    std::fs::write(dir.join(floor::WALKS_DIR).join("w2.txt"), text).unwrap();
}

#[test]
fn every_flipped_byte_is_caught_removed_and_rebuilt() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("floor");
    let cache = tmp.path().join("cache");
    make_rich_floor(&dir);
    let opts = ReadOptions::default();
    let (good, o) = read_floor_dir_cached_with(&dir, &cache, &opts, &|| {}).unwrap();
    assert_eq!(o, CacheOutcome::Miss);
    let file = cache_file(&dir, &cache);
    let bytes = std::fs::read(&file).unwrap();
    assert!(bytes.len() > 400, "{}", bytes.len());
    for at in 0..bytes.len() {
        // Every byte, its low bit or its high bit.
        let mask = if at % 2 == 0 { 0x01u8 } else { 0x80 };
        let mut bad = bytes.clone();
        bad[at] ^= mask;
        std::fs::write(&file, &bad).unwrap();
        let (f, o) = read_floor_dir_cached_with(&dir, &cache, &opts, &|| {}).unwrap();
        assert_eq!(o, CacheOutcome::Rebuilt, "byte {at} ^ {mask:#x}");
        assert_eq!(f, good, "byte {at}");
        // Rebuilt identically.
        assert_eq!(std::fs::read(&file).unwrap(), bytes, "byte {at}");
    }
    // Truncated anywhere, or padded.
    for n in (0..bytes.len()).step_by(7) {
        std::fs::write(&file, &bytes[..n]).unwrap();
        let (_, o) = read_floor_dir_cached_with(&dir, &cache, &opts, &|| {}).unwrap();
        assert_eq!(o, CacheOutcome::Rebuilt, "cut at {n}");
    }
    std::fs::write(&file, [&bytes[..], &[0]].concat()).unwrap();
    let (_, o) = read_floor_dir_cached_with(&dir, &cache, &opts, &|| {}).unwrap();
    assert_eq!(o, CacheOutcome::Rebuilt);
    let (_, o) = read_floor_dir_cached_with(&dir, &cache, &opts, &|| {}).unwrap();
    assert_eq!(o, CacheOutcome::Hit);
}

/// Rewrites the header's field at `at` and its own checksum, as a buggy or future
/// writer could.
fn patch_header(bytes: &mut [u8], at: usize, value: &[u8]) {
    bytes[at..at + value.len()].copy_from_slice(value);
    let own = crc(&bytes[..HEADER_BYTES - 4]);
    bytes[HEADER_BYTES - 4..HEADER_BYTES].copy_from_slice(&own.to_le_bytes());
}

#[test]
fn other_versions_and_absurd_lengths_are_rebuilt_not_allocated() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("floor");
    let cache = tmp.path().join("cache");
    make_rich_floor(&dir);
    let opts = ReadOptions::default();
    read_floor_dir_cached_with(&dir, &cache, &opts, &|| {}).unwrap();
    let file = cache_file(&dir, &cache);
    let bytes = std::fs::read(&file).unwrap();
    let cases: [(usize, Vec<u8>); 4] = [
        (8, (FORMAT_VERSION + 1).to_le_bytes().to_vec()),
        (8, 6u32.to_le_bytes().to_vec()),
        (12, (u64::MAX - 3).to_le_bytes().to_vec()),
        (20, 6_124_895_493_223_874_589u64.to_le_bytes().to_vec()),
    ];
    for (at, value) in cases {
        let mut bad = bytes.clone();
        patch_header(&mut bad, at, &value);
        std::fs::write(&file, &bad).unwrap();
        let (_, o) = read_floor_dir_cached_with(&dir, &cache, &opts, &|| {}).unwrap();
        assert_eq!(o, CacheOutcome::Rebuilt, "field at {at}");
        assert_eq!(std::fs::read(&file).unwrap(), bytes);
    }
    // The previous format's file (magic `WIPDRFC6`), and an empty file.
    for old in [&b"WIPDRFC6\x10\0\0\0\0\0\0\0"[..], b""] {
        std::fs::write(&file, old).unwrap();
        let (_, o) = read_floor_dir_cached_with(&dir, &cache, &opts, &|| {}).unwrap();
        assert_eq!(o, CacheOutcome::Rebuilt);
    }
}

#[test]
fn settings_disable_and_the_size_cap_evicts_least_recently_used() {
    let tmp = tempfile::tempdir().unwrap();
    let cache = tmp.path().join("cache");
    let opts = ReadOptions::default();
    let off = CacheSettings {
        dir: cache.clone(),
        enabled: false,
        max_bytes: DEFAULT_MAX_BYTES,
    };
    let dirs: Vec<PathBuf> = (0..3).map(|i| tmp.path().join(format!("f{i}"))).collect();
    for d in &dirs {
        make_rich_floor(d);
    }
    let (_, o) = read_floor(&dirs[0], &off, &opts, &|| {}).unwrap();
    assert_eq!(o, CacheOutcome::Disabled);
    assert!(!cache.exists(), "a disabled cache writes nothing");
    // A stranger's file in the folder is never touched.
    std::fs::create_dir_all(&cache).unwrap();
    std::fs::write(cache.join("notes.txt"), "mine").unwrap();
    let mut on = CacheSettings::in_dir(&cache);
    read_floor(&dirs[0], &on, &opts, &|| {}).unwrap();
    let one = info(&cache).unwrap().total_bytes();
    assert!(one > 0);
    // Room for two files: the third write evicts the least recently used one, which is
    // f1 after f0 was hit again.
    on.max_bytes = 2 * one + one / 2;
    let set_time = |d: &Path, s: u64| {
        std::fs::OpenOptions::new()
            .write(true)
            .open(cache_file(d, &cache))
            .unwrap()
            .set_modified(UNIX_EPOCH + std::time::Duration::from_secs(s))
            .unwrap();
    };
    read_floor(&dirs[1], &on, &opts, &|| {}).unwrap();
    set_time(&dirs[0], 1_000);
    set_time(&dirs[1], 2_000);
    let (_, o) = read_floor(&dirs[0], &on, &opts, &|| {}).unwrap();
    assert_eq!(o, CacheOutcome::Hit);
    let (_, o) = read_floor(&dirs[2], &on, &opts, &|| {}).unwrap();
    assert_eq!(o, CacheOutcome::Miss);
    let listed = info(&cache).unwrap();
    let names: Vec<PathBuf> = listed.files.iter().map(|f| f.path.clone()).collect();
    assert_eq!(names.len(), 2, "{names:?}");
    assert!(names.contains(&cache_file(&dirs[0], &cache)));
    assert!(names.contains(&cache_file(&dirs[2], &cache)));
    assert!(listed.total_bytes() <= on.max_bytes);
    // A cap below one file still keeps the file just written.
    on.max_bytes = 1;
    let (_, o) = read_floor(&dirs[1], &on, &opts, &|| {}).unwrap();
    assert_eq!(o, CacheOutcome::Miss);
    let listed = info(&cache).unwrap();
    assert_eq!(listed.files.len(), 1);
    assert_eq!(listed.files[0].path, cache_file(&dirs[1], &cache));
    // Clear removes the cache files only.
    std::fs::write(cache.join("floor-0123456789abcdef.tmp42"), "x").unwrap();
    let removed = clear(&cache).unwrap();
    assert_eq!(removed.files.len(), 2);
    assert!(info(&cache).unwrap().files.is_empty());
    assert_eq!(
        std::fs::read_to_string(cache.join("notes.txt")).unwrap(),
        "mine"
    );
    assert!(!info(tmp.path().join("nowhere")).unwrap().exists);
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
