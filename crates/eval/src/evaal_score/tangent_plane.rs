//! The organisers' local tangent plane: WGS84 geodetic coordinates to east/north/up metres
//! at an origin, through Earth-centred Earth-fixed coordinates (exact, not the first-order
//! [`wipdr_core::GeoFrame`]).

use wipdr_core::geo::{WGS84_A, WGS84_E2};

/// Altitude of the origin and of every point in the organisers' scorer, metres (about the
/// ground level of the 2023 venue, Nuremberg).
pub const EVAAL_ALTITUDE_M: f64 = 314.0;

/// An east/north/up frame tangent to the WGS84 ellipsoid at an origin.
///
/// ```
/// use wipdr_eval::evaal_score::TangentPlane;
/// let plane = TangentPlane::new(49.4611, 11.1109, 314.0);
/// let [e, n, _up] = plane.enu(49.4621, 11.1109, 314.0);
/// assert!(e.abs() < 1e-6 && (n - 111.22).abs() < 0.01); // 0.001 degree of latitude
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TangentPlane {
    origin_ecef: [f64; 3],
    sin_lat: f64,
    cos_lat: f64,
    sin_lon: f64,
    cos_lon: f64,
}

/// Earth-centred Earth-fixed coordinates (metres) of a WGS84 point (degrees, metres).
pub fn ecef(lat_deg: f64, lon_deg: f64, h_m: f64) -> [f64; 3] {
    let (sin_lat, cos_lat) = lat_deg.to_radians().sin_cos();
    let (sin_lon, cos_lon) = lon_deg.to_radians().sin_cos();
    let n = WGS84_A / (1.0 - WGS84_E2 * sin_lat * sin_lat).sqrt();
    [
        (n + h_m) * cos_lat * cos_lon,
        (n + h_m) * cos_lat * sin_lon,
        (n * (1.0 - WGS84_E2) + h_m) * sin_lat,
    ]
}

impl TangentPlane {
    /// The plane at `(lat, lon)` degrees and `h` metres above the ellipsoid.
    pub fn new(lat_deg: f64, lon_deg: f64, h_m: f64) -> Self {
        let (sin_lat, cos_lat) = lat_deg.to_radians().sin_cos();
        let (sin_lon, cos_lon) = lon_deg.to_radians().sin_cos();
        Self {
            origin_ecef: ecef(lat_deg, lon_deg, h_m),
            sin_lat,
            cos_lat,
            sin_lon,
            cos_lon,
        }
    }

    /// `[east, north, up]` metres of a point (degrees, metres above the ellipsoid).
    pub fn enu(&self, lat_deg: f64, lon_deg: f64, h_m: f64) -> [f64; 3] {
        let p = ecef(lat_deg, lon_deg, h_m);
        let d = [
            p[0] - self.origin_ecef[0],
            p[1] - self.origin_ecef[1],
            p[2] - self.origin_ecef[2],
        ];
        let east = -self.sin_lon * d[0] + self.cos_lon * d[1];
        let north = -self.sin_lat * self.cos_lon * d[0] - self.sin_lat * self.sin_lon * d[1]
            + self.cos_lat * d[2];
        let up = self.cos_lat * self.cos_lon * d[0]
            + self.cos_lat * self.sin_lon * d[1]
            + self.sin_lat * d[2];
        [east, north, up]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Meridian and prime-vertical radii of curvature at `lat` (degrees).
    fn radii(lat_deg: f64) -> (f64, f64) {
        let s = lat_deg.to_radians().sin();
        let w = (1.0 - WGS84_E2 * s * s).sqrt();
        (WGS84_A * (1.0 - WGS84_E2) / (w * w * w), WGS84_A / w)
    }

    #[test]
    fn small_offsets_follow_the_radii_of_curvature_at_the_altitude() {
        let (lat0, lon0, h) = (49.4611, 11.1109, EVAAL_ALTITUDE_M);
        let plane = TangentPlane::new(lat0, lon0, h);
        assert_eq!(plane.enu(lat0, lon0, h), [0.0, 0.0, 0.0]);
        let (m, n) = radii(lat0);
        let d = 0.001_f64;
        let [e, nn, _] = plane.enu(lat0 + d, lon0, h);
        assert!(e.abs() < 1e-9);
        assert!((nn - (m + h) * d.to_radians()).abs() < 1e-4, "{nn}");
        let [e, nn, up] = plane.enu(lat0, lon0 + d, h);
        assert!((e - (n + h) * lat0.to_radians().cos() * d.to_radians()).abs() < 1e-4);
        assert!(nn.abs() < 1e-3);
        // The plane leaves the ellipsoid: 72 m east it is 0.4 mm below the point.
        assert!(up < 0.0 && up > -1e-3, "{up}");
    }

    #[test]
    fn the_altitude_scales_distances_by_a_few_millimetres_per_100_m() {
        let (lat0, lon0) = (49.4611, 11.1109);
        let at = |h: f64| TangentPlane::new(lat0, lon0, h).enu(lat0 + 0.001, lon0, h)[1];
        let (sea, venue) = (at(0.0), at(EVAAL_ALTITUDE_M));
        // 111.2 m x 314 m / 6.37e6 m = 5.5 mm.
        assert!((venue - sea - 0.0055).abs() < 0.0002, "{}", venue - sea);
    }
}
