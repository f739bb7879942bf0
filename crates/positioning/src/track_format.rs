//! A track in the formats users read: CSV `t_ms,x,y,floor,sd_m` (full precision), a GeoJSON
//! Feature (longitude/latitude where the site has a WGS84 frame, else the floor's metres), and
//! the IPIN competition's `t_s,lat,lon,floor` at 2 Hz. `wipdr locate` writes them to files and
//! `wipdr serve` answers them from its database: one implementation, so the two give the same
//! bytes for the same track.
//!
//! ```
//! use wipdr_positioning::track_format::{TrackRow, csv};
//! let rows = [TrackRow { t_ms: 1000, x: 1.5, y: 2.0, floor: Some(0), sd_m: None }];
//! assert_eq!(csv(&rows), "t_ms,x,y,floor,sd_m\n1000,1.5,2,0,\n");
//! ```

use crate::PositionEstimate;
use std::fmt::Write as _;
use wipdr_core::{GeoFrame, Point2};

/// Rows a second of the IPIN format.
pub const IPIN_RATE_HZ: i64 = 2;

/// One estimate of a track as the formats write it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackRow {
    /// Time, ms (the stream's clock).
    pub t_ms: i64,
    /// Metres in the site's frame.
    pub x: f64,
    /// Metres in the site's frame.
    pub y: f64,
    /// The floor, where known.
    pub floor: Option<i32>,
    /// The standard deviation per axis, metres, where the scheme reports one.
    pub sd_m: Option<f64>,
}

impl From<&PositionEstimate> for TrackRow {
    fn from(e: &PositionEstimate) -> Self {
        Self {
            t_ms: e.t,
            x: e.position.x,
            y: e.position.y,
            floor: e.floor,
            sd_m: e.sd_m(),
        }
    }
}

/// The rows of a track of estimates.
pub fn rows_of(track: &[PositionEstimate]) -> Vec<TrackRow> {
    track.iter().map(TrackRow::from).collect()
}

fn opt<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map(|v| v.to_string()).unwrap_or_default()
}

/// CSV `t_ms,x,y,floor,sd_m` (full precision: every `f64` round-trips; an unknown floor or
/// radius is an empty field).
pub fn csv(track: &[TrackRow]) -> String {
    let mut s = String::from("t_ms,x,y,floor,sd_m\n");
    for e in track {
        let _ = writeln!(
            s,
            "{},{},{},{},{}",
            e.t_ms,
            e.x,
            e.y,
            opt(e.floor),
            opt(e.sd_m)
        );
    }
    s
}

/// A GeoJSON Feature with the track as a LineString: longitude/latitude (RFC 7946) where
/// `frame` is given, else the floor's metres; times, floors and radii as properties.
pub fn geojson(
    track: &[TrackRow],
    walk: &str,
    scheme: &str,
    frame: Option<&GeoFrame>,
) -> serde_json::Value {
    let coordinates: Vec<[f64; 2]> = track
        .iter()
        .map(|e| match frame {
            Some(f) => {
                let (lat, lon) = f.to_lat_lon(Point2::new(e.x, e.y));
                [lon, lat]
            }
            None => [e.x, e.y],
        })
        .collect();
    let times: Vec<i64> = track.iter().map(|e| e.t_ms).collect();
    let floors: Vec<Option<i32>> = track.iter().map(|e| e.floor).collect();
    let radii: Vec<Option<f64>> = track.iter().map(|e| e.sd_m).collect();
    let frame_note = if frame.is_some() {
        "WGS84 longitude, latitude"
    } else {
        "floor metres (x east, y north, as the floor plan)"
    };
    serde_json::json!({
        "type": "Feature",
        "properties": {
            "walk": walk,
            "scheme": scheme,
            "frame": frame_note,
            "t_ms": times,
            "floor": floors,
            "sd_m": radii,
        },
        "geometry": { "type": "LineString", "coordinates": coordinates },
    })
}

/// The track at `period_ms`: a row at every multiple of the period from the first estimate
/// to `end` (the stream's last sample; the last estimate when `None`), each the latest
/// estimate at or before its time.
pub fn at_rate(track: &[TrackRow], period_ms: i64, end: Option<i64>) -> Vec<TrackRow> {
    let (Some(first), Some(last)) = (track.first(), track.last()) else {
        return Vec::new();
    };
    let period = period_ms.max(1);
    let end = end.unwrap_or(last.t_ms).max(last.t_ms);
    let mut t = first.t_ms.div_euclid(period) * period;
    if t < first.t_ms {
        t += period;
    }
    let mut out = Vec::new();
    let mut j = 0usize;
    while t <= end {
        while j + 1 < track.len() && track[j + 1].t_ms <= t {
            j += 1;
        }
        out.push(TrackRow {
            t_ms: t,
            ..track[j]
        });
        t += period;
    }
    out
}

/// `t_s,lat,lon,floor` at [`IPIN_RATE_HZ`] (the IPIN competition's format; `floor` empty
/// where unknown).
pub fn ipin(track: &[TrackRow], frame: &GeoFrame, end: Option<i64>) -> String {
    let mut s = String::from("t_s,lat,lon,floor\n");
    for e in at_rate(track, 1000 / IPIN_RATE_HZ, end) {
        let (lat, lon) = frame.to_lat_lon(Point2::new(e.x, e.y));
        let _ = writeln!(
            s,
            "{:.3},{:.9},{:.9},{}",
            e.t_ms as f64 / 1000.0,
            lat,
            lon,
            opt(e.floor)
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(t_ms: i64, x: f64) -> TrackRow {
        TrackRow {
            t_ms,
            x,
            y: 0.0,
            floor: Some(0),
            sd_m: None,
        }
    }

    #[test]
    fn two_hertz_rows_take_the_latest_estimate_at_or_before_their_time() {
        let track = [row(120, 1.0), row(700, 2.0), row(1_400, 3.0)];
        let got: Vec<(i64, f64)> = at_rate(&track, 500, Some(2_100))
            .iter()
            .map(|e| (e.t_ms, e.x))
            .collect();
        assert_eq!(
            got,
            vec![(500, 1.0), (1_000, 2.0), (1_500, 3.0), (2_000, 3.0)]
        );
        assert!(at_rate(&[], 500, None).is_empty());
    }

    #[test]
    fn ipin_rows_are_in_degrees_and_csv_keeps_full_precision() {
        let frame = GeoFrame::new(49.46, 11.11).unwrap();
        assert_eq!(
            ipin(&[row(0, 0.0)], &frame, Some(400)),
            "t_s,lat,lon,floor\n0.000,49.460000000,11.110000000,0\n"
        );
        let x = 0.1 + 0.2;
        let text = csv(&[TrackRow {
            sd_m: Some(1.25),
            floor: None,
            ..row(5, x)
        }]);
        assert_eq!(text, format!("t_ms,x,y,floor,sd_m\n5,{x},0,,1.25\n"));
        let back: f64 = text
            .lines()
            .nth(1)
            .unwrap()
            .split(',')
            .nth(1)
            .unwrap()
            .parse()
            .unwrap();
        assert_eq!(back, x);
    }

    #[test]
    fn geojson_is_a_line_in_metres_without_a_frame() {
        let v = geojson(&[row(0, 1.0), row(500, 2.0)], "w", "pmf", None);
        assert_eq!(v["geometry"]["type"], "LineString");
        assert_eq!(v["geometry"]["coordinates"][1][0], 2.0);
        assert_eq!(v["properties"]["t_ms"][1], 500);
    }
}
