//! Access points and the radio model: log-distance path loss with wall attenuation, a
//! spatially consistent log-normal shadowing field, fast fading and multipath outliers.
//!
//! The mean received power of access point `j` at `p` is
//! `P0_j - 10 n log10(max(d, d0) / d0) - min(W * walls, W_max) + S_j(p)`, where `walls` counts
//! the distinct walls on the straight line from the access point to `p` and `S_j` is a
//! Gaussian random field (standard deviation `shadowing_std_db`, correlation length
//! `shadowing_correlation_m`) built from random Fourier features, so that two nearby points see
//! nearly the same shadowing (what makes fingerprinting work at all). A single measurement adds
//! white fading and, now and then, a multipath outlier, and is rounded to whole dBm like a
//! phone's report.

use crate::config::{RadioConfig, ScanConfig};
use crate::floor::SimFloorPlan;
use crate::rng::Draw;
use rand::rngs::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;
use wipdr_core::{Bssid, Point2};

/// One random Fourier feature of a shadowing field: `amplitude_db * cos(w . p + phase)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ShadowingFeature {
    /// Spatial frequency, rad/m.
    pub w: [f64; 2],
    /// Phase, rad.
    pub phase: f64,
    /// Amplitude, dB.
    pub amplitude_db: f64,
}

/// One BSSID (a radio of an access-point site).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AccessPoint {
    /// The BSSID.
    pub bssid: Bssid,
    /// Network name.
    pub ssid: String,
    /// Channel centre frequency, MHz.
    pub frequency_mhz: u32,
    /// Position, metres.
    pub position: Point2,
    /// Received power at the reference distance, dBm (`P0`).
    pub p0_dbm: f64,
    /// Index of the site (dual-band radios of one device share it).
    pub site: usize,
    /// The shadowing field's features.
    pub shadowing: Vec<ShadowingFeature>,
}

/// The radio environment of a floor: its access points and the propagation model.
#[derive(Debug, Clone, PartialEq)]
pub struct RadioModel {
    /// The access points, in BSSID column order of the survey map.
    pub access_points: Vec<AccessPoint>,
    cfg: RadioConfig,
}

const CHANNELS_24: [u32; 3] = [2412, 2437, 2462];
const CHANNELS_5: [u32; 8] = [5180, 5200, 5220, 5240, 5745, 5765, 5785, 5805];
const SSIDS: [&str; 6] = ["MallGuest", "Mall-Staff", "", "ChinaNet-", "CMCC-", "POS-"];

impl RadioModel {
    /// Places `cfg.access_points` sites: a fraction inside shops, the rest in corridors and the
    /// hall; every site has a 2.4 GHz BSSID and possibly a 5 GHz one.
    pub fn build(cfg: &RadioConfig, floor: &SimFloorPlan, rng: &mut ChaCha8Rng) -> Self {
        let mut aps = Vec::new();
        let units = &floor.plan.units;
        for site in 0..cfg.access_points {
            let in_shop = !units.is_empty() && rng.chance(cfg.shop_ap_fraction);
            let (position, ssid) = if in_shop {
                let u = rng.index(units.len());
                let (lo, hi) = units[u].polygon.bbox();
                let m = 1.0_f64.min((hi.x - lo.x) / 4.0).min((hi.y - lo.y) / 4.0);
                let p = Point2::new(
                    rng.uniform(lo.x + m, hi.x - m),
                    rng.uniform(lo.y + m, hi.y - m),
                );
                (p, format!("Shop-{:02}", u + 1))
            } else {
                let r = floor.walkable[rng.index(floor.walkable.len())];
                let p = Point2::new(
                    rng.uniform(r.x0 + 0.5, r.x1 - 0.5),
                    rng.uniform(r.y0 + 0.5, r.y1 - 0.5),
                );
                let name = SSIDS[rng.index(SSIDS.len())];
                let ssid = if name.ends_with('-') {
                    format!("{name}{:04X}", rng.index(0x10000))
                } else {
                    name.to_string()
                };
                (p, ssid)
            };
            // A locally administered unicast address: first byte 0x02.
            let base =
                (0x02u64 << 40) | ((rng.index(1 << 20) as u64) << 20) | (site as u64 & 0xf_ffff);
            let p0 = cfg.p0_dbm + cfg.p0_spread_db * rng.normal();
            let f24 = CHANNELS_24[rng.index(CHANNELS_24.len())];
            let mut radios = vec![(Bssid(base), f24, p0)];
            if rng.chance(cfg.dual_band_probability) {
                let f5 = CHANNELS_5[rng.index(CHANNELS_5.len())];
                radios.push((
                    Bssid(base ^ (0x80 << 16)),
                    f5,
                    p0 - cfg.band_5ghz_extra_loss_db,
                ));
            }
            for (bssid, frequency_mhz, p0_dbm) in radios {
                let shadowing = shadowing_field(cfg, rng);
                aps.push(AccessPoint {
                    bssid,
                    ssid: ssid.clone(),
                    frequency_mhz,
                    position,
                    p0_dbm,
                    site,
                    shadowing,
                });
            }
        }
        Self {
            access_points: aps,
            cfg: cfg.clone(),
        }
    }

    /// Mean received power (dBm) of access point `j` at `p`, with `walls` walls in between.
    pub fn mean_rss(&self, j: usize, p: Point2, walls: usize) -> f64 {
        let ap = &self.access_points[j];
        let c = &self.cfg;
        let d = (p - ap.position).norm().max(c.reference_distance_m);
        let path = 10.0 * c.path_loss_exponent * (d / c.reference_distance_m).log10();
        let wall = (c.wall_attenuation_db * walls as f64).min(c.max_wall_attenuation_db);
        let shadow: f64 = ap
            .shadowing
            .iter()
            .map(|f| f.amplitude_db * (f.w[0] * p.x + f.w[1] * p.y + f.phase).cos())
            .sum();
        ap.p0_dbm - path - wall + shadow
    }

    /// Mean received power of every access point at `p` (walls counted on the floor plan).
    pub fn mean_rss_all(&self, floor: &SimFloorPlan, p: Point2) -> Vec<f64> {
        (0..self.access_points.len())
            .map(|j| self.mean_rss(j, p, floor.walls_crossed(self.access_points[j].position, p)))
            .collect()
    }

    /// One measurement around a mean: fading, a multipath outlier now and then, whole dBm.
    pub fn measure(&self, mean_dbm: f64, rng: &mut ChaCha8Rng) -> f64 {
        let c = &self.cfg;
        let mut v = mean_dbm + c.measurement_noise_db * rng.normal();
        if rng.chance(c.multipath_probability) {
            let m = rng.uniform(c.multipath_db[0], c.multipath_db[1]);
            v += if rng.chance(0.5) { m } else { -m };
        }
        v.round()
    }
}

/// Probability that one sweep hears an access point measured at `rss_dbm`: zero below the
/// sensitivity floor, then a logistic rise to `max_detection_probability`.
pub fn detection_probability(scan: &ScanConfig, rss_dbm: f64) -> f64 {
    if rss_dbm < scan.sensitivity_dbm {
        return 0.0;
    }
    let z = (rss_dbm - scan.sensitivity_dbm - scan.detection_midpoint_db) / scan.detection_slope_db;
    scan.max_detection_probability / (1.0 + (-z).exp())
}

fn shadowing_field(cfg: &RadioConfig, rng: &mut ChaCha8Rng) -> Vec<ShadowingFeature> {
    let k = cfg.shadowing_features.max(1);
    // Cosine features with Gaussian frequencies (std 1/l) give a squared-exponential
    // covariance of length `l`; the amplitude sqrt(2/K) sigma gives the field variance sigma².
    let amplitude_db = cfg.shadowing_std_db * (2.0 / k as f64).sqrt();
    let l = cfg.shadowing_correlation_m;
    (0..k)
        .map(|_| ShadowingFeature {
            w: [rng.normal() / l, rng.normal() / l],
            phase: rng.uniform(0.0, TAU),
            amplitude_db,
        })
        .collect()
}
