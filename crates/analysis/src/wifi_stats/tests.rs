//! Tests of the Wi-Fi statistics and the RR fit.

use super::rr_fit::*;
use super::*;
use proptest::prelude::*;
use wipdr_core::WifiEntry;

/// SplitMix64 uniform in [0, 1) and a Box-Muller normal: a tiny seeded generator for
/// the synthetic data (reproducible per seed).
struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

fn synthetic(truth: &RrModel, n: usize, noise: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
    synthetic_over(truth, n, noise, seed, (-100.0, -45.0))
}

/// Noisy samples of `truth` at RSSI values uniform over `range`.
fn synthetic_over(
    truth: &RrModel,
    n: usize,
    noise: f64,
    seed: u64,
    range: (f64, f64),
) -> (Vec<f64>, Vec<f64>) {
    let mut rng = Rng(seed);
    let x: Vec<f64> = (0..n)
        .map(|_| range.0 + (range.1 - range.0) * rng.uniform())
        .collect();
    let y = x
        .iter()
        .map(|&v| truth.eval(v) + noise * rng.normal())
        .collect();
    (x, y)
}

fn within(got: f64, want: f64, rel: f64) -> bool {
    (got - want).abs() <= rel * want.abs()
}

#[test]
fn recovers_paper_parameters_from_noisy_data_several_seeds() {
    for seed in 1..=8 {
        let (x, y) = synthetic(&RrModel::PAPER_PERCENT, 2000, 1.0, seed);
        let fit = fit_rr_model(&x, &y, &FitConfig::default()).unwrap();
        let (m, t) = (fit.model, RrModel::PAPER_PERCENT);
        assert!(
            within(m.eta0, t.eta0, 0.05)
                && within(m.a, t.a, 0.05)
                && within(m.rssi_r, t.rssi_r, 0.05)
                && within(m.c, t.c, 0.05),
            "seed {seed}: {m:?}"
        );
        assert!(fit.correlation > 0.99, "{}", fit.correlation);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn recovers_parameters_within_5_percent(
        eta0 in 1.0f64..5.0,
        a in 50.0f64..95.0,
        rssi_r in -85.0f64..-65.0,
        c in 1.0f64..4.0,
        seed in any::<u64>(),
    ) {
        let truth = RrModel { eta0, a, rssi_r, c };
        // Data covering both plateaus (the inflection +- 25 dB, over 6 widths each side):
        // with a plateau barely sampled its level is not identifiable to 5 %.
        let (x, y) = synthetic_over(&truth, 3000, 0.5, seed, (rssi_r - 25.0, rssi_r + 25.0));
        let fit = fit_rr_model(&x, &y, &FitConfig::default()).unwrap();
        let m = fit.model;
        prop_assert!(within(m.eta0, eta0, 0.05), "eta0 {} vs {}", m.eta0, eta0);
        prop_assert!(within(m.a, a, 0.05), "a {} vs {}", m.a, a);
        prop_assert!(within(m.rssi_r, rssi_r, 0.05), "rssi_r {} vs {}", m.rssi_r, rssi_r);
        prop_assert!(within(m.c, c, 0.05), "c {} vs {}", m.c, c);
    }
}

#[test]
fn runaway_data_stay_within_bounds_and_say_so() {
    // A concave rise with no upper level: unbounded least squares runs off to infinity.
    let x: Vec<f64> = (0..60).map(|i| -95.0 + i as f64).collect();
    let y: Vec<f64> = x
        .iter()
        .map(|v| 100.0 - 90.0 * (-(v + 95.0) / 30.0).exp())
        .collect();
    let cfg = FitConfig {
        value_bounds: Some([0.0, 100.0]),
        ..Default::default()
    };
    let fit = fit_rr_model(&x, &y, &cfg).unwrap();
    let m = fit.model;
    assert!(m.eta0 >= 0.0 && m.eta0 + m.a <= 100.0 + 1e-9, "{m:?}");
    assert!((-95.0..=-36.0).contains(&m.rssi_r), "{m:?}");
    assert!(fit.at_bound.any(), "{fit:?}");
    // Interior data are not affected by the bounds.
    let (x, y) = synthetic(&RrModel::PAPER_PERCENT, 2000, 1.0, 11);
    let free = fit_rr_model(&x, &y, &FitConfig::default()).unwrap();
    let bounded = fit_rr_model(&x, &y, &cfg).unwrap();
    assert!(!bounded.at_bound.any(), "{bounded:?}");
    assert!((free.model.rssi_r - bounded.model.rssi_r).abs() < 1e-6);
    let bad = FitConfig {
        value_bounds: Some([1.0, 0.0]),
        ..Default::default()
    };
    assert!(matches!(
        fit_rr_model(&x, &y, &bad),
        Err(WifiStatsError::InvalidConfig { .. })
    ));
}

#[test]
fn falling_curve_has_negative_height() {
    let truth = RrModel {
        eta0: 0.6,
        a: -0.55,
        rssi_r: -85.0,
        c: 2.5,
    };
    let (x, y) = synthetic(&truth, 1500, 0.01, 7);
    let m = fit_rr_model(&x, &y, &FitConfig::default()).unwrap().model;
    assert!(
        within(m.a, -0.55, 0.05) && within(m.rssi_r, -85.0, 0.05),
        "{m:?}"
    );
}

#[test]
fn bad_input_gives_typed_errors() {
    let cfg = FitConfig::default();
    assert_eq!(
        fit_rr_model(&[], &[], &cfg),
        Err(WifiStatsError::TooFewPoints { have: 0, need: 8 })
    );
    let x = [-90.0, -85.0, -80.0, -75.0, -70.0, -65.0, -60.0, -55.0];
    let mut y = [0.0, 0.1, 0.3, 0.5, 0.8, 0.9, 0.9, 0.9];
    assert!(matches!(
        fit_rr_model(&x[..5], &y[..5], &cfg),
        Err(WifiStatsError::TooFewPoints { have: 5, need: 8 })
    ));
    assert!(matches!(
        fit_rr_model(&x, &y[..7], &cfg),
        Err(WifiStatsError::LengthMismatch { rssi: 8, eta: 7 })
    ));
    y[3] = f64::NAN;
    assert!(matches!(
        fit_rr_model(&x, &y, &cfg),
        Err(WifiStatsError::NonFinite {
            field: "eta",
            index: 3,
            ..
        })
    ));
    let flat = [-70.0; 8];
    assert!(matches!(
        fit_rr_model(&flat, &[0.5; 8], &cfg),
        Err(WifiStatsError::NoSpread { .. })
    ));
    let tight = FitConfig {
        max_iterations: 1,
        tolerance: 0.0,
        ..cfg
    };
    let (x, y) = synthetic(&RrModel::PAPER_PERCENT, 500, 2.0, 3);
    assert!(matches!(
        fit_rr_model(&x, &y, &tight),
        Err(WifiStatsError::NoConvergence { iterations: 1, .. })
    ));
}

fn entry(b: u64, rssi: f64, last_seen: i64) -> WifiEntry {
    WifiEntry {
        bssid: Bssid(b),
        ssid: String::new(),
        rssi_dbm: rssi,
        frequency_mhz: 2412,
        last_seen_ms: last_seen,
    }
}

#[test]
fn refresh_and_loss_from_last_seen_times() {
    // Scans every 2 s. AP 1 is fresh in every scan; AP 2 is a cached entry refreshed every
    // other scan (its last-seen time jitters by 1 ms when not refreshed); AP 3 is missing
    // from two of the six scans of its span.
    let mut scans = Vec::new();
    for k in 0..8i64 {
        let t = 1_000_000 + 2000 * k;
        let mut entries = vec![entry(1, -50.0, t - 100)];
        let ls2 = if k % 2 == 0 { t - 300 } else { t - 2300 + 1 };
        entries.push(entry(2, -80.0, ls2));
        if (1..=6).contains(&k) && k != 3 && k != 4 {
            entries.push(entry(3, -88.0, t - 50));
        }
        scans.push(WifiScan { t, entries });
    }
    let mut skips = WalkStatsSkips::default();
    let s = walk_ap_stats(&scans, &WifiStatsConfig::default(), &mut skips);
    assert_eq!(skips, WalkStatsSkips::default());
    assert_eq!(s.len(), 3);
    assert_eq!(
        (s[0].refresh_rate, s[0].loss_rate, s[0].span_scans),
        (1.0, 0.0, 7)
    );
    assert_eq!(s[0].mean_rssi_dbm, -50.0);
    // AP 2: scans 2, 4, 6 refresh it out of 7 (1..=7).
    assert_eq!(s[1].refreshes, 3);
    assert!((s[1].refresh_rate - 3.0 / 7.0).abs() < 1e-12);
    // AP 3: span 1..=6, missing in 3 and 4; each appearance is fresh.
    assert_eq!((s[2].span_scans, s[2].refreshes), (6, 4));
    assert!((s[2].loss_rate - 2.0 / 6.0).abs() < 1e-12);
    assert!((s[2].refresh_rate - 4.0 / 6.0).abs() < 1e-12);
}

#[test]
fn short_walks_and_spans_are_counted() {
    let mut skips = WalkStatsSkips::default();
    assert!(walk_ap_stats(&[], &WifiStatsConfig::default(), &mut skips).is_empty());
    let one = [WifiScan {
        t: 0,
        entries: vec![entry(1, -60.0, 0)],
    }];
    assert!(walk_ap_stats(&one, &WifiStatsConfig::default(), &mut skips).is_empty());
    assert_eq!(skips.walks_too_short, 2);
    let scans: Vec<WifiScan> = (0..3)
        .map(|k| WifiScan {
            t: 1000 * k,
            entries: vec![entry(1, if k == 2 { f64::NAN } else { -60.0 }, 1000 * k)],
        })
        .collect();
    let s = walk_ap_stats(&scans, &WifiStatsConfig::default(), &mut skips);
    assert!(s.is_empty());
    assert_eq!((skips.short_spans, skips.non_finite_rssi), (1, 1));
    assert!(
        WifiStatsConfig {
            min_span_scans: 0,
            ..Default::default()
        }
        .validate()
        .is_err()
    );
}

#[test]
fn real_walk_rates_are_sane() {
    let floor = match wipdr_io::real_data("ilc20/site1/F1") {
        Ok(floor) => floor,
        Err(missing) => {
            eprintln!("skipped: {missing}");
            return;
        }
    };
    let files = match wipdr_io::floor::walk_files(&floor) {
        Ok(f) if !f.is_empty() => f,
        _ => {
            eprintln!("skipped: no real walks under {}", floor.display());
            return;
        }
    };
    let walk = wipdr_io::trace::read_walk(&files[0]).unwrap().walk;
    let mut skips = WalkStatsSkips::default();
    let stats = walk_ap_stats(&walk.wifi, &WifiStatsConfig::default(), &mut skips);
    assert!(stats.len() > 20, "{} pairs", stats.len());
    assert!(stats.iter().all(|s| (0.0..=1.0).contains(&s.refresh_rate)
        && (0.0..=1.0).contains(&s.loss_rate)
        && s.mean_rssi_dbm.is_finite()
        && s.refreshes <= s.span_scans));
    // Stronger APs are refreshed more often on average (002 §3.1).
    let rates = |keep: &dyn Fn(f64) -> bool| -> Vec<f64> {
        stats
            .iter()
            .filter(|s| keep(s.mean_rssi_dbm))
            .map(|s| s.refresh_rate)
            .collect()
    };
    let (strong, weak) = (rates(&|r| r > -75.0), rates(&|r| r < -85.0));
    assert!(!strong.is_empty() && !weak.is_empty());
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    assert!(
        mean(&strong) > mean(&weak),
        "{} vs {}",
        mean(&strong),
        mean(&weak)
    );
}

#[test]
fn bins_average_and_skip_sparse() {
    let b = binned_means(
        &[-70.2, -70.8, -60.5, f64::NAN],
        &[1.0, 3.0, 5.0, 1.0],
        1.0,
        2,
    );
    assert_eq!(b.len(), 1);
    assert_eq!((b[0].rssi_dbm, b[0].mean, b[0].count), (-70.5, 2.0, 2));
}
