//! The run identity of a sweep: what its results were measured on (the sweep spec, the base
//! config, the data, the shard), kept in a sidecar file beside the results, and the stable
//! hashes behind it.
//!
//! Hashes are FNV-1a 64 ([`StableHasher`]), written as 16 hex digits, over:
//! - the spec and the base config: their canonical JSON ([`canonical_json`]: object keys
//!   sorted, compact), so a field reordered in a file or a default written out explicitly
//!   does not change them, and any changed value does;
//! - each config of the sweep (base config with the point's parameters set): its canonical
//!   JSON; every results row carries it ([`crate::sweep::SweepRow::config_hash`]);
//! - each floor: its label and the content of the parsed floor (plan, size, walks with every
//!   sample, parse reports, skipped walk files), serialised as JSON. The folder path is left
//!   out, so a copy of the data elsewhere (a cluster node's scratch disk) is the same data;
//!   a changed, added or removed walk, or other read options, is not. It costs one pass over
//!   the parsed data (walks hashed in parallel), small beside one evaluation.

use super::SweepError;
use super::spec::SweepSpec;
use crate::config::EvalConfig;
use crate::input::FloorInput;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The version of the sidecar format.
pub const IDENTITY_FORMAT: u32 = 1;

/// A stable 64-bit FNV-1a hasher (the same on every machine and Rust release, unlike
/// `std`'s `DefaultHasher`); also an `io::Write` sink, so a value can be serialised into it.
#[derive(Debug, Clone, Copy)]
pub struct StableHasher(u64);

impl Default for StableHasher {
    fn default() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}

impl StableHasher {
    /// Feeds bytes.
    pub fn update(&mut self, bytes: &[u8]) {
        let mut h = self.0;
        for &b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
        self.0 = h;
    }

    /// Feeds a string with its length (so concatenations cannot collide).
    pub fn update_str(&mut self, s: &str) {
        self.update(&(s.len() as u64).to_le_bytes());
        self.update(s.as_bytes());
    }

    /// The hash as 16 lowercase hex digits.
    pub fn hex(&self) -> String {
        format!("{:016x}", self.0)
    }
}

impl std::io::Write for StableHasher {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.update(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Compact JSON with every object's keys sorted: one text per value, whatever the order its
/// fields were written or serialised in.
pub fn canonical_json(v: &Value) -> String {
    let mut out = String::new();
    write_canonical(v, &mut out);
    out
}

fn write_canonical(v: &Value, out: &mut String) {
    match v {
        Value::Object(map) => {
            let mut keys: Vec<&String> = map.keys().collect();
            keys.sort();
            out.push('{');
            for (i, k) in keys.iter().enumerate() {
                if i > 0 {
                    out.push(',');
                }
                out.push_str(&Value::String((*k).clone()).to_string());
                out.push(':');
                write_canonical(&map[k.as_str()], out);
            }
            out.push('}');
        }
        Value::Array(items) => {
            out.push('[');
            for (i, item) in items.iter().enumerate() {
                if i > 0 {
                    out.push(',');
                }
                write_canonical(item, out);
            }
            out.push(']');
        }
        scalar => out.push_str(&scalar.to_string()),
    }
}

/// The hash of a JSON value's canonical text.
pub fn json_hash(v: &Value) -> String {
    let mut h = StableHasher::default();
    h.update(canonical_json(v).as_bytes());
    h.hex()
}

fn to_json<T: Serialize>(what: &str, v: &T) -> Result<Value, SweepError> {
    serde_json::to_value(v).map_err(|e| SweepError::Spec(format!("serialising the {what}: {e}")))
}

/// The hash of one evaluation config (its canonical JSON): what a results row is tied to.
pub fn config_hash(cfg: &EvalConfig) -> Result<String, SweepError> {
    Ok(json_hash(&to_json("config", cfg)?))
}

/// One floor a sweep ran on.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FloorIdentity {
    /// The floor's label.
    pub label: String,
    /// Its number of walks.
    pub walks: usize,
    /// The hash of its parsed content (see the module docs).
    pub hash: String,
}

/// The data a sweep ran on: its floors, in order.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DataIdentity {
    /// The hash of the floors' identities, in order.
    pub hash: String,
    /// The floors.
    pub floors: Vec<FloorIdentity>,
}

fn serialised_hash<T: Serialize + ?Sized>(v: &T) -> Result<u64, SweepError> {
    let mut h = StableHasher::default();
    serde_json::to_writer(&mut h, v)
        .map_err(|e| SweepError::Spec(format!("hashing the data: {e}")))?;
    Ok(h.0)
}

/// The identity of one floor: label, walk count and content hash (the folder path left out).
pub fn floor_identity(floor: &FloorInput) -> Result<FloorIdentity, SweepError> {
    let d = &floor.data;
    let walks: Vec<u64> = d
        .walks
        .par_iter()
        .map(serialised_hash)
        .collect::<Result<_, _>>()?;
    let mut h = StableHasher::default();
    h.update_str(&floor.label);
    let rest = (&d.name, &d.plan);
    h.update(&serialised_hash(&rest)?.to_le_bytes());
    h.update(&(walks.len() as u64).to_le_bytes());
    for w in walks {
        h.update(&w.to_le_bytes());
    }
    Ok(FloorIdentity {
        label: floor.label.clone(),
        walks: d.walks.len(),
        hash: h.hex(),
    })
}

/// The identity of a list of floors.
pub fn data_identity(floors: &[FloorInput]) -> Result<DataIdentity, SweepError> {
    let started = std::time::Instant::now();
    let floors: Vec<FloorIdentity> = floors
        .iter()
        .map(floor_identity)
        .collect::<Result<_, _>>()?;
    tracing::info!(
        floors = floors.len(),
        ms = u64::try_from(started.elapsed().as_millis()).unwrap_or(u64::MAX),
        "data identity hashed"
    );
    let mut h = StableHasher::default();
    for f in &floors {
        h.update_str(&f.label);
        h.update_str(&f.hash);
    }
    Ok(DataIdentity {
        hash: h.hex(),
        floors,
    })
}

/// One shard of a sweep: the configs with `index % count == index`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardId {
    /// This shard (0-based).
    pub index: usize,
    /// The number of shards.
    pub count: usize,
}

impl std::str::FromStr for ShardId {
    type Err = SweepError;

    /// Parses `I/N` (`0 <= I < N`), the form of `--shard`.
    ///
    /// ```
    /// use wipdr_eval::sweep::ShardId;
    /// let s: ShardId = "1/4".parse().unwrap();
    /// assert_eq!((s.index, s.count), (1, 4));
    /// assert!("4/4".parse::<ShardId>().is_err());
    /// assert!("1".parse::<ShardId>().is_err());
    /// ```
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = |why: &str| SweepError::Spec(format!("shard {s:?}: {why}"));
        let (i, n) = s
            .split_once('/')
            .ok_or_else(|| bad("expected I/N, e.g. 0/4"))?;
        let whole = |v: &str| {
            v.trim()
                .parse::<usize>()
                .map_err(|_| bad("I and N must be whole numbers, e.g. 0/4"))
        };
        let (index, count) = (whole(i)?, whole(n)?);
        if count == 0 || index >= count {
            return Err(bad("need 0 <= I < N"));
        }
        Ok(Self { index, count })
    }
}

impl std::fmt::Display for ShardId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// What a results file was measured on; written beside it as `<results>.run.json`
/// ([`RunIdentity::sidecar_path`]) when a sweep starts, and checked by `resume` and `merge`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunIdentity {
    /// [`IDENTITY_FORMAT`].
    pub format: u32,
    /// Hash of the sweep spec's canonical JSON.
    pub spec_hash: String,
    /// Hash of the base config's canonical JSON.
    pub base_hash: String,
    /// The data.
    pub data: DataIdentity,
    /// The shard, `None` for the whole sweep (or a merge of shards).
    pub shard: Option<ShardId>,
    /// Configs in the whole sweep (all shards).
    pub configs: usize,
    /// The parameter columns of the results file.
    pub columns: Vec<String>,
    /// The sweep spec (so a mismatch can name the field that differs).
    pub spec: Value,
    /// The base config.
    pub base: Value,
}

/// At most this many differing fields are named per part of a mismatch message.
const MAX_NAMED: usize = 4;

impl RunIdentity {
    /// The identity of a sweep of `spec` over `base` on `floors`, shard `shard` (`(i, n)`; a
    /// shard `0/1` is the whole sweep), `configs` configs in all.
    pub fn new(
        spec: &SweepSpec,
        base: &EvalConfig,
        floors: &[FloorInput],
        shard: Option<(usize, usize)>,
        configs: usize,
    ) -> Result<Self, SweepError> {
        let spec_v = to_json("sweep spec", spec)?;
        let base_v = to_json("base config", base)?;
        Ok(Self {
            format: IDENTITY_FORMAT,
            spec_hash: json_hash(&spec_v),
            base_hash: json_hash(&base_v),
            data: data_identity(floors)?,
            shard: shard
                .filter(|&(_, n)| n > 1)
                .map(|(index, count)| ShardId { index, count }),
            configs,
            columns: spec.columns(),
            spec: spec_v,
            base: base_v,
        })
    }

    /// The sidecar of a results file: its path with `.run.json` appended.
    pub fn sidecar_path(results: &Path) -> PathBuf {
        let mut s = results.as_os_str().to_owned();
        s.push(".run.json");
        PathBuf::from(s)
    }

    /// Reads the sidecar of `results`.
    pub fn read(results: &Path) -> Result<Self, SweepError> {
        let path = Self::sidecar_path(results);
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(SweepError::MissingIdentity {
                    results: results.to_path_buf(),
                    sidecar: path,
                });
            }
            Err(source) => return Err(SweepError::Io { path, source }),
        };
        serde_json::from_str(&text).map_err(|e| SweepError::Results {
            path,
            line: e.line(),
            reason: format!("not a sweep run identity: {e}"),
        })
    }

    /// Writes the sidecar of `results` (atomically: a temporary file, then a rename).
    pub fn write(&self, results: &Path) -> Result<(), SweepError> {
        let path = Self::sidecar_path(results);
        let mut text = serde_json::to_string_pretty(self)
            .map_err(|e| SweepError::Spec(format!("serialising the run identity: {e}")))?;
        text.push('\n');
        let mut tmp = path.as_os_str().to_owned();
        tmp.push(".tmp");
        let tmp = PathBuf::from(tmp);
        std::fs::write(&tmp, text).map_err(|source| SweepError::Io {
            path: tmp.clone(),
            source,
        })?;
        std::fs::rename(&tmp, &path).map_err(|source| SweepError::Io { path, source })
    }

    /// How `other`'s sweep differs from this one's in spec, base config and data (the shard
    /// left out), one message per part, empty when they are the same sweep.
    pub fn sweep_differences(&self, other: &Self) -> Vec<String> {
        let mut out = Vec::new();
        if self.format != other.format {
            out.push(format!(
                "identity format differs: {} vs {}",
                self.format, other.format
            ));
        }
        out.extend(hashed_difference(
            "spec",
            (&self.spec_hash, &self.spec),
            (&other.spec_hash, &other.spec),
        ));
        out.extend(hashed_difference(
            "base config",
            (&self.base_hash, &self.base),
            (&other.base_hash, &other.base),
        ));
        out.extend(data_difference(&self.data, &other.data));
        if out.is_empty() && (self.configs != other.configs || self.columns != other.columns) {
            out.push(format!(
                "spec expands differently: {} configs {:?} vs {} configs {:?}",
                self.configs, self.columns, other.configs, other.columns
            ));
        }
        out
    }

    /// As [`Self::sweep_differences`], plus the shard.
    pub fn differences(&self, other: &Self) -> Vec<String> {
        let mut out = self.sweep_differences(other);
        if self.shard != other.shard {
            let show = |s: Option<ShardId>| {
                s.map_or("the whole sweep".to_string(), |s| format!("shard {s}"))
            };
            out.push(format!(
                "shard differs: {} vs {}",
                show(self.shard),
                show(other.shard)
            ));
        }
        out
    }
}

fn short(v: Option<&Value>) -> String {
    let s = v.map_or_else(|| "(absent)".to_string(), canonical_json);
    if s.chars().count() > 60 {
        let head: String = s.chars().take(57).collect();
        format!("{head}...")
    } else {
        s
    }
}

/// `"{what} differs (hash vs hash): the differing fields"` when two hashed values' hashes
/// differ (`(hash, value)` each).
pub(crate) fn hashed_difference(
    what: &str,
    (hash_a, a): (&str, &Value),
    (hash_b, b): (&str, &Value),
) -> Option<String> {
    (hash_a != hash_b).then(|| {
        format!(
            "{what} differs ({hash_a} vs {hash_b}): {}",
            named_differences(a, b)
        )
    })
}

/// `"data differs: ..."` naming the floors that differ, when the data differ.
pub(crate) fn data_difference(a: &DataIdentity, b: &DataIdentity) -> Option<String> {
    (a != b).then(|| format!("data differs: {}", data_differences(a, b)))
}

/// The dotted paths where two JSON values differ, with both values, at most [`MAX_NAMED`].
fn named_differences(a: &Value, b: &Value) -> String {
    let mut found = Vec::new();
    let mut total = 0;
    diff_paths(a, b, "", &mut found, &mut total);
    let mut s = found.join(", ");
    if total > found.len() {
        let _ = write!(s, " and {} more", total - found.len());
    }
    if s.is_empty() {
        s = "(same values, other form)".into();
    }
    s
}

fn diff_paths(a: &Value, b: &Value, path: &str, found: &mut Vec<String>, total: &mut usize) {
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
            keys.sort();
            keys.dedup();
            for k in keys {
                let sub = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                match (x.get(k), y.get(k)) {
                    (Some(u), Some(v)) => diff_paths(u, v, &sub, found, total),
                    (u, v) => note(&sub, u, v, found, total),
                }
            }
        }
        _ if a != b => note(path, Some(a), Some(b), found, total),
        _ => {}
    }
}

fn note(
    path: &str,
    a: Option<&Value>,
    b: Option<&Value>,
    found: &mut Vec<String>,
    total: &mut usize,
) {
    *total += 1;
    if found.len() < MAX_NAMED {
        let path = if path.is_empty() { "(root)" } else { path };
        found.push(format!("{path}: {} vs {}", short(a), short(b)));
    }
}

fn data_differences(a: &DataIdentity, b: &DataIdentity) -> String {
    let labels = |d: &DataIdentity| d.floors.iter().map(|f| f.label.clone()).collect::<Vec<_>>();
    if a.floors.len() != b.floors.len() || labels(a) != labels(b) {
        return format!("floors {:?} vs {:?}", labels(a), labels(b));
    }
    let parts: Vec<String> = a
        .floors
        .iter()
        .zip(&b.floors)
        .filter(|(x, y)| x != y)
        .map(|(x, y)| {
            format!(
                "floor {:?}: {} walks, content {} vs {} walks, content {}",
                x.label, x.walks, x.hash, y.walks, y.hash
            )
        })
        .collect();
    parts.join("; ")
}
