//! `odometry-train`: the learned odometry's dataset extraction, training (candle, CPU),
//! leave-one-floor-out evaluation and test fixture. See README.md.

mod data;
mod eval;
mod train;

use anyhow::{Context, Result, bail};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;
use train::TrainConfig;
use wipdr_pdr::odometry::LearnedOdometry;
use wipdr_pdr::odometry::features::{CHANNELS, WINDOW};

const USAGE: &str = "usage: odometry-train <extract|steps|steps-nosnap|lofo|score|ship|bench> [--data DIR] [--cache DIR] [--epochs N] [--mse-epochs N] [--batch N] [--lr X] [--seed N] [--channels A,B,C] [--strides A,B,C] [--kernel N] [--hidden N] [--mirror BOOL] [--pretrain-epochs N] [--pretrain-batch N] [--pretrain-lr X] [--dense-weight X] [--dense-truth BOOL] [--swa-epochs N] [--out FILE] [--fixture FILE] [--holdout FLOOR] [--models DIR]";

struct Args {
    cmd: String,
    data: PathBuf,
    cache: PathBuf,
    out: Option<PathBuf>,
    fixture: Option<PathBuf>,
    holdout: Option<String>,
    models: Option<PathBuf>,
    cfg: TrainConfig,
}

fn parse() -> Result<Args> {
    let mut it = std::env::args().skip(1);
    let cmd = it.next().context(USAGE)?;
    let mut a = Args {
        cmd,
        data: wipdr_io::data_root().join("ilc20"),
        cache: PathBuf::from("/work/odometry-cache"),
        out: None,
        fixture: None,
        holdout: None,
        models: None,
        cfg: TrainConfig::default(),
    };
    while let Some(k) = it.next() {
        let v = it.next().with_context(|| format!("{k} needs a value"))?;
        match k.as_str() {
            "--data" => a.data = v.into(),
            "--cache" => a.cache = v.into(),
            "--out" => a.out = Some(v.into()),
            "--fixture" => a.fixture = Some(v.into()),
            "--holdout" => a.holdout = Some(v),
            "--models" => a.models = Some(v.into()),
            "--epochs" => a.cfg.epochs = v.parse()?,
            "--mse-epochs" => a.cfg.mse_epochs = v.parse()?,
            "--seed" => a.cfg.seed = v.parse()?,
            "--lr" => a.cfg.lr = v.parse()?,
            "--batch" => a.cfg.batch = v.parse()?,
            "--channels" => {
                a.cfg.channels = v.split(',').map(str::parse).collect::<Result<_, _>>()?
            }
            "--strides" => {
                a.cfg.strides = v.split(',').map(str::parse).collect::<Result<_, _>>()?
            }
            "--hidden" => a.cfg.hidden = v.parse()?,
            "--mirror" => a.cfg.mirror = v.parse()?,
            "--kernel" => a.cfg.kernel = v.parse()?,
            "--pretrain-epochs" => a.cfg.pretrain_epochs = v.parse()?,
            "--pretrain-batch" => a.cfg.pretrain_batch = v.parse()?,
            "--pretrain-lr" => a.cfg.pretrain_lr = v.parse()?,
            "--dense-weight" => a.cfg.dense_weight = v.parse()?,
            "--dense-truth" => a.cfg.dense_truth = v.parse()?,
            "--swa-epochs" => a.cfg.swa_epochs = v.parse()?,
            _ => bail!("unknown option {k}\n{USAGE}"),
        }
    }
    if a.cfg.channels.len() != a.cfg.strides.len() {
        bail!("--channels and --strides differ in length");
    }
    Ok(a)
}

fn dataset_path(a: &Args) -> PathBuf {
    a.cache.join("ilc-dataset.bin")
}

/// The folder of the leave-one-floor-out models (`--models`, default `CACHE/lofo`).
fn models_dir(a: &Args) -> PathBuf {
    a.models.clone().unwrap_or_else(|| a.cache.join("lofo"))
}

fn metadata(a: &Args, hash: &str, floors: &[String], secs: f64) -> BTreeMap<String, String> {
    let c = &a.cfg;
    BTreeMap::from([
        (
            "command".into(),
            std::env::args().collect::<Vec<_>>().join(" "),
        ),
        ("data_sha256".into(), hash.to_string()),
        ("train_floors".into(), floors.join(",")),
        ("train_seconds".into(), format!("{secs:.1}")),
        ("seed".into(), c.seed.to_string()),
        (
            "epochs".into(),
            format!("{} ({} mse)", c.epochs, c.mse_epochs),
        ),
        ("channels".into(), format!("{:?}", c.channels)),
        ("hidden".into(), c.hidden.to_string()),
        ("kernel".into(), c.kernel.to_string()),
        ("batch".into(), c.batch.to_string()),
        ("lr".into(), c.lr.to_string()),
        ("mirror".into(), c.mirror.to_string()),
        (
            "pretrain".into(),
            format!(
                "{} epochs, batch {}, lr {}",
                c.pretrain_epochs, c.pretrain_batch, c.pretrain_lr
            ),
        ),
        ("dense_weight".into(), c.dense_weight.to_string()),
        ("dense_truth".into(), c.dense_truth.to_string()),
        ("swa_epochs".into(), c.swa_epochs.to_string()),
    ])
}

fn main() -> Result<()> {
    let a = parse()?;
    std::fs::create_dir_all(&a.cache)?;
    match a.cmd.as_str() {
        "extract" => {
            let t = Instant::now();
            let ds = data::extract(&a.data, &a.cache, true)?;
            let hash = data::save(&ds, &dataset_path(&a))?;
            eprintln!(
                "{} walks, {:.1} s; sha256 {hash}",
                ds.walks.len(),
                t.elapsed().as_secs_f64()
            );
        }
        "steps-nosnap" => {
            // a diagnostic, nothing written: the step model with heading snapping off (the
            // evaluation has it on) against the same model with it on, on the segments
            let on = data::load(&dataset_path(&a))?.0;
            let off = data::extract(&a.data, &a.cache, false)?;
            for (name, ds) in [("snapping on", &on), ("snapping off", &off)] {
                let (mut e, mut dir) = (Vec::new(), Vec::new());
                for s in ds.walks.iter().flat_map(|w| &w.segments) {
                    e.push((s.truth[0] - s.steps[0]).hypot(s.truth[1] - s.steps[1]));
                    if s.truth[0].hypot(s.truth[1]) >= 2.0 {
                        dir.push(eval::dir_err(s.steps, s.truth));
                    }
                }
                println!(
                    "steps, {name}: {} segments, mean {:.3} median {:.3} | |direction err| {:.1} deg (segments >= 2 m)",
                    e.len(),
                    eval::mean(&e),
                    eval::median(&e),
                    eval::mean(&dir)
                );
            }
        }
        "score" => {
            // re-score the models `lofo` saved, without training
            let (ds, hash) = data::load(&dataset_path(&a))?;
            println!("dataset sha256 {hash}");
            let mut pooled = eval::Scores::default();
            for f in &ds.floors {
                let path = models_dir(&a).join(format!("{}.safetensors", f.replace('/', "_")));
                let model = LearnedOdometry::from_safetensors(
                    &std::fs::read(&path).with_context(|| format!("{}", path.display()))?,
                )?;
                let mut s = eval::Scores::default();
                for w in ds.walks.iter().filter(|w| &w.floor == f) {
                    s.add(&model, w)?;
                }
                println!("{f}: {}", s.summary());
                let js = models_dir(&a).join(format!("vectors_{}.json", f.replace('/', "_")));
                std::fs::write(&js, serde_json::to_vec(&s.vectors)?)?;
                pooled.extend(&s);
            }
            println!("pooled: {}", pooled.summary());
        }
        "bench" => {
            // the library's forward pass on the cached windows of every walk, one thread
            let (ds, _) = data::load(&dataset_path(&a))?;
            let model = LearnedOdometry::shipped()?;
            let per = CHANNELS * WINDOW;
            let n: usize = ds.walks.iter().map(|w| w.t_end.len()).sum();
            let t = Instant::now();
            let mut check = 0.0f64;
            for w in &ds.walks {
                for x in w.data.chunks_exact(per) {
                    check += f64::from(model.network().forward(x)?[0]);
                }
            }
            let secs = t.elapsed().as_secs_f64();
            println!(
                "{n} windows (one a second of walk) in {secs:.2} s: {:.1} us a window, {:.0}x real time for the network alone (checksum {check:.3})",
                1e6 * secs / n as f64,
                n as f64 / secs
            );
        }
        "steps" => {
            // the step model on the dataset's segments (no network)
            let (ds, hash) = data::load(&dataset_path(&a))?;
            println!("dataset sha256 {hash}");
            for f in &ds.floors {
                let s: Vec<f64> = ds
                    .walks
                    .iter()
                    .filter(|w| &w.floor == f)
                    .flat_map(|w| {
                        w.segments
                            .iter()
                            .map(|s| (s.truth[0] - s.steps[0]).hypot(s.truth[1] - s.steps[1]))
                    })
                    .collect();
                println!(
                    "{f}: {} segments, steps mean {:.3} median {:.3}",
                    s.len(),
                    eval::mean(&s),
                    eval::median(&s)
                );
            }
            let s: Vec<f64> = ds
                .walks
                .iter()
                .flat_map(|w| {
                    w.segments
                        .iter()
                        .map(|s| (s.truth[0] - s.steps[0]).hypot(s.truth[1] - s.steps[1]))
                })
                .collect();
            let mse = s.iter().map(|e| e * e).sum::<f64>() / s.len() as f64;
            // the dense labels summed over each segment (each window weighted by its overlap,
            // as the network's outputs) against the segment's step displacement and truth:
            // a check of their frame and offset
            let (mut to_steps, mut to_truth, mut track_to_truth) =
                (Vec::new(), Vec::new(), Vec::new());
            let mut covered = 0usize;
            for w in &ds.walks {
                let track = data::truth_dense(w);
                covered += track.iter().flatten().count();
                let sum = |labels: &dyn Fn(usize) -> Option<[f32; 2]>, sg: &data::Segment| {
                    let mut d = [0.0f64; 2];
                    for (k, &t) in w.t_end.iter().enumerate() {
                        let f = wipdr_pdr::odometry::overlap_fraction(t, sg.t_a, sg.t_b);
                        if f > 0.0 {
                            let l = labels(k)?;
                            let (x, _) = wipdr_pdr::odometry::features::local_to_world(
                                w.heading[k],
                                [f64::from(l[0]), f64::from(l[1])],
                                [0.0; 2],
                            );
                            d = [d[0] + f * x[0], d[1] + f * x[1]];
                        }
                    }
                    Some(wipdr_pdr::odometry::rotate_heading(d, w.offset_floor))
                };
                for sg in &w.segments {
                    if let Some(d) = sum(&|k| Some(w.dense[k]), sg) {
                        to_steps.push((d[0] - sg.steps[0]).hypot(d[1] - sg.steps[1]));
                        to_truth.push((d[0] - sg.truth[0]).hypot(d[1] - sg.truth[1]));
                    }
                    if let Some(d) = sum(&|k| track[k], sg) {
                        track_to_truth.push((d[0] - sg.truth[0]).hypot(d[1] - sg.truth[1]));
                    }
                }
            }
            let nd: usize = ds.walks.iter().map(|w| w.dense.len()).sum();
            let speed = ds
                .walks
                .iter()
                .flat_map(|w| {
                    w.dense
                        .iter()
                        .map(|d| f64::from(d[0]).hypot(f64::from(d[1])))
                })
                .sum::<f64>()
                / nd as f64;
            println!(
                "dense labels: {nd} windows, mean {speed:.3} m a second; summed over the segments: {:.3} m mean from the segments' steps, {:.3} m mean from the truth",
                eval::mean(&to_steps),
                eval::mean(&to_truth)
            );
            println!(
                "waypoint-track labels (--dense-truth): {covered} windows inside the waypoints' span; summed over {} segments: {:.3} m mean from the truth",
                track_to_truth.len(),
                eval::mean(&track_to_truth)
            );
            println!(
                "pooled: {} segments, steps mean {:.3} median {:.3}, mean squared error {mse:.3} m² (the unit of the training's MSE loss)",
                s.len(),
                eval::mean(&s),
                eval::median(&s)
            );
        }
        "lofo" => {
            let (ds, hash) = data::load(&dataset_path(&a))?;
            println!("dataset sha256 {hash}");
            let out_dir = models_dir(&a);
            std::fs::create_dir_all(&out_dir)?;
            let mut pooled = eval::Scores::default();
            let floors: Vec<String> = match &a.holdout {
                Some(h) => vec![h.clone()],
                None => ds.floors.clone(),
            };
            for f in &floors {
                let train: Vec<_> = ds.walks.iter().filter(|w| &w.floor != f).collect();
                let test: Vec<_> = ds.walks.iter().filter(|w| &w.floor == f).collect();
                let train_floors: Vec<String> =
                    ds.floors.iter().filter(|x| *x != f).cloned().collect();
                eprintln!(
                    "hold out {f}: {} training walks, {} test walks",
                    train.len(),
                    test.len()
                );
                let t = Instant::now();
                let (vm, loss) = train::train(&train, &a.cfg)?;
                let secs = t.elapsed().as_secs_f64();
                let path = out_dir.join(format!("{}.safetensors", f.replace('/', "_")));
                train::save_safetensors(
                    &vm,
                    &a.cfg,
                    metadata(&a, &hash, &train_floors, secs),
                    &path,
                )?;
                let model = LearnedOdometry::from_safetensors(&std::fs::read(&path)?)?;
                let mut tr = eval::Scores::default();
                for w in &train {
                    tr.add(&model, w)?;
                }
                eprintln!(
                    "  training floors (in-sample): learned mean {:.3}, steps mean {:.3}",
                    eval::mean(&tr.learned),
                    eval::mean(&tr.steps)
                );
                let mut s = eval::Scores::default();
                for w in &test {
                    s.add(&model, w)?;
                }
                println!(
                    "{f} (trained {secs:.0} s, final loss {loss:.3}): {}",
                    s.summary()
                );
                pooled.extend(&s);
            }
            println!("pooled: {}", pooled.summary());
            let js = out_dir.join("scores.json");
            std::fs::write(&js, serde_json::to_vec(&pooled)?)?;
        }
        "ship" | "fixture" => {
            let (ds, hash) = data::load(&dataset_path(&a))?;
            let all: Vec<_> = ds.walks.iter().collect();
            let t = Instant::now();
            let (vm, loss) = train::train(&all, &a.cfg)?;
            let secs = t.elapsed().as_secs_f64();
            let out = a.out.clone().context("--out FILE needed")?;
            train::save_safetensors(&vm, &a.cfg, metadata(&a, &hash, &ds.floors, secs), &out)?;
            println!(
                "trained on {} walks in {secs:.1} s, final loss {loss:.4}: {}",
                all.len(),
                out.display()
            );
            // the fixture: windows from the first walk of each floor, candle's raw outputs
            let per = CHANNELS * WINDOW;
            let mut windows = Vec::new();
            for f in &ds.floors {
                if let Some(w) = ds.walks.iter().find(|w| &w.floor == f) {
                    for k in [0usize, w.t_end.len() / 2] {
                        if k < w.t_end.len() {
                            windows.extend_from_slice(&w.data[k * per..(k + 1) * per]);
                        }
                    }
                }
            }
            let expected = train::candle_outputs(&vm, &a.cfg, &windows)?;
            let fixture = a
                .fixture
                .clone()
                .unwrap_or_else(|| out.with_extension("fixture.json"));
            let js = serde_json::json!({
                "about": "Windows (CHANNELS x WINDOW, channel-major) of ILC walks and the candle network's raw outputs for the weights beside this file; written by tools/odometry-train",
                "channels": CHANNELS,
                "window": WINDOW,
                "windows": windows,
                "expected": expected,
            });
            std::fs::write(&fixture, serde_json::to_vec(&js)?)?;
            println!("fixture {}", fixture.display());
        }
        _ => bail!("{USAGE}"),
    }
    Ok(())
}
