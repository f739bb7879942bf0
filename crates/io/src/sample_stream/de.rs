//! [`PlainSample`]'s JSON reading, written out: serde's derive for an internally tagged enum
//! buffers every object into a generic tree before it knows the variant (an allocation per
//! key and value): with the allocator, about a tenth of `wipdr serve`'s time under load
//! (perf, `docs/results/serve.md`). This reads each key once into its slot and builds the
//! variant at the end, with the derive's checks and messages: the tag `sensor` is required and must
//! name a sensor, each sensor's fields are required (`meta`'s are optional) and no other
//! field is allowed, a field may not repeat. The derived reading is kept in the tests, and a
//! property test checks that both accept the same objects with the same values. A 1 s batch
//! of 200 accelerometer samples and a scan: `cargo bench -p wipdr-benches --bench
//! plain_json` (43 µs on the quiet 2-core machine; the derive took about 60 µs, a one-off
//! comparison in `docs/experiments.md`).

use super::{PlainAp, PlainSample};
use serde::de::{self, Deserializer, IgnoredAny, MapAccess, Visitor};
use std::fmt;
use wipdr_core::TimestampMs;

/// Each sensor's fields besides `sensor`, as the derive names them in its messages.
const META_FIELDS: &[&str] = &["phone_model", "start_unix_ms"];
const VEC3_FIELDS: &[&str] = &["t_ms", "x", "y", "z"];
const PRESSURE_FIELDS: &[&str] = &["t_ms", "hpa"];
const WIFI_FIELDS: &[&str] = &["t_ms", "aps"];

/// The tag's values (serde's derive: an unknown one is ``unknown variant `x`, expected one
/// of `meta`, ...``, as the enum's derive said).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
enum Sensor {
    Meta,
    Accelerometer,
    Gyroscope,
    Magnetometer,
    RotationVector,
    Pressure,
    Wifi,
}

impl Sensor {
    fn fields(self) -> &'static [&'static str] {
        match self {
            Self::Meta => META_FIELDS,
            Self::Pressure => PRESSURE_FIELDS,
            Self::Wifi => WIFI_FIELDS,
            Self::Accelerometer | Self::Gyroscope | Self::Magnetometer | Self::RotationVector => {
                VEC3_FIELDS
            }
        }
    }
}

/// An object key: a known field, or another name (kept for the message).
enum Key {
    Sensor,
    TMs,
    X,
    Y,
    Z,
    Hpa,
    Aps,
    PhoneModel,
    StartUnixMs,
    Other(String),
}

impl Key {
    fn name(&self) -> &str {
        match self {
            Self::Sensor => "sensor",
            Self::TMs => "t_ms",
            Self::X => "x",
            Self::Y => "y",
            Self::Z => "z",
            Self::Hpa => "hpa",
            Self::Aps => "aps",
            Self::PhoneModel => "phone_model",
            Self::StartUnixMs => "start_unix_ms",
            Self::Other(name) => name,
        }
    }
}

impl<'de> de::Deserialize<'de> for Key {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = Key;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a field name")
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<Key, E> {
                Ok(match v {
                    "sensor" => Key::Sensor,
                    "t_ms" => Key::TMs,
                    "x" => Key::X,
                    "y" => Key::Y,
                    "z" => Key::Z,
                    "hpa" => Key::Hpa,
                    "aps" => Key::Aps,
                    "phone_model" => Key::PhoneModel,
                    "start_unix_ms" => Key::StartUnixMs,
                    other => Key::Other(other.to_owned()),
                })
            }
        }
        d.deserialize_identifier(V)
    }
}

/// Stores `value` in `slot`, refusing a second value for the same field.
fn set<T, E: de::Error>(slot: &mut Option<T>, value: T, field: &'static str) -> Result<(), E> {
    if slot.is_some() {
        return Err(E::duplicate_field(field));
    }
    *slot = Some(value);
    Ok(())
}

/// The fields read so far.
#[derive(Default)]
struct Slots {
    sensor: Option<Sensor>,
    t_ms: Option<TimestampMs>,
    x: Option<f64>,
    y: Option<f64>,
    z: Option<f64>,
    hpa: Option<f64>,
    aps: Option<Vec<PlainAp>>,
    phone_model: Option<Option<String>>,
    start_unix_ms: Option<Option<TimestampMs>>,
}

struct SampleVisitor;

impl<'de> Visitor<'de> for SampleVisitor {
    type Value = PlainSample;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a sample object tagged by `sensor`")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<PlainSample, A::Error> {
        let mut s = Slots::default();
        // Keys in the order met; the first one the sensor does not have is the error.
        let mut met: Vec<Key> = Vec::with_capacity(5);
        while let Some(key) = map.next_key::<Key>()? {
            match &key {
                Key::Sensor => set(&mut s.sensor, map.next_value()?, "sensor")?,
                Key::TMs => set(&mut s.t_ms, map.next_value()?, "t_ms")?,
                Key::X => set(&mut s.x, map.next_value()?, "x")?,
                Key::Y => set(&mut s.y, map.next_value()?, "y")?,
                Key::Z => set(&mut s.z, map.next_value()?, "z")?,
                Key::Hpa => set(&mut s.hpa, map.next_value()?, "hpa")?,
                Key::Aps => set(&mut s.aps, map.next_value()?, "aps")?,
                Key::PhoneModel => set(&mut s.phone_model, map.next_value()?, "phone_model")?,
                Key::StartUnixMs => set(&mut s.start_unix_ms, map.next_value()?, "start_unix_ms")?,
                Key::Other(_) => {
                    map.next_value::<IgnoredAny>()?;
                }
            }
            if !matches!(key, Key::Sensor) {
                met.push(key);
            }
        }
        let Some(sensor) = s.sensor else {
            return Err(de::Error::missing_field("sensor"));
        };
        let fields = sensor.fields();
        if let Some(k) = met.iter().find(|k| !fields.contains(&k.name())) {
            return Err(de::Error::unknown_field(k.name(), fields));
        }
        let need =
            |v: Option<f64>, field: &'static str| v.ok_or_else(|| de::Error::missing_field(field));
        let t = || s.t_ms.ok_or_else(|| de::Error::missing_field("t_ms"));
        Ok(match sensor {
            Sensor::Meta => PlainSample::Meta {
                phone_model: s.phone_model.flatten(),
                start_unix_ms: s.start_unix_ms.flatten(),
            },
            Sensor::Pressure => PlainSample::Pressure {
                t_ms: t()?,
                hpa: need(s.hpa, "hpa")?,
            },
            Sensor::Wifi => PlainSample::Wifi {
                t_ms: t()?,
                aps: s.aps.ok_or_else(|| de::Error::missing_field("aps"))?,
            },
            vec3 => {
                let (t_ms, x, y, z) = (t()?, need(s.x, "x")?, need(s.y, "y")?, need(s.z, "z")?);
                match vec3 {
                    Sensor::Accelerometer => PlainSample::Accelerometer { t_ms, x, y, z },
                    Sensor::Gyroscope => PlainSample::Gyroscope { t_ms, x, y, z },
                    Sensor::Magnetometer => PlainSample::Magnetometer { t_ms, x, y, z },
                    _ => PlainSample::RotationVector { t_ms, x, y, z },
                }
            }
        })
    }
}

impl<'de> de::Deserialize<'de> for PlainSample {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_map(SampleVisitor)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use serde::Deserialize;

    /// The `sensor` values, in the enum's order.
    const SENSORS: &[&str] = &[
        "meta",
        "accelerometer",
        "gyroscope",
        "magnetometer",
        "rotation_vector",
        "pressure",
        "wifi",
    ];

    /// The derived reading this module replaces, kept to compare with.
    #[derive(Debug, Deserialize)]
    #[serde(tag = "sensor", rename_all = "snake_case", deny_unknown_fields)]
    enum Derived {
        Meta {
            #[serde(default)]
            phone_model: Option<String>,
            #[serde(default)]
            start_unix_ms: Option<TimestampMs>,
        },
        Accelerometer {
            t_ms: TimestampMs,
            x: f64,
            y: f64,
            z: f64,
        },
        Gyroscope {
            t_ms: TimestampMs,
            x: f64,
            y: f64,
            z: f64,
        },
        Magnetometer {
            t_ms: TimestampMs,
            x: f64,
            y: f64,
            z: f64,
        },
        RotationVector {
            t_ms: TimestampMs,
            x: f64,
            y: f64,
            z: f64,
        },
        Pressure {
            t_ms: TimestampMs,
            hpa: f64,
        },
        Wifi {
            t_ms: TimestampMs,
            aps: Vec<PlainAp>,
        },
    }

    impl From<Derived> for PlainSample {
        fn from(d: Derived) -> Self {
            match d {
                Derived::Meta {
                    phone_model,
                    start_unix_ms,
                } => Self::Meta {
                    phone_model,
                    start_unix_ms,
                },
                Derived::Accelerometer { t_ms, x, y, z } => Self::Accelerometer { t_ms, x, y, z },
                Derived::Gyroscope { t_ms, x, y, z } => Self::Gyroscope { t_ms, x, y, z },
                Derived::Magnetometer { t_ms, x, y, z } => Self::Magnetometer { t_ms, x, y, z },
                Derived::RotationVector { t_ms, x, y, z } => Self::RotationVector { t_ms, x, y, z },
                Derived::Pressure { t_ms, hpa } => Self::Pressure { t_ms, hpa },
                Derived::Wifi { t_ms, aps } => Self::Wifi { t_ms, aps },
            }
        }
    }

    fn read(text: &str) -> Result<PlainSample, String> {
        serde_json::from_str::<PlainSample>(text).map_err(|e| e.to_string())
    }

    #[test]
    fn every_sensor_reads_back_what_was_written() {
        let samples = [
            PlainSample::Meta {
                phone_model: Some("Pixel 7".into()),
                start_unix_ms: Some(1_700_000_000_000),
            },
            PlainSample::Meta {
                phone_model: None,
                start_unix_ms: None,
            },
            PlainSample::Accelerometer {
                t_ms: 0,
                x: 0.12,
                y: 0.3,
                z: 9.79,
            },
            PlainSample::Gyroscope {
                t_ms: -5,
                x: 1e-3,
                y: -2e-3,
                z: 0.01,
            },
            PlainSample::Magnetometer {
                t_ms: 7,
                x: 20.0,
                y: -3.5,
                z: 40.0,
            },
            PlainSample::RotationVector {
                t_ms: 9,
                x: 0.01,
                y: 0.02,
                z: 0.7,
            },
            PlainSample::Pressure {
                t_ms: 1000,
                hpa: 1009.42,
            },
            PlainSample::Wifi {
                t_ms: 500,
                aps: vec![PlainAp {
                    bssid: "aa:bb:cc:dd:ee:01".into(),
                    rssi_dbm: -61.0,
                    last_seen_ms: Some(480),
                }],
            },
        ];
        for s in samples {
            let text = serde_json::to_string(&s).unwrap();
            assert_eq!(read(&text).unwrap(), s, "{text}");
        }
    }

    #[test]
    fn bad_objects_get_the_derives_messages() {
        let cases = [
            (r#"{"t_ms":0,"x":1,"y":2,"z":3}"#, "missing field `sensor`"),
            (
                r#"{"sensor":"lidar","t_ms":0}"#,
                "unknown variant `lidar`, expected one of",
            ),
            (
                r#"{"sensor":"accelerometer","t_ms":0,"x":1,"y":2}"#,
                "missing field `z`",
            ),
            (
                r#"{"sensor":"pressure","t_ms":0,"hpa":1000,"x":1}"#,
                "unknown field `x`, expected `t_ms` or `hpa`",
            ),
            (
                r#"{"sensor":"gyroscope","t_ms":0,"x":1,"y":2,"z":3,"w":4}"#,
                "unknown field `w`, expected one of `t_ms`, `x`, `y`, `z`",
            ),
            (
                r#"{"sensor":"gyroscope","t_ms":0,"x":1,"x":1,"y":2,"z":3}"#,
                "duplicate field `x`",
            ),
            (
                r#"{"sensor":"wifi","sensor":"wifi","t_ms":0,"aps":[]}"#,
                "duplicate field `sensor`",
            ),
            (
                r#"{"sensor":"pressure","t_ms":"0","hpa":1000}"#,
                "invalid type: string \"0\"",
            ),
            (r#"["accelerometer",0,1,2,3]"#, "invalid type: sequence"),
        ];
        for (text, want) in cases {
            let got = read(text).unwrap_err();
            assert!(got.contains(want), "{text}: {got}");
        }
    }

    /// A JSON object from some of the fields (in any order, maybe twice), with values of
    /// the right or the wrong type, and maybe a sensor name that is not one.
    fn object() -> impl Strategy<Value = String> {
        let key = prop::sample::select(vec![
            "sensor",
            "sensor",
            "t_ms",
            "x",
            "y",
            "z",
            "hpa",
            "aps",
            "phone_model",
            "start_unix_ms",
            "extra",
        ]);
        let value = prop_oneof![
            prop::sample::select(SENSORS.to_vec()).prop_map(|s| format!("\"{s}\"")),
            Just("\"lidar\"".to_string()),
            (-2_000_000i64..2_000_000).prop_map(|v| v.to_string()),
            (-1e3f64..1e3).prop_map(|v| format!("{v:?}")),
            Just("null".to_string()),
            Just("true".to_string()),
            Just(r#"[{"bssid":"aa:bb:cc:dd:ee:01","rssi_dbm":-61}]"#.to_string()),
            Just(r#"[{"bssid":"aa:bb:cc:dd:ee:01"}]"#.to_string()),
            Just("\"Pixel 7\"".to_string()),
        ];
        prop::collection::vec((key, value), 0..8).prop_map(|kv| {
            let body: Vec<String> = kv.iter().map(|(k, v)| format!("\"{k}\":{v}")).collect();
            format!("{{{}}}", body.join(","))
        })
    }

    /// Objects that name every field of a sensor with values of the right type, so that
    /// most of them are accepted (the mixed strategy above mostly makes errors).
    fn valid_ish() -> impl Strategy<Value = String> {
        (
            prop::sample::select(SENSORS.to_vec()),
            -1_000_000i64..1_000_000,
            prop::array::uniform3(-1e3f64..1e3),
            any::<bool>(),
        )
            .prop_map(|(sensor, t, v, extra)| {
                let fields = match sensor {
                    "meta" => r#""phone_model":"Pixel 7""#.to_string(),
                    "pressure" => format!(r#""t_ms":{t},"hpa":{:?}"#, v[0]),
                    "wifi" => format!(
                        r#""aps":[{{"bssid":"x","rssi_dbm":{:?}}}],"t_ms":{t}"#,
                        v[1]
                    ),
                    _ => format!(r#""z":{:?},"t_ms":{t},"x":{:?},"y":{:?}"#, v[2], v[0], v[1]),
                };
                let extra = if extra { r#","hpa":1"# } else { "" };
                format!(r#"{{{fields},"sensor":"{sensor}"{extra}}}"#)
            })
    }

    proptest! {
        /// The hand-written reading accepts exactly the objects the derive accepts, with
        /// the same values.
        #[test]
        fn reads_as_the_derive_does(text in prop_oneof![object(), valid_ish()]) {
            let ours = serde_json::from_str::<PlainSample>(&text);
            let derived = serde_json::from_str::<Derived>(&text).map(PlainSample::from);
            match (ours, derived) {
                (Ok(a), Ok(b)) => prop_assert_eq!(a, b),
                (Err(_), Err(_)) => {}
                (a, b) => prop_assert!(false, "{}: ours {:?}, derived {:?}", text, a, b),
            }
        }
    }
}
