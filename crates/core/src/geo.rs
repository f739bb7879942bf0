//! WGS84 latitude/longitude to a local east/north metre frame and back.
//!
//! The frame is the plane tangent to the WGS84 ellipsoid at an origin: `x` metres east,
//! `y` metres north, with the ellipsoid's meridian radius `M` and prime-vertical radius `N` at
//! the origin's latitude (`x = dlon * N cos(lat0)`, `y = dlat * M`, angles in radians). Over a
//! building (a few hundred metres) this differs from an exact ENU projection by well under a
//! millimetre, and the inverse is exact up to rounding. IPIN logfiles give ground truth and
//! beacon positions in degrees; the tools write estimates back in degrees with
//! [`GeoFrame::to_lat_lon`].

use crate::{CoreError, Point2};
use serde::{Deserialize, Serialize};

/// WGS84 semi-major axis, metres.
pub const WGS84_A: f64 = 6_378_137.0;
/// WGS84 first eccentricity squared.
pub const WGS84_E2: f64 = 6.694_379_990_141_33e-3;

/// A local east/north metre frame at a WGS84 origin.
///
/// ```
/// use wipdr_core::GeoFrame;
/// let frame = GeoFrame::new(49.4611, 11.1109)?;
/// let p = frame.to_local(49.4612, 11.1110);
/// assert!((p.y - 11.12).abs() < 0.01 && (p.x - 7.25).abs() < 0.01);
/// let (lat, lon) = frame.to_lat_lon(p);
/// assert!((lat - 49.4612).abs() < 1e-12 && (lon - 11.1110).abs() < 1e-12);
/// # Ok::<(), wipdr_core::CoreError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GeoFrame {
    /// Origin latitude, degrees.
    pub origin_lat_deg: f64,
    /// Origin longitude, degrees.
    pub origin_lon_deg: f64,
    /// Metres per radian of longitude at the origin (`N cos(lat0)`).
    east_m_per_rad: f64,
    /// Metres per radian of latitude at the origin (`M`).
    north_m_per_rad: f64,
}

impl GeoFrame {
    /// A frame at `(lat, lon)` degrees; latitudes within +-89 degrees (the frame degenerates
    /// at the poles), longitudes within +-180.
    pub fn new(origin_lat_deg: f64, origin_lon_deg: f64) -> Result<Self, CoreError> {
        if !(origin_lat_deg.is_finite() && origin_lat_deg.abs() <= 89.0) {
            return Err(CoreError::InvalidValue {
                field: "origin latitude",
                value: origin_lat_deg,
            });
        }
        if !(origin_lon_deg.is_finite() && origin_lon_deg.abs() <= 180.0) {
            return Err(CoreError::InvalidValue {
                field: "origin longitude",
                value: origin_lon_deg,
            });
        }
        let phi = origin_lat_deg.to_radians();
        let w = (1.0 - WGS84_E2 * phi.sin().powi(2)).sqrt();
        let n = WGS84_A / w;
        let m = WGS84_A * (1.0 - WGS84_E2) / (w * w * w);
        Ok(Self {
            origin_lat_deg,
            origin_lon_deg,
            east_m_per_rad: n * phi.cos(),
            north_m_per_rad: m,
        })
    }

    /// Degrees to local metres (`x` east, `y` north).
    pub fn to_local(&self, lat_deg: f64, lon_deg: f64) -> Point2 {
        Point2::new(
            (lon_deg - self.origin_lon_deg).to_radians() * self.east_m_per_rad,
            (lat_deg - self.origin_lat_deg).to_radians() * self.north_m_per_rad,
        )
    }

    /// Local metres back to `(latitude, longitude)` degrees.
    pub fn to_lat_lon(&self, p: Point2) -> (f64, f64) {
        (
            self.origin_lat_deg + (p.y / self.north_m_per_rad).to_degrees(),
            self.origin_lon_deg + (p.x / self.east_m_per_rad).to_degrees(),
        )
    }

    /// The same frame moved so that local point `p` becomes its origin.
    pub fn shifted_to(&self, p: Point2) -> Result<Self, CoreError> {
        let (lat, lon) = self.to_lat_lon(p);
        Self::new(lat, lon)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn one_degree_of_latitude_is_about_111_km() {
        let f = GeoFrame::new(49.46, 11.11).unwrap();
        let p = f.to_local(50.46, 11.11);
        assert!((p.y - 111_200.0).abs() < 300.0, "{}", p.y);
        assert_eq!(p.x, 0.0);
    }

    #[test]
    fn bad_origins_are_errors() {
        assert!(GeoFrame::new(f64::NAN, 0.0).is_err());
        assert!(GeoFrame::new(90.0, 0.0).is_err());
        assert!(GeoFrame::new(0.0, 181.0).is_err());
    }

    proptest! {
        #[test]
        fn inverse_round_trips(lat0 in -80.0..80.0f64, lon0 in -179.0..179.0f64,
                               x in -2000.0..2000.0f64, y in -2000.0..2000.0f64) {
            let f = GeoFrame::new(lat0, lon0).unwrap();
            let (lat, lon) = f.to_lat_lon(Point2::new(x, y));
            let back = f.to_local(lat, lon);
            prop_assert!((back.x - x).abs() < 1e-6 && (back.y - y).abs() < 1e-6);
        }
    }
}
