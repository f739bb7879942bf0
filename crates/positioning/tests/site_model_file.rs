//! Hostile site model files: every damaged, truncated, foreign or crafted file is a typed
//! error naming the file, never a panic, an abort or an allocation the file did not pay for.

use proptest::prelude::*;
use std::path::Path;
use std::sync::OnceLock;
use wipdr_core::{Bssid, Point2, Walk, Waypoint, WifiEntry, WifiScan};
use wipdr_positioning::site_model::{
    FORMAT_VERSION, HEADER_BYTES, MAGIC, SiteConfig, SiteModel, SiteModelFileError, TrainingData,
};

/// A small model: one training walk along a corridor, two APs.
fn model() -> &'static SiteModel {
    static MODEL: OnceLock<SiteModel> = OnceLock::new();
    MODEL.get_or_init(|| {
        let mut walk = Walk::default();
        walk.meta.id = "corridor".into();
        for i in 0..30 {
            let (t, x) = (1000 * i64::from(i), f64::from(i));
            walk.waypoints
                .push(Waypoint::new(t, Point2::new(x, 0.5 * x)));
            walk.wifi.push(WifiScan {
                t,
                entries: vec![
                    WifiEntry::new(Bssid(1), -40.0 - 1.5 * x).seen_at(t),
                    WifiEntry::new(Bssid(2), -85.0 + 1.5 * x).seen_at(t),
                ],
            });
        }
        let data = TrainingData {
            name: "corridor",
            walks: &[&walk],
            ..Default::default()
        };
        SiteModel::fit(&data, &SiteConfig::default()).expect("fits")
    })
}

fn bytes() -> &'static [u8] {
    static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
    BYTES.get_or_init(|| model().to_bytes().expect("encodes"))
}

fn crc(b: &[u8]) -> u32 {
    crc32fast::hash(b)
}

/// A file with `payload` behind a header that checks (right CRCs, version and length).
fn with_valid_header(payload: &[u8], announced: u64) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&announced.to_le_bytes());
    out.extend_from_slice(&crc(payload).to_le_bytes());
    let h = crc(&out);
    out.extend_from_slice(&h.to_le_bytes());
    out.extend_from_slice(payload);
    out
}

fn load_bytes(b: &[u8]) -> Result<SiteModel, SiteModelFileError> {
    SiteModel::from_bytes(b, Path::new("hostile.wipdr"))
}

fn names_the_file(e: &SiteModelFileError) {
    assert!(e.to_string().starts_with("hostile.wipdr: "), "{e}");
}

#[test]
fn a_saved_model_loads_as_itself() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("corridor.wipdr");
    model().save(&path).unwrap();
    let loaded = SiteModel::load(&path).unwrap();
    assert_eq!(loaded.data(), model().data());
    assert_eq!(std::fs::read(&path).unwrap(), bytes());
}

#[test]
fn truncation_at_every_length_is_a_typed_error() {
    let b = bytes();
    for len in (0..b.len()).step_by(7).chain([b.len() - 1]) {
        let e = load_bytes(&b[..len]).expect_err("a truncated file is refused");
        names_the_file(&e);
        assert!(
            matches!(
                e,
                SiteModelFileError::TruncatedHeader { .. }
                    | SiteModelFileError::Length { .. }
                    | SiteModelFileError::NotAModel { .. }
            ),
            "{len}: {e}"
        );
    }
}

#[test]
fn another_version_names_both_versions() {
    let mut b = bytes().to_vec();
    b[8..12].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
    let h = crc(&b[..HEADER_BYTES - 4]);
    b[HEADER_BYTES - 4..HEADER_BYTES].copy_from_slice(&h.to_le_bytes());
    match load_bytes(&b) {
        Err(
            e @ SiteModelFileError::Version {
                found, expected, ..
            },
        ) => {
            assert_eq!((found, expected), (FORMAT_VERSION + 1, FORMAT_VERSION));
            assert!(e.to_string().contains("fit the site again"), "{e}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn foreign_files_are_not_models() {
    let cache = b"WIPDRFC\0\x09\x00\x00\x00rest of a floor cache file".to_vec();
    let gzip = vec![
        0x1f, 0x8b, 0x08, 0x00, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12,
    ];
    let text = b"t_ms,sensor,a,b,c,d\n0,pressure,1000\n".to_vec();
    for (file, says) in [
        (cache, "floor cache"),
        (gzip, "gzip"),
        (text, "starts with bytes"),
        (Vec::new(), "empty"),
    ] {
        match load_bytes(&file) {
            Err(e @ SiteModelFileError::NotAModel { .. }) => {
                names_the_file(&e);
                assert!(e.to_string().contains(says), "{e}");
            }
            other => panic!("{says}: {other:?}"),
        }
    }
}

#[test]
fn a_header_announcing_a_terabyte_is_refused_before_reading_it() {
    let b = with_valid_header(&bytes()[HEADER_BYTES..], 1_000_000_000_000);
    match load_bytes(&b) {
        Err(SiteModelFileError::Length {
            announced, actual, ..
        }) => {
            assert_eq!(announced, 1_000_000_000_000);
            assert_eq!(actual, (bytes().len() - HEADER_BYTES) as u64);
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_payload_announcing_1e12_entries_fails_without_allocating_them() {
    // The payload's first field is a string: its bincode length prefix (varint: 0xFD then a
    // u64) announces 10^12 bytes; the CRCs are right, so only the decoder's limit stands.
    let mut payload = vec![0xFD];
    payload.extend_from_slice(&1_000_000_000_000u64.to_le_bytes());
    payload.extend_from_slice(&[b'x'; 64]);
    let b = with_valid_header(&payload, payload.len() as u64);
    match load_bytes(&b) {
        Err(e @ SiteModelFileError::Codec { .. }) => names_the_file(&e),
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_consistent_looking_payload_with_wrong_shapes_is_invalid() {
    // Re-encode the model's data with the radio map's arrays cut short: the CRCs are right,
    // bincode decodes it, the shape check refuses it.
    let mut data = model().data().clone();
    let mut map = serde_json::to_value(&*data.radio_map).unwrap();
    map["mean_dbm"].as_array_mut().unwrap().pop();
    data.radio_map = std::sync::Arc::new(serde_json::from_value(map).unwrap());
    match SiteModel::from_data(data, None) {
        Err(e) => assert!(e.to_string().contains("radio map"), "{e}"),
        Ok(_) => panic!("a radio map with a missing value was accepted"),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// Any flipped byte is caught (by a checksum, the magic, the version or the length).
    #[test]
    fn a_flipped_byte_is_a_typed_error(at in 0usize..100_000, bit in 0u8..8) {
        let mut b = bytes().to_vec();
        let at = at % b.len();
        b[at] ^= 1 << bit;
        let e = load_bytes(&b).expect_err("a damaged file is refused");
        names_the_file(&e);
    }

    /// Random bytes, with or without the magic in front, never panic.
    #[test]
    fn random_bytes_are_a_typed_error(mut junk in proptest::collection::vec(any::<u8>(), 0..512), magic in any::<bool>()) {
        if magic {
            let mut b = MAGIC.to_vec();
            b.append(&mut junk);
            junk = b;
        }
        let e = load_bytes(&junk).expect_err("junk is refused");
        names_the_file(&e);
    }

    /// A crafted payload behind a valid header (CRCs recomputed) decodes or fails typed.
    #[test]
    fn crafted_payloads_behind_a_valid_header_never_panic(
        cut in 0usize..100_000,
        at in 0usize..100_000,
        value in any::<u8>(),
    ) {
        let body = &bytes()[HEADER_BYTES..];
        let mut payload = body[..cut % body.len()].to_vec();
        if !payload.is_empty() {
            let i = at % payload.len();
            payload[i] = value;
        }
        let b = with_valid_header(&payload, payload.len() as u64);
        if let Err(e) = load_bytes(&b) {
            names_the_file(&e);
        }
    }
}
