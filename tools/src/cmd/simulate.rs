//! `wipdr simulate`: a synthetic floor with walks, truth and a survey radio map, reproducible
//! from a seed (see the `wipdr-sim` crate for the models and the output layout).

use anyhow::Context;
use std::path::PathBuf;
use wipdr_sim::{SimConfig, generate, write};

/// Arguments of `wipdr simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output folder; the floor is written to `OUT/<floor name>/`.
    #[arg(long)]
    pub out: PathBuf,
    /// Seed of every random draw: the same seed and config give byte-identical files.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Number of walks (overrides the config).
    #[arg(long)]
    pub walks: Option<usize>,
    /// Mean walk duration in seconds (overrides the config).
    #[arg(long = "duration-s")]
    pub duration_s: Option<f64>,
    /// Probability that a Wi-Fi scan is replaced by a gross error (overrides the config).
    #[arg(long = "gross-error-rate")]
    pub gross_error_rate: Option<f64>,
    /// A TOML file with `SimConfig` fields (any subset; the rest keep their defaults).
    #[arg(long)]
    pub config: Option<PathBuf>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut cfg = match &args.config {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading {}", path.display()))?;
            toml::from_str::<SimConfig>(&text)
                .with_context(|| format!("parsing {}", path.display()))?
        }
        None => SimConfig::default(),
    };
    if let Some(n) = args.walks {
        cfg.walks = n;
    }
    if let Some(d) = args.duration_s {
        cfg.duration_s = d;
        cfg.duration_jitter_s = cfg.duration_jitter_s.min(d / 3.0);
    }
    if let Some(r) = args.gross_error_rate {
        cfg.gross_error_rate = r;
    }
    let sim = generate(&cfg, args.seed).context("generating the synthetic floor")?;
    let dir = write::write_floor(&sim, &args.out)
        .with_context(|| format!("writing under {}", args.out.display()))?;
    let steps: usize = sim.walks.iter().map(|w| w.truth.steps.len()).sum();
    let scans: usize = sim.walks.iter().map(|w| w.walk.wifi.len()).sum();
    let gross: usize = sim.walks.iter().map(|w| w.truth.gross_errors.len()).sum();
    let seconds: f64 = sim
        .walks
        .iter()
        .map(|w| (w.truth.end_ms - w.truth.start_ms) as f64 / 1000.0)
        .sum();
    println!(
        "wrote {}: {} walks ({:.0} s, {} steps, {} scans, {} injected gross errors), {} BSSIDs, survey {} train / {} test points (seed {})",
        dir.display(),
        sim.walks.len(),
        seconds,
        steps,
        scans,
        gross,
        sim.world.radio.access_points.len(),
        sim.survey.train.len(),
        sim.survey.test.len(),
        args.seed
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn files(dir: &std::path::Path) -> Vec<(PathBuf, Vec<u8>)> {
        let mut out = Vec::new();
        let mut stack = vec![dir.to_path_buf()];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    stack.push(p);
                } else {
                    let bytes = std::fs::read(&p).unwrap();
                    out.push((p.strip_prefix(dir).unwrap().to_path_buf(), bytes));
                }
            }
        }
        out.sort();
        out
    }

    fn args(out: PathBuf, config: Option<PathBuf>) -> Args {
        Args {
            out,
            seed: 9,
            walks: Some(2),
            duration_s: Some(30.0),
            gross_error_rate: Some(0.1),
            config,
        }
    }

    #[test]
    fn same_seed_writes_byte_identical_files() {
        let tmp = tempfile::tempdir().unwrap();
        let config = tmp.path().join("sim.toml");
        std::fs::write(&config, "[survey]\nspacing_m = 8.0\ntest_points = 5\n").unwrap();
        let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
        run(args(a.clone(), Some(config.clone()))).unwrap();
        run(args(b.clone(), Some(config))).unwrap();
        let (fa, fb) = (files(&a), files(&b));
        assert!(
            fa.iter()
                .any(|(p, _)| p.ends_with("F1/path_data_files/sim_F1_w0001.txt.gz"))
        );
        assert!(fa.iter().any(|(p, _)| p.ends_with("F1/survey/train.csv")));
        assert_eq!(fa, fb);
    }

    #[test]
    fn a_bad_config_is_an_error_naming_the_file() {
        let tmp = tempfile::tempdir().unwrap();
        let config = tmp.path().join("bad.toml");
        std::fs::write(&config, "no_such_field = 1\n").unwrap();
        let err = run(args(tmp.path().join("out"), Some(config))).unwrap_err();
        assert!(format!("{err:#}").contains("bad.toml"), "{err:#}");
    }
}
