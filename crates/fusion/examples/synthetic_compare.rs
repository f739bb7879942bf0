//! Compares every fusion scheme on seeded synthetic walks with injected Wi-Fi gross errors and
//! prints markdown tables (the source of `docs/results/fusion-synthetic.md`).
//!
//! ```text
//! cargo run --release -p wipdr-fusion --example synthetic_compare [-- WALKS]
//! ```

use wipdr_core::stats::ErrorStats;
use wipdr_fusion::synthetic::{SyntheticConfig, SyntheticWalk};
use wipdr_fusion::{EkfConfig, PfConfig, SchemeConfig, scheme_names};

struct Variant {
    label: String,
    config: SchemeConfig,
    start_at_truth: bool,
}

fn variants() -> Vec<Variant> {
    let mut v: Vec<Variant> = scheme_names()
        .iter()
        .map(|name| Variant {
            label: name.to_string(),
            config: SchemeConfig::default_for(name).expect("known name"),
            start_at_truth: *name == "pdr",
        })
        .collect();
    // The EKF family with R matched to the synthetic Wi-Fi noise (3 m per axis).
    let matched = EkfConfig {
        r_wifi_m2: 9.0,
        ..EkfConfig::default()
    };
    for (name, cfg) in [
        ("ekf", SchemeConfig::Ekf(matched.clone())),
        ("aekf", SchemeConfig::Aekf(matched.clone())),
        ("akf", SchemeConfig::Akf(matched.clone())),
        ("rkf", SchemeConfig::Rkf(matched.clone())),
        ("arkf", SchemeConfig::Arkf(matched.clone())),
    ] {
        v.push(Variant {
            label: format!("{name} (R = 3² m²)"),
            config: cfg,
            start_at_truth: false,
        });
    }
    let pf_matched = PfConfig {
        wifi_sd_m: 3.0,
        ..PfConfig::default()
    };
    v.push(Variant {
        label: "pf (sd = 3 m)".into(),
        config: SchemeConfig::Pf(pf_matched.clone()),
        start_at_truth: false,
    });
    v.push(Variant {
        label: "apf (sd = 3 m)".into(),
        config: SchemeConfig::Apf(pf_matched),
        start_at_truth: false,
    });
    for (label, walls, adaptive) in [
        ("apf (walls only)", true, false),
        ("apf (adaptive factor only)", false, true),
    ] {
        v.push(Variant {
            label: label.into(),
            config: SchemeConfig::Apf(PfConfig {
                use_walls: walls,
                use_adaptive_factor: adaptive,
                ..PfConfig::default()
            }),
            start_at_truth: false,
        });
    }
    v
}

fn main() {
    let walks: u64 = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(20);
    for (title, first_fix_gross) in [
        ("Synthetic walks, first fix correct", false),
        (
            "Synthetic walks starting from a gross first fix (a start in a coverage gap)",
            true,
        ),
    ] {
        let generated: Vec<SyntheticWalk> = (1..=walks)
            .map(|seed| {
                SyntheticWalk::generate(&SyntheticConfig {
                    seed,
                    first_fix_gross,
                    ..SyntheticConfig::default()
                })
            })
            .collect();
        let fixes: usize = generated.iter().map(|w| w.wifi.len()).sum();
        let gross: usize = generated
            .iter()
            .map(|w| w.gross.iter().filter(|g| **g).count())
            .sum();
        println!("## {title}\n");
        println!(
            "{walks} walks (seeds 1-{walks}), {} steps, {fixes} Wi-Fi fixes of which {gross} gross. \
             Errors after every step, pooled.\n",
            generated.iter().map(|w| w.steps.len()).sum::<usize>()
        );
        println!(
            "| scheme | mean (m) | RMS (m) | p50 | p95 | max | gross flagged | false alarms | re-inits |"
        );
        println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- |");
        for v in variants() {
            let mut errors = vec![];
            let (mut tp, mut fp, mut pos, mut neg, mut reinit) = (0usize, 0usize, 0, 0, 0u32);
            let mut says = false;
            for (k, walk) in generated.iter().enumerate() {
                let start = v.start_at_truth.then_some(walk.start);
                let r = walk
                    .run(&v.config, k as u64 + 1, start)
                    .expect("valid config");
                errors.extend(r.step_errors);
                reinit += r.reinitialisations;
                // the first fix initialises: not scored
                for (j, f) in r.flagged.iter().enumerate().skip(1) {
                    if let Some(f) = f {
                        says = true;
                        if walk.gross[j] {
                            pos += 1;
                            tp += usize::from(*f);
                        } else {
                            neg += 1;
                            fp += usize::from(*f);
                        }
                    }
                }
            }
            let s = ErrorStats::from_errors(&errors);
            let (det, fa) = if says && pos > 0 && neg > 0 {
                (
                    format!("{:.1} % ({tp}/{pos})", 100.0 * tp as f64 / pos as f64),
                    format!("{:.1} % ({fp}/{neg})", 100.0 * fp as f64 / neg as f64),
                )
            } else {
                ("—".into(), "—".into())
            };
            println!(
                "| {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} | {det} | {fa} | {reinit} |",
                v.label, s.mean, s.rms, s.p50, s.p95, s.max
            );
        }
        println!();
    }
}
