//! Prints how realistic a generated floor is for positioning: plain WKNN Wi-Fi error against
//! the survey map (ordinary and gross-error scans apart), scan statistics, and a naive step
//! counter's count against the true steps.
//!
//! `cargo run --release -p wipdr-sim --example quality -- [SEED] [WALKS] [CONFIG.toml]`

use wipdr_core::angle;
use wipdr_sim::{SimConfig, generate};

fn percentile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return f64::NAN;
    }
    v[((v.len() - 1) as f64 * q).round() as usize]
}

fn main() {
    let mut args = std::env::args().skip(1);
    let seed: u64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(1);
    let walks: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(10);
    let mut cfg: SimConfig = match args.next() {
        Some(path) => toml::from_str(&std::fs::read_to_string(path).expect("read config"))
            .expect("parse config"),
        None => SimConfig::default(),
    };
    cfg.walks = walks;
    let max_age_ms: i64 = std::env::var("MAX_AGE_MS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(i64::MAX);
    cfg.gross_error_rate = 0.05;
    let sim = generate(&cfg, seed).expect("generate");
    let bssids = &sim.survey.bssids;
    let fill = -110.0;
    let train: Vec<(wipdr_core::Point2, Vec<f64>)> = sim
        .survey
        .train
        .iter()
        .map(|p| {
            (
                p.position,
                p.rss.iter().map(|v| v.unwrap_or(fill)).collect(),
            )
        })
        .collect();
    let wknn = |q: &[f64]| {
        let mut d: Vec<(f64, wipdr_core::Point2)> = train
            .iter()
            .map(|(p, f)| {
                (
                    f.iter()
                        .zip(q)
                        .map(|(a, b)| (a - b) * (a - b))
                        .sum::<f64>()
                        .sqrt(),
                    *p,
                )
            })
            .collect();
        d.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (mut sx, mut sy, mut sw) = (0.0, 0.0, 0.0);
        for (dist, p) in d.iter().take(5) {
            let w = 1.0 / dist.max(1e-6);
            sx += w * p.x;
            sy += w * p.y;
            sw += w;
        }
        wipdr_core::Point2::new(sx / sw, sy / sw)
    };
    let (mut normal, mut gross, mut ages, mut counts) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut true_steps, mut detected_steps) = (0usize, 0usize);
    let mut end_drift = Vec::new();
    for w in &sim.walks {
        for scan in &w.walk.wifi {
            let mut q = vec![fill; bssids.len()];
            for e in scan
                .entries
                .iter()
                .filter(|e| e.age_ms(scan.t) <= max_age_ms)
            {
                ages.push(e.age_ms(scan.t) as f64 / 1000.0);
                if let Ok(j) = bssids
                    .binary_search(&e.bssid)
                    .or_else(|_| bssids.iter().position(|b| *b == e.bssid).ok_or(()))
                {
                    q[j] = e.rssi_dbm;
                }
            }
            counts.push(scan.entries.len() as f64);
            let err = (wknn(&q) - w.truth.position_at(scan.t).unwrap()).norm();
            if w.truth.is_gross_error(scan.t) {
                gross.push(err)
            } else {
                normal.push(err)
            }
        }
        // Naive steps: peaks of the smoothed acceleration magnitude above g + 1.
        let acc = &w.walk.imu.accelerometer;
        let mag: Vec<f64> = acc.iter().map(|a| a.norm()).collect();
        let smooth: Vec<f64> = (0..mag.len())
            .map(|i| {
                let lo = i.saturating_sub(2);
                let hi = (i + 3).min(mag.len());
                mag[lo..hi].iter().sum::<f64>() / (hi - lo) as f64
            })
            .collect();
        let mut last = i64::MIN / 2;
        let mut steps_t = Vec::new();
        for i in 1..smooth.len().saturating_sub(1) {
            if smooth[i] > 10.8
                && smooth[i] >= smooth[i - 1]
                && smooth[i] > smooth[i + 1]
                && acc[i].t - last > 300
            {
                steps_t.push(acc[i].t);
                last = acc[i].t;
            }
        }
        detected_steps += steps_t.len();
        true_steps += w.truth.steps.len();
        // PDR with true lengths and rotation-vector heading: drift at the end.
        let rv = &w.walk.imu.rotation_vector;
        let mut p = w.truth.position_at(w.truth.start_ms).unwrap();
        for st in &w.truth.steps {
            let k = rv.partition_point(|r| r.t <= st.t).min(rv.len() - 1);
            let [qw, qx, qy, qz] = rv[k].quaternion();
            // Azimuth of the phone's y axis in ENU: atan2(R01, R11).
            let r01 = 2.0 * (qx * qy - qw * qz);
            let r11 = 1.0 - 2.0 * (qx * qx + qz * qz);
            p += angle::step_displacement(st.length, r01.atan2(r11));
        }
        end_drift.push((p - w.truth.position_at(w.truth.end_ms).unwrap()).norm());
    }
    let mut turn_angles: Vec<f64> = sim
        .walks
        .iter()
        .flat_map(|w| w.truth.turns.iter().map(|t| t.angle.abs().to_degrees()))
        .collect();
    let turn_count = turn_angles.len();
    println!(
        "turns: {turn_count}, |angle| min {:.0} deg, median {:.0}, max {:.0}",
        percentile(&mut turn_angles, 0.0),
        percentile(&mut turn_angles, 0.5),
        percentile(&mut turn_angles, 1.0)
    );
    let n = normal.len();
    let age_label = if max_age_ms == i64::MAX {
        "all entries".to_string()
    } else {
        format!("entries at most {max_age_ms} ms old")
    };
    let mean = normal.iter().sum::<f64>() / n as f64;
    println!(
        "Wi-Fi WKNN (k = 5, {age_label}): {n} scans, mean {mean:.2} m, p50 {:.2}, p95 {:.2}",
        percentile(&mut normal, 0.5),
        percentile(&mut normal, 0.95)
    );
    println!(
        "gross-error scans: {}, median error {:.1} m",
        gross.len(),
        percentile(&mut gross, 0.5)
    );
    let over2 = ages.iter().filter(|&&a| a > 2.0).count() as f64 / ages.len() as f64;
    println!(
        "entries per scan: median {:.0}; entry age median {:.2} s, {:.0} % over 2 s, max {:.1} s",
        percentile(&mut counts, 0.5),
        percentile(&mut ages, 0.5),
        over2 * 100.0,
        percentile(&mut ages, 1.0)
    );
    println!("steps: true {true_steps}, naive peak counter {detected_steps}");
    println!(
        "PDR with true step lengths and rotation-vector heading, end drift: median {:.2} m, max {:.2} m",
        percentile(&mut end_drift, 0.5),
        percentile(&mut end_drift, 1.0)
    );
}
