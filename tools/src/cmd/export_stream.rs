//! `wipdr export-stream`: a recorded walk (ILC trace or IPIN logfile) written as a plain
//! sample stream (`wipdr_io::sample_stream`: `t_ms,sensor,a,b,c,d`), the format a user's own
//! logger can write and `wipdr locate --model` reads.
//!
//! ```text
//! wipdr export-stream fixtures/sim/F1/path_data_files/sim_F1_w0000.txt.gz --out w0000.csv
//! ```

use anyhow::{Context, Result};
use std::io::Write;
use std::path::PathBuf;

/// Arguments of `wipdr export-stream`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The walk file (ILC trace or IPIN logfile).
    pub walk: PathBuf,
    /// The CSV to write (`.csv`; gzipped when it ends in `.gz`).
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    let parsed = wipdr_io::any::read_walk_file(&args.walk, &wipdr_io::Limits::default())
        .with_context(|| format!("reading {}", args.walk.display()))?;
    let file = std::fs::File::create(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let gz = args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"));
    let mut out: Box<dyn Write> = if gz {
        Box::new(flate2::write::GzEncoder::new(
            std::io::BufWriter::new(file),
            flate2::Compression::best(),
        ))
    } else {
        Box::new(std::io::BufWriter::new(file))
    };
    wipdr_io::sample_stream::write_csv(&parsed.walk, &mut out)
        .and_then(|()| out.flush())
        .with_context(|| format!("writing {}", args.out.display()))?;
    drop(out);
    eprintln!(
        "{} -> {} ({} scans, {} accelerometer samples)",
        args.walk.display(),
        args.out.display(),
        parsed.walk.wifi.len(),
        parsed.walk.imu.accelerometer.len()
    );
    Ok(())
}
