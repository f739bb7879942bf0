//! A stored track in the formats `wipdr locate` writes: CSV `t_ms,x,y,floor,sd_m`, a GeoJSON
//! Feature (longitude/latitude where the model has a WGS84 frame, else metres), and the IPIN
//! competition's `t_s,lat,lon,floor` at 2 Hz (where the model has a WGS84 frame). The same
//! rules as `tools/src/cmd/locate.rs`, byte for byte (the equivalence test compares the files).

use crate::db::StoredEstimate;
use std::fmt::Write as _;
use wipdr_core::{GeoFrame, Point2};

/// Rows a second of the IPIN format.
pub const IPIN_RATE_HZ: i64 = 2;

fn opt<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map(|v| v.to_string()).unwrap_or_default()
}

/// CSV `t_ms,x,y,floor,sd_m` (full precision: `f64` round-trips).
pub fn csv(track: &[StoredEstimate]) -> String {
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

/// A GeoJSON Feature with the track as a LineString.
pub fn geojson(
    track: &[StoredEstimate],
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
pub fn at_rate(track: &[StoredEstimate], period_ms: i64, end: Option<i64>) -> Vec<StoredEstimate> {
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
        out.push(StoredEstimate {
            t_ms: t,
            ..track[j]
        });
        t += period;
    }
    out
}

/// `t_s,lat,lon,floor` at [`IPIN_RATE_HZ`].
pub fn ipin(track: &[StoredEstimate], frame: &GeoFrame, end: Option<i64>) -> String {
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

    fn e(t_ms: i64) -> StoredEstimate {
        StoredEstimate {
            t_ms,
            x: t_ms as f64,
            y: 0.0,
            floor: None,
            sd_m: None,
        }
    }

    #[test]
    fn the_rate_rows_take_the_latest_estimate_at_or_before_their_time() {
        let rows = at_rate(&[e(120), e(700), e(1100)], 500, Some(1600));
        let t: Vec<i64> = rows.iter().map(|r| r.t_ms).collect();
        assert_eq!(t, vec![500, 1000, 1500]);
        let x: Vec<f64> = rows.iter().map(|r| r.x).collect();
        assert_eq!(x, vec![120.0, 700.0, 1100.0]);
        assert_eq!(csv(&[e(1)]), "t_ms,x,y,floor,sd_m\n1,1,0,,\n");
    }
}
