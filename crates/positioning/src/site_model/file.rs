//! The site model file (`site.wipdr`): a checked header, then the model's data.
//!
//! ## Layout
//!
//! - a fixed header of [`HEADER_BYTES`]: the magic [`MAGIC`], the format version (`u32`), the
//!   payload's length (`u64`) and CRC-32, and the header's own CRC-32 (little-endian);
//! - the payload: bincode 2 of the model's data, its settings (the positioner config and the
//!   scheme table, whose tagged enums bincode cannot carry) as one JSON text inside, the
//!   radio map's table in sparse form (only the cells some scan heard:
//!   [`wipdr_fingerprint::radio_map::SparseCell`]).
//!
//! ## Bad files
//!
//! Nothing read from a file is trusted before the check that covers it: the file's size is
//! compared with [`MAX_MODEL_BYTES`] before it is read; the header's CRC covers the payload
//! length, which must equal the file's size less the header; the payload's CRC is checked
//! before it is decoded; bincode decodes with a size limit (and serde never preallocates more
//! than a megabyte on a length it reads), so a header or payload announcing 10^12 entries
//! fails without allocating them; the radio map's dense table is allocated only after its
//! shape is checked against [`MAX_MAP_CELLS`]; the decoded model is checked
//! ([`wipdr_fingerprint::RadioMap::check_consistent`], the config's validation, the
//! leave-one-out errors' [`super::LeaveOneOut::validate`]) before use.
//! Every failure is a [`SiteModelFileError`] naming the file and what differs.

use super::{SiteModel, SiteModelData, SiteModelError};
use serde::{Deserialize, Serialize};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use thiserror::Error;
use wipdr_fingerprint::radio_map::SparseCell;

/// The file's first eight bytes.
pub const MAGIC: &[u8; 8] = b"WIPDRSM\0";
/// Bumped whenever the saved types or the layout change; a file of another version is
/// refused with [`SiteModelFileError::Version`] (fit the site again). Version 3 added the
/// leave-one-walk-out Wi-Fi errors ([`super::LeaveOneOut`], optional within the version: a
/// model fit without them saves `None`). Version 4 added the positioner config's
/// `[likelihood]` section (the scan likelihood's settings).
pub const FORMAT_VERSION: u32 = 4;
/// Bytes of the fixed header: magic, version, payload length, payload CRC, header CRC.
pub const HEADER_BYTES: usize = 8 + 4 + 8 + 4 + 4;
/// Largest model file read: 2 GiB (the five ILC floors as one model take a few tens of MB).
pub const MAX_MODEL_BYTES: u64 = 2 * 1024 * 1024 * 1024;
/// Most cells (`reference points x APs`) of a saved radio map's dense table: 400 million
/// (4 GiB in memory; the two ILC sites as buildings have 39 and 35 million), checked before
/// the table is allocated.
pub const MAX_MAP_CELLS: usize = 400_000_000;
/// Most bytes bincode may claim while decoding a payload.
const DECODE_LIMIT: usize = 1 << 32;

/// Why a model file could not be read or written; every variant names the file.
#[derive(Debug, Error)]
pub enum SiteModelFileError {
    /// The file could not be opened, read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// The file is larger than [`MAX_MODEL_BYTES`].
    #[error("{path}: {bytes} bytes, more than a site model may have ({max})")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size.
        bytes: u64,
        /// The limit.
        max: u64,
    },
    /// The file is not a site model (another program's, or another wipdr file).
    #[error("{path}: not a wipdr site model ({found}); make one with `wipdr fit`")]
    NotAModel {
        /// The file.
        path: PathBuf,
        /// What it looks like instead.
        found: String,
    },
    /// A site model of another format version.
    #[error(
        "{path}: a site model of format version {found}, this program reads version {expected} (fit the site again with this version)"
    )]
    Version {
        /// The file.
        path: PathBuf,
        /// Its version.
        found: u32,
        /// The version this program reads.
        expected: u32,
    },
    /// The file ends inside the header.
    #[error(
        "{path}: {bytes} bytes, shorter than a site model's header ({HEADER_BYTES}): truncated"
    )]
    TruncatedHeader {
        /// The file.
        path: PathBuf,
        /// Its size.
        bytes: usize,
    },
    /// The file is shorter or longer than its header says.
    #[error(
        "{path}: the header announces {announced} payload bytes, the file holds {actual} (truncated or padded)"
    )]
    Length {
        /// The file.
        path: PathBuf,
        /// Payload length in the header.
        announced: u64,
        /// Payload bytes present.
        actual: u64,
    },
    /// A checksum does not match: the file was damaged.
    #[error("{path}: the {part}'s checksum does not match (the file is damaged)")]
    Checksum {
        /// The file.
        path: PathBuf,
        /// `header` or `payload`.
        part: &'static str,
    },
    /// The payload could not be decoded or encoded.
    #[error("{path}: {reason}")]
    Codec {
        /// The file.
        path: PathBuf,
        /// What failed.
        reason: String,
    },
    /// The decoded model is not one `wipdr fit` could have made.
    #[error("{path}: invalid site model: {reason}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

/// The payload: the model's data with its settings as JSON text.
#[derive(Serialize, Deserialize)]
struct Payload {
    settings_json: String,
    name: String,
    vocabulary: wipdr_fingerprint::ApVocabulary,
    points: Vec<wipdr_fingerprint::ReferencePoint>,
    radio: wipdr_fingerprint::RadioMapConfig,
    cells: Vec<SparseCell>,
    measured: Vec<super::MeasuredPoint>,
    coverage_includes_extension: bool,
    trail_segments: Vec<wipdr_core::Segment>,
    pressure_references: Vec<crate::PressureReference>,
    plan: Option<wipdr_core::FloorPlan>,
    geo_frame: Option<wipdr_core::GeoFrame>,
    floors: Vec<i32>,
    floor_heights_m: Vec<f64>,
    provenance: super::Provenance,
    leave_one_out: Option<super::LeaveOneOut>,
}

/// The settings part of the payload.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Settings {
    config: crate::PositionerConfig,
    schemes: std::collections::BTreeMap<String, wipdr_fusion::SchemeConfig>,
}

fn crc(bytes: &[u8]) -> u32 {
    crc32fast::hash(bytes)
}

fn codec_config() -> bincode::config::Configuration<
    bincode::config::LittleEndian,
    bincode::config::Varint,
    bincode::config::Limit<DECODE_LIMIT>,
> {
    bincode::config::standard().with_limit::<DECODE_LIMIT>()
}

/// What a file that is not a site model looks like, from its first bytes.
fn identify(head: &[u8]) -> String {
    if head.starts_with(b"WIPDRFC\0") {
        "it is a wipdr floor cache file".into()
    } else if head.starts_with(&[0x1f, 0x8b]) {
        "gzip data: a walk or logfile? give it to `wipdr locate --model` as input".into()
    } else if head.is_empty() {
        "the file is empty".into()
    } else {
        let shown: Vec<String> = head.iter().take(8).map(|b| format!("{b:02x}")).collect();
        format!("it starts with bytes {}", shown.join(" "))
    }
}

impl SiteModel {
    /// The model as the bytes of a model file.
    pub fn to_bytes(&self) -> Result<Vec<u8>, SiteModelFileError> {
        let codec = |reason: String| SiteModelFileError::Codec {
            path: PathBuf::new(),
            reason,
        };
        let d = self.data();
        let settings_json = serde_json::to_string(&Settings {
            config: d.config.clone(),
            schemes: d.schemes.clone(),
        })
        .map_err(|e| codec(format!("settings: {e}")))?;
        let payload = Payload {
            settings_json,
            name: d.name.clone(),
            vocabulary: d.radio_map.vocabulary().clone(),
            points: d.radio_map.points().to_vec(),
            radio: d.radio_map.config(),
            cells: d.radio_map.sparse_cells(),
            measured: d.measured.to_vec(),
            coverage_includes_extension: d.coverage_includes_extension,
            trail_segments: d.trail_segments.clone(),
            pressure_references: d.pressure_references.to_vec(),
            plan: d.plan.clone(),
            geo_frame: d.geo_frame,
            floors: d.floors.clone(),
            floor_heights_m: d.floor_heights_m.clone(),
            provenance: d.provenance.clone(),
            leave_one_out: d.leave_one_out.clone(),
        };
        let body = bincode::serde::encode_to_vec(&payload, codec_config())
            .map_err(|e| codec(format!("encoding: {e}")))?;
        let mut out = Vec::with_capacity(HEADER_BYTES + body.len());
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&(body.len() as u64).to_le_bytes());
        out.extend_from_slice(&crc(&body).to_le_bytes());
        let header_crc = crc(&out);
        out.extend_from_slice(&header_crc.to_le_bytes());
        out.extend_from_slice(&body);
        Ok(out)
    }

    /// A model from the bytes of a model file; `path` names it in errors.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self, SiteModelFileError> {
        let path_buf = || path.to_path_buf();
        let magic_len = bytes.len().min(MAGIC.len());
        if bytes.is_empty() || bytes[..magic_len] != MAGIC[..magic_len] {
            return Err(SiteModelFileError::NotAModel {
                path: path_buf(),
                found: identify(bytes),
            });
        }
        if bytes.len() < HEADER_BYTES {
            return Err(SiteModelFileError::TruncatedHeader {
                path: path_buf(),
                bytes: bytes.len(),
            });
        }
        let u32_at = |i: usize| {
            let mut b = [0u8; 4];
            b.copy_from_slice(&bytes[i..i + 4]);
            u32::from_le_bytes(b)
        };
        let mut b8 = [0u8; 8];
        b8.copy_from_slice(&bytes[12..20]);
        let announced = u64::from_le_bytes(b8);
        if u32_at(HEADER_BYTES - 4) != crc(&bytes[..HEADER_BYTES - 4]) {
            return Err(SiteModelFileError::Checksum {
                path: path_buf(),
                part: "header",
            });
        }
        let version = u32_at(8);
        if version != FORMAT_VERSION {
            return Err(SiteModelFileError::Version {
                path: path_buf(),
                found: version,
                expected: FORMAT_VERSION,
            });
        }
        let body = &bytes[HEADER_BYTES..];
        if announced != body.len() as u64 {
            return Err(SiteModelFileError::Length {
                path: path_buf(),
                announced,
                actual: body.len() as u64,
            });
        }
        if u32_at(20) != crc(body) {
            return Err(SiteModelFileError::Checksum {
                path: path_buf(),
                part: "payload",
            });
        }
        let (payload, used): (Payload, usize) =
            bincode::serde::decode_from_slice(body, codec_config()).map_err(|e| {
                SiteModelFileError::Codec {
                    path: path_buf(),
                    reason: format!("decoding the payload: {e}"),
                }
            })?;
        if used != body.len() {
            return Err(SiteModelFileError::Codec {
                path: path_buf(),
                reason: format!("{} bytes after the payload", body.len() - used),
            });
        }
        let invalid = |reason: String| SiteModelFileError::Invalid {
            path: path_buf(),
            reason,
        };
        let settings: Settings = serde_json::from_str(&payload.settings_json)
            .map_err(|e| invalid(format!("settings: {e}")))?;
        let radio_map = wipdr_fingerprint::RadioMap::from_sparse(
            payload.vocabulary,
            payload.points,
            payload.radio,
            &payload.cells,
            MAX_MAP_CELLS,
        )
        .map_err(|e| invalid(e.to_string()))?;
        let data = SiteModelData {
            name: payload.name,
            config: settings.config,
            schemes: settings.schemes,
            radio_map: std::sync::Arc::new(radio_map),
            measured: std::sync::Arc::new(payload.measured),
            coverage_includes_extension: payload.coverage_includes_extension,
            trail_segments: payload.trail_segments,
            pressure_references: std::sync::Arc::new(payload.pressure_references),
            plan: payload.plan,
            geo_frame: payload.geo_frame,
            floors: payload.floors,
            floor_heights_m: payload.floor_heights_m,
            provenance: payload.provenance,
            leave_one_out: payload.leave_one_out,
        };
        SiteModel::from_data(data, None).map_err(|e| match e {
            SiteModelError::File(f) => f,
            other => invalid(other.to_string()),
        })
    }

    /// Writes the model to `path` (through a temporary file beside it, renamed into place:
    /// a reader never sees half a model).
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), SiteModelFileError> {
        let path = path.as_ref();
        let io = |source| SiteModelFileError::Io {
            path: path.to_path_buf(),
            source,
        };
        let bytes = self.to_bytes().map_err(|e| match e {
            SiteModelFileError::Codec { reason, .. } => SiteModelFileError::Codec {
                path: path.to_path_buf(),
                reason,
            },
            other => other,
        })?;
        let mut tmp_name = path.as_os_str().to_owned();
        tmp_name.push(format!(".tmp{}", std::process::id()));
        let tmp = PathBuf::from(tmp_name);
        let write = || -> std::io::Result<()> {
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(&bytes)?;
            f.sync_all()?;
            std::fs::rename(&tmp, path)
        };
        write().map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            io(e)
        })
    }

    /// Reads a model file (see the [module docs](self) for the checks).
    pub fn load(path: impl AsRef<Path>) -> Result<Self, SiteModelFileError> {
        let path = path.as_ref();
        let io = |source| SiteModelFileError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = std::fs::File::open(path).map_err(io)?;
        let bytes = file.metadata().map_err(io)?.len();
        if bytes > MAX_MODEL_BYTES {
            return Err(SiteModelFileError::TooLarge {
                path: path.to_path_buf(),
                bytes,
                max: MAX_MODEL_BYTES,
            });
        }
        let mut buf = Vec::with_capacity(usize::try_from(bytes).unwrap_or(0));
        file.take(MAX_MODEL_BYTES + 1)
            .read_to_end(&mut buf)
            .map_err(io)?;
        Self::from_bytes(&buf, path)
    }
}
