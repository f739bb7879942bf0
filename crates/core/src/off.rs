//! Config fields of type `Option<T>` whose default is `Some`: TOML has no null, so such a
//! field is turned off by the string `"off"`, and a `None` is written as `"off"` too. Without
//! this a config written to TOML (a sweep's best config, a preset saved for reuse) would drop
//! its `None` fields and read back with the defaults' `Some` values: a config that lies.
//!
//! Use it with `#[serde(with = "wipdr_core::off")]` on the field. Any other value is read as
//! `T` itself, with `T`'s own error messages (a misspelt key inside a table still names its
//! path).
//!
//! ```
//! use serde::{Deserialize, Serialize};
//!
//! #[derive(Debug, PartialEq, Serialize, Deserialize)]
//! struct Gate {
//!     #[serde(with = "wipdr_core::off")]
//!     max_rate: Option<f64>,
//! }
//!
//! let off: Gate = toml::from_str("max_rate = \"off\"").unwrap();
//! assert_eq!(off.max_rate, None);
//! assert_eq!(toml::to_string(&off).unwrap().trim(), "max_rate = \"off\"");
//! let on: Gate = toml::from_str("max_rate = 1.5").unwrap();
//! assert_eq!(on.max_rate, Some(1.5));
//! assert!(toml::from_str::<Gate>("max_rate = \"of\"").is_err());
//! ```

use serde::de::value::{MapAccessDeserializer, SeqAccessDeserializer};
use serde::de::{self, IntoDeserializer, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;
use std::marker::PhantomData;

/// The word that turns a field off.
pub const OFF: &str = "off";

/// Writes `Some(v)` as `v`, `None` as `"off"`.
pub fn serialize<T: Serialize, S: Serializer>(value: &Option<T>, s: S) -> Result<S::Ok, S::Error> {
    match value {
        Some(v) => v.serialize(s),
        None => s.serialize_str(OFF),
    }
}

/// Reads `"off"` as `None`, anything else as `Some(T)`.
pub fn deserialize<'de, T: Deserialize<'de>, D: Deserializer<'de>>(
    d: D,
) -> Result<Option<T>, D::Error> {
    d.deserialize_any(OffOr(PhantomData))
}

struct OffOr<T>(PhantomData<T>);

impl<'de, T: Deserialize<'de>> Visitor<'de> for OffOr<T> {
    type Value = Option<T>;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "a value or \"{OFF}\"")
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<Self::Value, E> {
        if v == OFF {
            return Ok(None);
        }
        T::deserialize(v.into_deserializer())
            .map(Some)
            .map_err(|e: E| E::custom(format!("{e} (or \"{OFF}\")")))
    }

    fn visit_bool<E: de::Error>(self, v: bool) -> Result<Self::Value, E> {
        T::deserialize(v.into_deserializer()).map(Some)
    }

    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Self::Value, E> {
        T::deserialize(v.into_deserializer()).map(Some)
    }

    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Self::Value, E> {
        T::deserialize(v.into_deserializer()).map(Some)
    }

    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Self::Value, E> {
        T::deserialize(v.into_deserializer()).map(Some)
    }

    /// JSON's null (a config echoed by an older build) reads as off too.
    fn visit_unit<E: de::Error>(self) -> Result<Self::Value, E> {
        Ok(None)
    }

    fn visit_none<E: de::Error>(self) -> Result<Self::Value, E> {
        Ok(None)
    }

    fn visit_some<D: Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        deserialize(d)
    }

    fn visit_seq<A: de::SeqAccess<'de>>(self, seq: A) -> Result<Self::Value, A::Error> {
        T::deserialize(SeqAccessDeserializer::new(seq)).map(Some)
    }

    fn visit_map<A: de::MapAccess<'de>>(self, map: A) -> Result<Self::Value, A::Error> {
        T::deserialize(MapAccessDeserializer::new(map)).map(Some)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, PartialEq, Serialize, Deserialize, Default)]
    #[serde(deny_unknown_fields)]
    struct Inner {
        a: i64,
    }

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    #[serde(default, deny_unknown_fields)]
    struct Outer {
        #[serde(with = "crate::off")]
        rate: Option<f64>,
        #[serde(with = "crate::off")]
        inner: Option<Inner>,
        #[serde(with = "crate::off")]
        age_ms: Option<i64>,
    }

    impl Default for Outer {
        fn default() -> Self {
            Self {
                rate: Some(3.0),
                inner: Some(Inner { a: 1 }),
                age_ms: Some(5),
            }
        }
    }

    #[test]
    fn none_survives_toml_and_json() {
        let off = Outer {
            rate: None,
            inner: None,
            age_ms: None,
        };
        let text = toml::to_string(&off).unwrap();
        assert_eq!(toml::from_str::<Outer>(&text).unwrap(), off, "{text}");
        let json = serde_json::to_string(&off).unwrap();
        assert_eq!(serde_json::from_str::<Outer>(&json).unwrap(), off);
        let null = r#"{"rate": null, "inner": null, "age_ms": null}"#;
        assert_eq!(serde_json::from_str::<Outer>(null).unwrap(), off);
        let on = Outer::default();
        assert_eq!(
            toml::from_str::<Outer>(&toml::to_string(&on).unwrap()).unwrap(),
            on
        );
    }

    #[test]
    fn values_and_errors_are_the_inner_types() {
        let o: Outer = toml::from_str("rate = 2\n[inner]\na = 4\n").unwrap();
        assert_eq!(o.rate, Some(2.0));
        assert_eq!(o.inner, Some(Inner { a: 4 }));
        let e = toml::from_str::<Outer>("[inner]\nb = 4\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("unknown field `b`"), "{e}");
        let e = toml::from_str::<Outer>("rate = \"fast\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("off"), "{e}");
    }
}
