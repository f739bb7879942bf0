//! Hostile input stays bounded: each case ends in a typed error from a documented,
//! configurable [`Limits`] field, without reading (or buffering) the whole input.

use std::io::{Read, Write};
use wipdr_io::floor::{ReadOptions, read_floor_info};
use wipdr_io::geojson::read_floor_plan;
use wipdr_io::trace::read_walk_from;
use wipdr_io::{IoError, Limits, read_floor_dir};

/// An endless reader repeating `chunk`, counting what it hands out.
struct Endless {
    chunk: Vec<u8>,
    pos: usize,
    served: u64,
}

impl Endless {
    fn new(chunk: Vec<u8>) -> Self {
        Self {
            chunk,
            pos: 0,
            served: 0,
        }
    }
}

impl Read for Endless {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let mut n = 0;
        while n < buf.len() {
            let take = (self.chunk.len() - self.pos).min(buf.len() - n);
            buf[n..n + take].copy_from_slice(&self.chunk[self.pos..self.pos + take]);
            n += take;
            self.pos = (self.pos + take) % self.chunk.len();
        }
        self.served += n as u64;
        Ok(n)
    }
}

#[test]
fn a_line_of_megabytes() {
    // Default limits: a single 64 MiB line without a newline is refused after 64 KiB.
    let mut endless = Endless::new(b"1574559495421\tTYPE_WAYPOINT\t1.0".to_vec());
    let e = read_walk_from(&mut endless, "long", &Limits::default()).unwrap_err();
    assert!(
        matches!(e, IoError::LineTooLong { line: 1, limit, .. } if limit == 64 * 1024),
        "{e}"
    );
    assert!(endless.served < 1 << 20, "read {} bytes", endless.served);
}

#[test]
fn a_gzip_stream_that_inflates_without_end() {
    // One gzip member of 1 MiB of valid records, repeated forever: MultiGzDecoder would
    // inflate it without end; the input limit stops it.
    let line = b"1574559495421\tTYPE_WAYPOINT\t1.0\t2.0\n";
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    for _ in 0..(1 << 20) / line.len() {
        enc.write_all(line).unwrap();
    }
    let member = enc.finish().unwrap();
    assert!(member.len() < 10_000, "{} bytes compressed", member.len());
    let limits = Limits {
        max_input_bytes: 8 << 20,
        ..Limits::default()
    };
    let mut endless = Endless::new(member);
    let e = read_walk_from(&mut endless, "bomb.txt.gz", &limits).unwrap_err();
    assert!(
        matches!(e, IoError::InputTooLarge { limit, .. } if limit == 8 << 20),
        "{e}"
    );
    assert!(
        endless.served < 1 << 20,
        "read {} compressed bytes",
        endless.served
    );
}

#[test]
fn a_scan_claiming_millions_of_entries() {
    // Two million Wi-Fi lines sharing one time, produced lazily; default limits.
    struct Scan {
        i: u64,
        pending: Vec<u8>,
    }
    impl Read for Scan {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if self.pending.is_empty() {
                if self.i == 2_000_000 {
                    return Ok(0);
                }
                let b = self.i.to_be_bytes();
                self.pending = format!(
                    "1574559497191\tTYPE_WIFI\tnet\t{:02x}:{:02x}:{:02x}:{:02x}:{:02x}:{:02x}\t-50\t2412\t1574559497000\n",
                    b[2], b[3], b[4], b[5], b[6], b[7]
                )
                .into_bytes();
                self.i += 1;
            }
            let n = self.pending.len().min(buf.len());
            buf[..n].copy_from_slice(&self.pending[..n]);
            self.pending.drain(..n);
            Ok(n)
        }
    }
    let mut scan = Scan {
        i: 0,
        pending: Vec::new(),
    };
    let e = read_walk_from(&mut scan, "scan", &Limits::default()).unwrap_err();
    assert!(
        matches!(
            e,
            IoError::ScanTooLarge {
                line: 8193,
                limit: 8192,
                ..
            }
        ),
        "{e}"
    );
    assert!(scan.i < 20_000, "generated {} lines", scan.i);
}

#[test]
fn too_many_records() {
    let limits = Limits {
        max_records: 10_000,
        ..Limits::default()
    };
    let mut endless =
        Endless::new(b"1574559495421\tTYPE_BLUE\t\t16:E5:41:F6:CC:67\t-95\n".to_vec());
    let e = read_walk_from(&mut endless, "many", &limits).unwrap_err();
    assert!(
        matches!(e, IoError::TooManyRecords { line: 10_001, .. }),
        "{e}"
    );
}

#[test]
fn a_geojson_of_absurd_size() {
    let dir = tempfile::tempdir().unwrap();
    // A (sparse) 65 MiB file: refused by size with default limits, without parsing it.
    let big = dir.path().join("geojson_map.json");
    std::fs::File::create(&big)
        .unwrap()
        .set_len(65 << 20)
        .unwrap();
    let e = read_floor_plan(&big, 10.0, 10.0, &Limits::default()).unwrap_err();
    assert!(
        matches!(e, IoError::InputTooLarge { limit, .. } if limit == 64 << 20),
        "{e}"
    );
    assert!(e.to_string().contains("geojson_map.json"), "{e}");

    // Too many vertices for the configured limit.
    let mut coords = String::from("[");
    for i in 0..5000 {
        coords.push_str(&format!("[{}, {}],", i % 100, i / 100));
    }
    coords.push_str("[0, 0]]");
    let text = format!(
        r#"{{"type": "FeatureCollection", "features": [{{"type": "Feature", "geometry": {{"type": "Polygon", "coordinates": [{coords}]}}}}]}}"#
    );
    std::fs::write(&big, &text).unwrap();
    let limits = Limits {
        max_geojson_vertices: 1000,
        ..Limits::default()
    };
    let e = read_floor_plan(&big, 10.0, 10.0, &limits).unwrap_err();
    assert!(e.to_string().contains("more than 1000 vertices"), "{e}");
    assert!(read_floor_plan(&big, 10.0, 10.0, &Limits::default()).is_ok());

    // Too many features.
    let feature = r#"{"type": "Feature", "geometry": {"type": "Polygon", "coordinates": [[[0,0],[1,0],[1,1],[0,0]]]}}"#;
    let text = format!(r#"{{"features": [{}]}}"#, vec![feature; 50].join(","));
    std::fs::write(&big, &text).unwrap();
    let limits = Limits {
        max_geojson_features: 20,
        ..Limits::default()
    };
    let e = read_floor_plan(&big, 10.0, 10.0, &limits).unwrap_err();
    assert!(
        matches!(&e, IoError::Invalid { field, .. } if field == "features"),
        "{e}"
    );

    // Absurd nesting: serde_json's recursion limit gives a syntax error, not a stack overflow.
    std::fs::write(&big, "[".repeat(100_000)).unwrap();
    let e = read_floor_plan(&big, 10.0, 10.0, &Limits::default()).unwrap_err();
    assert!(matches!(e, IoError::JsonSyntax { .. }), "{e}");
}

#[test]
fn bad_floor_info_names_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let info = dir.path().join("floor_info.json");
    std::fs::write(&info, r#"{"map_info": {"width": -3, "height": 5}}"#).unwrap();
    let e = read_floor_info(&info, &Limits::default()).unwrap_err();
    assert!(e.to_string().contains("map_info.width"), "{e}");
    std::fs::write(&info, "{not json").unwrap();
    let e = read_floor_info(&info, &Limits::default()).unwrap_err();
    assert!(matches!(e, IoError::JsonSyntax { .. }), "{e}");
    let e = read_floor_dir(dir.path(), &ReadOptions::default()).unwrap_err();
    assert!(matches!(e, IoError::NotAFloor { .. }), "{e}");
}
