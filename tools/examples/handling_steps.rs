//! How many detected steps each handling gate rejects, before and after a walk's first
//! ground-truth point (docs/experiments.md, handling gate): runs the PDR with the gate
//! off over every walk given, feeds each variant's `HandlingGate` the same gyroscope stream,
//! and asks each at every step whether it would reject it. Also the dominant-axis share of
//! the rotation at the steps above 1.5 rad/s (10th / 50th / 90th percentile).
//!
//!     cargo run --release -p wipdr --example handling_steps -- $WIPDR_DATA/ipin2023/trials/*.gz
//!     cargo run --release -p wipdr --example handling_steps -- $WIPDR_DATA/ilc20/site*/F*/path_data_files/*
use std::collections::BTreeMap;
use wipdr_pdr::handling::{HandlingConfig, HandlingGate};
use wipdr_pdr::{Pdr, PdrConfig};

fn main() {
    let default = HandlingConfig::default();
    let old = HandlingConfig {
        tumbling_rad_s: None,
        ..default
    };
    let variants = [
        ("single 3.0 (sessions 9-18)", old),
        (
            "single 1.5",
            HandlingConfig {
                max_rotation_rad_s: Some(1.5),
                ..old
            },
        ),
        (
            "3.0 / release 1.5, no hold",
            HandlingConfig {
                release_rad_s: Some(1.5),
                release_hold_s: 1e9,
                ..old
            },
        ),
        ("default (tumbling test)", default),
    ];
    let pdr_cfg = PdrConfig {
        handling: HandlingConfig::off(),
        ..PdrConfig::default()
    };
    // phase -> (steps, rejected per variant, shares above 1.5 rad/s)
    let mut tally: BTreeMap<&str, (usize, Vec<usize>, Vec<f64>)> = BTreeMap::new();
    let mut skipped = 0;
    for path in std::env::args().skip(1) {
        let walk = match wipdr_io::any::read_walk_file(&path, &Default::default()) {
            Ok(p) => p.walk,
            Err(e) => {
                eprintln!("skipped {path}: {e}");
                skipped += 1;
                continue;
            }
        };
        let Some(first) = walk.waypoints.first().map(|w| w.t) else {
            skipped += 1;
            continue;
        };
        let (steps, _) = Pdr::run_detailed(pdr_cfg.check().unwrap(), &walk);
        let gyro = &walk.imu.gyroscope;
        let mut gates = vec![HandlingGate::default(); variants.len()];
        let mut next = 0;
        for s in &steps {
            while next < gyro.len() && gyro[next].t <= s.event.t {
                for (gate, (_, cfg)) in gates.iter_mut().zip(&variants) {
                    gate.push_vector(gyro[next].t, gyro[next].v, cfg);
                }
                next += 1;
            }
            let phase = if s.event.t < first { "before" } else { "after" };
            let entry = tally
                .entry(phase)
                .or_insert_with(|| (0, vec![0; variants.len()], Vec::new()));
            entry.0 += 1;
            for (k, (gate, (_, cfg))) in gates.iter().zip(&variants).enumerate() {
                entry.1[k] += usize::from(gate.handling(cfg));
            }
            let probe = &gates[variants.len() - 1];
            if probe.rate().is_some_and(|r| r > 1.5) {
                entry.2.push(probe.axis_share());
            }
        }
    }
    println!("walks skipped (unreadable or without ground truth): {skipped}");
    for (phase, (steps, rejected, mut shares)) in tally {
        println!("steps {phase} the first ground-truth point: {steps}");
        for ((name, _), n) in variants.iter().zip(rejected) {
            println!("  rejected by {name:28} {n}");
        }
        shares.sort_by(f64::total_cmp);
        let at = |q: f64| {
            let i = ((shares.len() as f64 - 1.0) * q).round();
            shares.get(i.max(0.0) as usize).copied().unwrap_or(f64::NAN)
        };
        println!(
            "  dominant-axis share above 1.5 rad/s ({} steps): p10 {:.2}, p50 {:.2}, p90 {:.2}",
            shares.len(),
            at(0.1),
            at(0.5),
            at(0.9)
        );
    }
}
