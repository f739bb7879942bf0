//! # wipdr-io — readers and writers that survive real data
//!
//! Brings the recorded inputs of every paper's evaluation into the [`wipdr_core`] vocabulary:
//! the Indoor Location Competition 2.0 walks (smartphone IMU, Wi-Fi scans and surveyed
//! waypoints; the real-data setting of papers 000 §4, 001 §4, 002 §5 and 004 §5, see
//! `docs/evaluation.md`), their floor plans, the IPIN competition's logfiles (the
//! field's second benchmark, with floors and a barometer), and the public fingerprint
//! benchmarks.
//! It also writes walks and plans in the same formats, so synthetic floors (crate `wipdr-sim`)
//! go through the real readers.
//!
//! ## Formats
//!
//! - [`trace`]: ILC 2.0 trace text, plain `.txt` or `.txt.gz` (gzip detected by its magic
//!   bytes; multi-member streams read with `MultiGzDecoder`). One record per line, tab
//!   separated: time (Unix ms), `TYPE_...`, values; `#` lines are tab-separated `key:value`
//!   headers. The reader sorts every stream by time, groups Wi-Fi lines sharing a time into
//!   one scan, keeps the most recent entry of a BSSID listed twice, splits run-on lines, and
//!   skips unknown or malformed records, counting them by kind with line numbers in a
//!   [`trace::ParseReport`]. [`trace::write_walk`] writes the same format deterministically.
//! - [`logfile`]: IPIN competition logfiles (GetSensorData app, `;`-separated, `%` header):
//!   fixed field positions, sensor times from the SensorTimestamp on the AppTimestamp clock,
//!   one Wi-Fi scan per run of lines sharing an AppTimestamp, POSI ground truth in degrees
//!   with floors; GNSS and the other unneeded types counted. [`logfile::write_logfile`]
//!   writes the format (fixtures). [`logfile_folder`]: a folder of them as one building, in
//!   a WGS84 tangent-plane metre frame ([`wipdr_core::GeoFrame`]).
//! - [`site`]: an ILC site folder (`F1/`, `F2/`, ...) as one building, levels from the floor
//!   folder names.
//! - [`floor`]: an ILC floor folder (`floor_info.json`, `geojson_map.json`,
//!   `path_data_files/*.txt.gz`), walks read in parallel (rayon); a walk file that cannot
//!   be read is skipped, logged and kept with its error in [`floor::FloorData::skipped_walks`]
//!   (or fails the floor with [`floor::ReadOptions::strict`]).
//! - [`geojson`]: the floor plan in lon/lat degrees, mapped into metres by sending the
//!   bounding box of the first feature (the outline) onto `[0, width] x [0, height]`
//!   (longitude to `x`, latitude to `y`); units keep their `name`.
//! - [`evaal`]: the IPIN competition's scoring files, a trial's ground truth (`GT_*.csv`) and
//!   the EvAAL API's estimates log (`*.est`), strict, errors naming file, line and field.
//! - [`fingerprint_csv`]: the fingerprint benchmark CSVs (`100` = not detected).
//! - [`cache`]: a bincode cache of parsed floors, keyed by each source file's size and
//!   modification time (default folder [`cache::DEFAULT_CACHE_DIR`]).
//!
//! [`data_root()`] is where the real data sets live (`$WIPDR_DATA`, else `../shared/data`
//! beside the workspace); [`real_data()`] finds a folder under it or says why it is missing.
//!
//! ## Limits
//!
//! Every reader is bounded by [`Limits`] (serde, configurable): line length (64 KiB),
//! decompressed bytes per trace (512 MiB), records per trace (8 M), entries per Wi-Fi scan
//! (8192), JSON file size (64 MiB), GeoJSON features (100 000) and vertices (2 M). Crossing a
//! limit is a typed [`IoError`] naming the file and line or field: a line of megabytes, a
//! gzip bomb, a scan of millions of entries or an absurd GeoJSON never exhaust memory or hang.
//! Times beyond +-2^53 ms ([`trace::MAX_ABS_TIME_MS`]) are skipped as bad records, so time
//! arithmetic downstream cannot overflow. Libraries here never print; they log with
//! `tracing` and return [`IoError`].
//!
//! ## Example
//!
//! ```
//! use wipdr_core::{Point2, Walk, Waypoint};
//! use wipdr_io::{trace, Limits};
//!
//! // Write a walk in the ILC format and read it back through the real reader.
//! let mut walk = Walk::default();
//! walk.meta.id = "demo".into();
//! walk.meta.start_time = Some(1_000);
//! walk.waypoints.push(Waypoint::new(1_000, Point2::new(3.0, 4.0)));
//! let mut text = Vec::new();
//! trace::write_walk(&walk, &mut text).unwrap();
//!
//! // A record that lost its newline, and an undocumented record type.
//! text.extend_from_slice(b"2000\tTYPE_WAYPOINT\t5.0\t6.01574559495421\tTYPE_BLUE\tx\n");
//! let parsed = trace::read_walk_from(&text[..], "demo", &Limits::default()).unwrap();
//! assert_eq!(parsed.walk.waypoints.len(), 2);
//! assert_eq!(parsed.report.run_on_lines_split, 1);
//! assert_eq!(parsed.report.skipped_of(trace::SkipKind::UnknownType), 1);
//! ```

pub mod any;
pub mod cache;
pub mod data_root;
pub mod error;
pub mod evaal;
pub mod fingerprint_csv;
pub mod floor;
pub mod geojson;
pub mod limits;
pub mod logfile;
pub mod logfile_folder;
pub mod sample_stream;
pub mod site;
pub mod trace;

pub use cache::read_floor_dir_cached;
pub use data_root::{DATA_ROOT_ENV, MissingData, data_root, real_data};
pub use error::IoError;
pub use floor::{FloorData, ReadOptions, SkippedWalk, read_floor_dir};
pub use geojson::LonLatBox;
pub use limits::Limits;
pub use trace::{ParseReport, ParsedWalk, read_walk, read_walk_from, write_walk, write_walk_file};
