//! Config files that cannot silently lie: a partial section merges onto the effective
//! defaults of its context (not onto its type's own defaults), and every unknown field is an
//! error naming its dotted path.
//!
//! Why: `#[serde(default)]` fills a missing field from the *type's* `Default`, so a
//! `[matcher]` section setting only `k` would reset the metric to the type's default even
//! where the surrounding config's default differs. Here the config text is merged, field by
//! field, onto the serialised defaults of the whole config, then deserialised strictly.
//!
//! Tagged sections (`kind = ...`, `scheme = ...`) whose tag differs from the default's are
//! not merged field by field (the fields of another kind would not fit): they start from the
//! defaults of their own tag where the context has some ([`TagDefaults`]), else from their
//! type's serde defaults.
//!
//! ```
//! use wipdr_positioning::PositionerConfig;
//! use wipdr_fingerprint::{MatcherConfig, Metric};
//! let cfg = PositionerConfig::from_toml("[matcher]\nk = 7").unwrap();
//! // k set; the kind (the AP index), its top 4 and the shared-AP metric stay the context's.
//! match cfg.matcher {
//!     MatcherConfig::Apindex(c) => {
//!         assert!(c.k == 7 && c.top_offline == 4 && matches!(c.metric, Metric::SharedAp(_)))
//!     }
//!     _ => unreachable!(),
//! }
//! let err = PositionerConfig::from_toml("[scheme]\nscheme = \"ekf\"\nr_wifii = 3.0").unwrap_err();
//! assert!(err.to_string().contains("scheme"), "{err}");
//! ```

use crate::PositioningError;
use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::Value;

/// Tags whose sections are merged onto per-tag defaults: `(dotted path of the section,
/// tag key)`. A path segment `*` matches any key (`schemes.*`).
pub type TagDefaults = fn(path: &str, tag: &str) -> Option<Value>;

/// The tag defaults of wipdr's configs: a `[matcher]` of another kind starts from
/// [`wipdr_fingerprint::MatcherConfig::defaults_for`] that kind; a scheme section from
/// [`wipdr_fusion::SchemeConfig::default_for`] its scheme.
pub fn wipdr_tag_defaults(path: &str, tag: &str) -> Option<Value> {
    let last = path.rsplit('.').next().unwrap_or(path);
    if last == "matcher" {
        return wipdr_fingerprint::MatcherConfig::defaults_for(tag)
            .ok()
            .and_then(|c| serde_json::to_value(c).ok());
    }
    if last == "scheme" || path.starts_with("schemes.") {
        return wipdr_fusion::SchemeConfig::default_for(tag)
            .ok()
            .and_then(|c| serde_json::to_value(c).ok());
    }
    None
}

const TAG_KEYS: [&str; 2] = ["kind", "scheme"];

/// Merges `user` onto `base` (both JSON values of one config) at `path`.
pub fn merge_values(base: Value, user: Value, path: &str, tags: TagDefaults) -> Value {
    match (base, user) {
        (Value::Object(mut base), Value::Object(user)) => {
            for key in TAG_KEYS {
                if let Some(Value::String(tag)) = user.get(key) {
                    let same = base.get(key).and_then(Value::as_str) == Some(tag.as_str());
                    if !same {
                        // Another kind: its own defaults (which carry its tag), or none (the
                        // type's serde defaults apply).
                        return match tags(path, tag) {
                            Some(fresh)
                                if fresh.get(key).and_then(Value::as_str) == Some(tag.as_str()) =>
                            {
                                merge_values(fresh, Value::Object(user), path, tags)
                            }
                            _ => Value::Object(user),
                        };
                    }
                }
            }
            for (k, v) in user {
                let sub = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                let merged = match base.remove(&k) {
                    Some(b) => merge_values(b, v, &sub, tags),
                    None => v,
                };
                base.insert(k, merged);
            }
            Value::Object(base)
        }
        // A map-typed field with no default entry (e.g. `schemes.ekf`): per-tag defaults.
        (Value::Null, Value::Object(user)) => {
            let fresh = TAG_KEYS.iter().find_map(|k| {
                let tag = user.get(*k).and_then(Value::as_str)?;
                let fresh = tags(path, tag)?;
                (fresh.get(*k).and_then(Value::as_str) == Some(tag)).then_some(fresh)
            });
            match fresh {
                Some(fresh) => merge_values(fresh, Value::Object(user), path, tags),
                None => Value::Object(user),
            }
        }
        (_, user) => user,
    }
}

/// Deserialises `value` strictly into `T`, naming the failing field's dotted path.
pub fn from_value_with_path<T: DeserializeOwned>(value: Value) -> Result<T, PositioningError> {
    serde_path_to_error::deserialize(value).map_err(|e| {
        let path = e.path().to_string();
        PositioningError::Parse(format!("{path}: {}", e.into_inner()))
    })
}

/// Reads TOML `text` as a `T`, merged onto `defaults` (see the module docs). A non-finite
/// number (`nan`, `inf`) anywhere is an error naming its dotted path ([`toml_to_json`]).
pub fn from_toml_onto<T: Serialize + DeserializeOwned>(
    text: &str,
    defaults: &T,
) -> Result<T, PositioningError> {
    let user: Value = toml_to_json(text).map_err(PositioningError::Parse)?;
    from_value_onto(user, defaults)
}

/// TOML text as the JSON value the configs merge, refusing non-finite numbers: TOML's `nan`
/// and `inf` have no JSON form (serde_json writes them as `null`, which an optional field
/// would read as "not set", turning a threshold silently off), so any of them is an error
/// naming its dotted path.
///
/// ```
/// let v = wipdr_positioning::merge::toml_to_json("[query]\nmin_rssi_dbm = -80.0").unwrap();
/// assert_eq!(v["query"]["min_rssi_dbm"], -80.0);
/// let e = wipdr_positioning::merge::toml_to_json("[query]\nmin_rssi_dbm = nan").unwrap_err();
/// assert!(e.starts_with("query.min_rssi_dbm: NaN is not a finite number"), "{e}");
/// ```
pub fn toml_to_json(text: &str) -> Result<Value, String> {
    let table: toml::Table = toml::from_str(text).map_err(|e| e.to_string())?;
    for (key, value) in &table {
        non_finite(value, key)?;
    }
    serde_json::to_value(&table).map_err(|e| e.to_string())
}

/// The first non-finite float in `value` (at dotted `path`), as an error.
fn non_finite(value: &toml::Value, path: &str) -> Result<(), String> {
    match value {
        toml::Value::Float(f) if !f.is_finite() => Err(format!(
            "{path}: {f} is not a finite number (write a finite value, or \"off\" where the \
             field can be turned off)"
        )),
        toml::Value::Array(items) => items
            .iter()
            .enumerate()
            .try_for_each(|(i, v)| non_finite(v, &format!("{path}[{i}]"))),
        toml::Value::Table(t) => t
            .iter()
            .try_for_each(|(k, v)| non_finite(v, &format!("{path}.{k}"))),
        _ => Ok(()),
    }
}

/// [`from_toml_onto`] for a value already parsed (JSON, or a sweep's patched TOML).
pub fn from_value_onto<T: Serialize + DeserializeOwned>(
    user: Value,
    defaults: &T,
) -> Result<T, PositioningError> {
    let base = serde_json::to_value(defaults)
        .map_err(|e| PositioningError::Parse(format!("defaults do not serialise: {e}")))?;
    from_value_with_path(merge_values(base, user, "", wipdr_tag_defaults))
}

/// Refuses a field of a scheme table (the keys of `table`, a `[scheme]` or `[schemes.NAME]`
/// section configuring scheme `kind`) that the scheme does not read
/// ([`wipdr_fusion::SchemeConfig::unread_fields`]) and that is set to a value other than the
/// scheme's shipped default and its paper preset: a written-out config lists every field, so
/// a default value there says nothing, while any other value would be silently ignored.
/// The error's path is the field (the caller prefixes the table's path,
/// [`wipdr_core::ConfigError::under`]).
///
/// ```
/// use serde_json::json;
/// use wipdr_positioning::merge::check_scheme_table;
/// let t = json!({"scheme": "ekf", "robust": {"alpha": 0.05}});
/// assert_eq!(check_scheme_table("ekf", t.as_object().unwrap()).unwrap_err().path, "robust");
/// assert!(check_scheme_table("rkf", t.as_object().unwrap()).is_ok());
/// ```
pub fn check_scheme_table(
    kind: &str,
    table: &serde_json::Map<String, Value>,
) -> Result<(), wipdr_core::ConfigError> {
    let unread = wipdr_fusion::SchemeConfig::unread_fields(kind);
    if unread.is_empty() {
        return Ok(());
    }
    let presets: Vec<Value> = [
        wipdr_fusion::SchemeConfig::default_for(kind),
        wipdr_fusion::SchemeConfig::paper_for(kind),
    ]
    .into_iter()
    .filter_map(|c| serde_json::to_value(c.ok()?).ok())
    .collect();
    let set: Vec<&str> = table
        .iter()
        .filter(|(key, value)| {
            unread.contains(&key.as_str())
                && !presets.iter().any(|p| p.get(key.as_str()) == Some(*value))
        })
        .map(|(key, _)| key.as_str())
        .collect();
    wipdr_fusion::SchemeConfig::check_unread(kind, set)
}

#[cfg(test)]
mod tests {
    use crate::PositionerConfig;

    #[test]
    fn partial_sections_keep_context_defaults() {
        let cfg = PositionerConfig::from_toml("[query]\nmin_rssi_dbm = -90.0").unwrap();
        assert_eq!(cfg.query.min_rssi_dbm, Some(-90.0));
        assert_eq!(
            cfg.query.max_age_ms,
            Some(crate::config::DEFAULT_MAX_ENTRY_AGE_MS)
        );
    }

    #[test]
    fn another_kind_starts_from_its_own_defaults() {
        // The default kind is the AP index: a WKNN section starts from the WKNN defaults.
        let cfg = PositionerConfig::from_toml("[matcher]\nkind = \"wknn\"\nk = 4").unwrap();
        let want = match wipdr_fingerprint::MatcherConfig::defaults_for("wknn").unwrap() {
            wipdr_fingerprint::MatcherConfig::Wknn(mut a) => {
                a.k = 4;
                a
            }
            _ => unreachable!(),
        };
        assert_eq!(cfg.matcher, wipdr_fingerprint::MatcherConfig::Wknn(want));
    }

    #[test]
    fn unknown_fields_name_their_path() {
        for (text, path) in [
            ("[matcher]\nkk = 3", "matcher"),
            ("[pdr]\nstep_lenght = 3", "pdr"),
            ("[scheme]\nscheme = \"pmf\"\ncell = 2.0", "scheme"),
            ("mapmatching = true", "mapmatching"),
        ] {
            let e = PositionerConfig::from_toml(text).unwrap_err().to_string();
            assert!(e.contains(path), "{text}: {e}");
        }
    }
}
