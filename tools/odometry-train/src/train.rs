//! Training with candle (CPU): a 1D CNN over the windows, its outputs integrated over each
//! waypoint segment (each second weighted by its overlap with the segment), MSE for the
//! first epochs and then the Gaussian negative log-likelihood of the segment displacement
//! under the summed learned covariance.

use crate::data::{WalkRec, label_rv, truth_dense};
use anyhow::{Result, bail};
use candle_core::{D, DType, Device, Tensor, Var};
use candle_nn::{Conv1d, Conv1dConfig, Linear, Module, Optimizer, VarBuilder, VarMap};
use std::collections::BTreeMap;
use wipdr_pdr::odometry::features::{CHANNELS, WINDOW};
use wipdr_pdr::odometry::model::{INPUT_SCALE, OUTPUTS};
use wipdr_pdr::odometry::{LOG_VAR_RANGE, overlap_fraction};

/// Training settings.
#[derive(Debug, Clone)]
pub struct TrainConfig {
    /// Seed of the weight initialisation and the batch order.
    pub seed: u64,
    /// Epochs.
    pub epochs: usize,
    /// Epochs of MSE before the NLL.
    pub mse_epochs: usize,
    /// Segments per batch.
    pub batch: usize,
    /// Learning rate.
    pub lr: f64,
    /// Weight decay.
    pub weight_decay: f64,
    /// Channels of the convolutions.
    pub channels: Vec<usize>,
    /// Strides of the convolutions.
    pub strides: Vec<usize>,
    /// Kernel size.
    pub kernel: usize,
    /// Hidden width of the dense head.
    pub hidden: usize,
    /// Mirror half of the batches left-right (augmentation).
    pub mirror: bool,
    /// Epochs of pretraining on every window with the step model's dense labels (MSE on the
    /// displacement outputs), before the segment epochs.
    pub pretrain_epochs: usize,
    /// Windows per pretraining batch.
    pub pretrain_batch: usize,
    /// Learning rate of the pretraining (cosine decay over its epochs).
    pub pretrain_lr: f64,
    /// Weight of the dense-label MSE (on the batch's windows) added to the segment loss.
    pub dense_weight: f64,
    /// Dense labels from the waypoint track (linear between waypoints) where the window's
    /// interval lies inside the waypoints' span, the step model's elsewhere.
    pub dense_truth: bool,
    /// The returned weights are the mean of the weights at the end of each of the last
    /// `swa_epochs` segment epochs (stochastic weight averaging; 0: the last epoch's).
    pub swa_epochs: usize,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            seed: 44,
            epochs: 25,
            mse_epochs: 8,
            batch: 16,
            lr: 2e-3,
            weight_decay: 1e-4,
            channels: vec![32, 64, 64],
            strides: vec![2, 2, 2],
            kernel: 5,
            hidden: 64,
            mirror: true,
            pretrain_epochs: 0,
            pretrain_batch: 64,
            pretrain_lr: 2e-3,
            dense_weight: 0.0,
            dense_truth: false,
            swa_epochs: 0,
        }
    }
}

/// SplitMix64: the seeded generator of initialisation and shuffling.
pub struct Rng(u64);

impl Rng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }
    /// Next 64 bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Fisher-Yates shuffle.
    pub fn shuffle<T>(&mut self, v: &mut [T]) {
        for i in (1..v.len()).rev() {
            let j = (self.next_u64() % (i as u64 + 1)) as usize;
            v.swap(i, j);
        }
    }
}

/// The network in candle, the same layers as `wipdr_pdr::odometry::model`.
pub struct Net {
    convs: Vec<Conv1d>,
    fcs: Vec<Linear>,
    scale: Tensor,
}

impl Net {
    /// Builds the layers on `vb`.
    pub fn new(cfg: &TrainConfig, vb: VarBuilder, dev: &Device) -> Result<Self> {
        let mut convs = Vec::new();
        let mut inp = CHANNELS;
        for (i, (&c, &s)) in cfg.channels.iter().zip(&cfg.strides).enumerate() {
            let cc = Conv1dConfig {
                padding: cfg.kernel / 2,
                stride: s,
                ..Default::default()
            };
            convs.push(candle_nn::conv1d(
                inp,
                c,
                cfg.kernel,
                cc,
                vb.pp(format!("conv{i}")),
            )?);
            inp = c;
        }
        let fcs = vec![
            candle_nn::linear(inp, cfg.hidden, vb.pp("fc0"))?,
            candle_nn::linear(cfg.hidden, OUTPUTS, vb.pp("fc1"))?,
        ];
        let scale: Vec<f32> = INPUT_SCALE.iter().map(|s| 1.0 / s).collect();
        let scale = Tensor::from_vec(scale, (1, CHANNELS, 1), dev)?;
        Ok(Self { convs, fcs, scale })
    }

    /// Raw outputs `[n, 4]` of windows `[n, CHANNELS, WINDOW]`.
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let mut h = x.broadcast_mul(&self.scale)?;
        for c in &self.convs {
            h = c.forward(&h)?.relu()?;
        }
        let mut h = h.mean(D::Minus1)?;
        let last = self.fcs.len() - 1;
        for (i, f) in self.fcs.iter().enumerate() {
            h = f.forward(&h)?;
            if i < last {
                h = h.relu()?;
            }
        }
        Ok(h)
    }
}

/// Re-initialises every variable from the seeded generator (candle's CPU generator cannot be
/// seeded): weights uniform in +-1/sqrt(fan_in) (PyTorch's default), biases the same.
pub fn init_seeded(varmap: &VarMap, seed: u64) -> Result<()> {
    let mut rng = Rng::new(seed);
    let data = varmap
        .data()
        .lock()
        .map_err(|_| anyhow::anyhow!("varmap lock"))?;
    let sorted: BTreeMap<&String, &Var> = data.iter().collect();
    let fan_in = |name: &str| -> usize {
        let w = name.replace(".bias", ".weight");
        data.get(&w)
            .map(|v| v.dims()[1..].iter().product())
            .unwrap_or(1)
    };
    for (name, var) in sorted {
        let n = var.elem_count();
        let bound = 1.0 / (fan_in(name) as f64).sqrt();
        let vals: Vec<f32> = (0..n)
            .map(|_| ((rng.uniform() * 2.0 - 1.0) * bound) as f32)
            .collect();
        var.set(&Tensor::from_vec(vals, var.dims(), var.device())?)?;
    }
    Ok(())
}

/// The windows of a segment: (window index, fraction of its interval inside the segment).
pub type SegmentWindows = Vec<(usize, f32)>;

/// The training set flattened: every window of the training walks, and every segment as
/// (label in the rotation vector frame, list of (window index, fraction)).
pub struct TrainSet {
    /// `[n, CHANNELS, WINDOW]` window data.
    pub data: Vec<f32>,
    /// Frame heading of each window.
    pub heading: Vec<f32>,
    /// The step model's displacement over each window's output interval, yawed frame.
    pub dense: Vec<[f32; 2]>,
    /// Segments.
    pub segments: Vec<([f32; 2], SegmentWindows)>,
}

impl TrainSet {
    /// The windows and segments of `walks` (`dense_truth`: see [`TrainConfig::dense_truth`]).
    pub fn of(walks: &[&WalkRec], dense_truth: bool) -> Self {
        let mut set = TrainSet {
            data: Vec::new(),
            heading: Vec::new(),
            dense: Vec::new(),
            segments: Vec::new(),
        };
        for w in walks {
            let base = set.heading.len();
            set.data.extend_from_slice(&w.data);
            set.heading.extend(w.heading.iter().map(|h| *h as f32));
            if dense_truth {
                let t = truth_dense(w);
                set.dense
                    .extend(w.dense.iter().zip(t).map(|(s, t)| t.unwrap_or(*s)));
            } else {
                set.dense.extend_from_slice(&w.dense);
            }
            for s in &w.segments {
                let parts: Vec<(usize, f32)> = w
                    .t_end
                    .iter()
                    .enumerate()
                    .filter_map(|(k, &t)| {
                        let f = overlap_fraction(t, s.t_a, s.t_b);
                        (f > 0.0).then_some((base + k, f as f32))
                    })
                    .collect();
                if !parts.is_empty() {
                    let l = label_rv(w, s);
                    set.segments.push(([l[0] as f32, l[1] as f32], parts));
                }
            }
        }
        set
    }
}

/// Left-right mirror of window data `[n, CHANNELS * WINDOW]` in place: the right
/// acceleration and the forward and up angular rates change sign.
fn mirror_windows(x: &mut [f32]) {
    let per = CHANNELS * WINDOW;
    for w in x.chunks_exact_mut(per) {
        for ch in [1usize, 3, 5] {
            for v in &mut w[ch * WINDOW..(ch + 1) * WINDOW] {
                *v = -*v;
            }
        }
    }
}

/// The cosine learning rate of `epoch` out of `epochs`, starting at `lr`.
fn cosine(lr: f64, epoch: usize, epochs: usize) -> f64 {
    lr * 0.5 * (1.0 + (std::f64::consts::PI * epoch as f64 / epochs as f64).cos())
}

/// The dense-label MSE: the displacement outputs `out[:, 0..2]` against `y` (`[n, 2]`, yawed
/// frame), summed over the two components, mean over windows.
fn dense_mse(out: &Tensor, y: &Tensor) -> Result<Tensor> {
    Ok((out.narrow(1, 0, 2)? - y)?.sqr()?.sum(1)?.mean_all()?)
}

/// AdamW over every variable of `varmap`.
fn adamw(varmap: &VarMap, lr: f64, weight_decay: f64) -> Result<candle_nn::AdamW> {
    Ok(candle_nn::AdamW::new(
        varmap.all_vars(),
        candle_nn::ParamsAdamW {
            lr,
            weight_decay,
            ..Default::default()
        },
    )?)
}

/// Pretraining on every window with the step model's dense labels (MSE), its own AdamW
/// and batch order (a generator of its own, so that the segment epochs' order does not
/// depend on it).
fn pretrain(net: &Net, varmap: &VarMap, set: &TrainSet, cfg: &TrainConfig) -> Result<()> {
    let dev = Device::Cpu;
    let mut opt = adamw(varmap, cfg.pretrain_lr, cfg.weight_decay)?;
    let mut rng = Rng::new(cfg.seed ^ 0xDE45_E000);
    let mut order: Vec<usize> = (0..set.dense.len()).collect();
    let per = CHANNELS * WINDOW;
    for epoch in 0..cfg.pretrain_epochs {
        let lr = cosine(cfg.pretrain_lr, epoch, cfg.pretrain_epochs);
        opt.set_learning_rate(lr);
        rng.shuffle(&mut order);
        let (mut sum, mut count) = (0.0, 0usize);
        for chunk in order.chunks(cfg.pretrain_batch) {
            let n = chunk.len();
            let mut x = Vec::with_capacity(n * per);
            let mut y = Vec::with_capacity(n * 2);
            for &k in chunk {
                x.extend_from_slice(&set.data[k * per..(k + 1) * per]);
                y.extend_from_slice(&set.dense[k]);
            }
            if cfg.mirror && rng.uniform() < 0.5 {
                mirror_windows(&mut x);
                for v in y.iter_mut().skip(1).step_by(2) {
                    *v = -*v;
                }
            }
            let x = Tensor::from_vec(x, (n, CHANNELS, WINDOW), &dev)?;
            let y = Tensor::from_vec(y, (n, 2), &dev)?;
            let loss = dense_mse(&net.forward(&x)?, &y)?;
            opt.backward_step(&loss)?;
            let l = f64::from(loss.to_scalar::<f32>()?);
            if !l.is_finite() {
                bail!("non-finite pretraining loss at epoch {epoch}");
            }
            sum += l * n as f64;
            count += n;
        }
        eprintln!(
            "  pretrain {epoch:>3} dense mse {:.4} m² a window, lr {lr:.2e}",
            sum / count as f64
        );
    }
    Ok(())
}

/// Trains a network on `walks`; returns the varmap and the final epoch's mean loss.
pub fn train(walks: &[&WalkRec], cfg: &TrainConfig) -> Result<(VarMap, f64)> {
    let dev = Device::Cpu;
    let set = TrainSet::of(walks, cfg.dense_truth);
    if set.segments.is_empty() {
        bail!("no training segments");
    }
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F32, &dev);
    let net = Net::new(cfg, vb, &dev)?;
    init_seeded(&varmap, cfg.seed)?;
    if cfg.pretrain_epochs > 0 {
        pretrain(&net, &varmap, &set, cfg)?;
    }
    let mut opt = adamw(&varmap, cfg.lr, cfg.weight_decay)?;
    let mut rng = Rng::new(cfg.seed ^ 0x5EED);
    let mut order: Vec<usize> = (0..set.segments.len()).collect();
    let mut last_loss = f64::NAN;
    let per = CHANNELS * WINDOW;
    let mut swa: Option<Vec<Tensor>> = None;
    for epoch in 0..cfg.epochs {
        let lr = cosine(cfg.lr, epoch, cfg.epochs);
        opt.set_learning_rate(lr);
        rng.shuffle(&mut order);
        let nll = epoch >= cfg.mse_epochs;
        let (mut sum, mut count, mut dense_sum) = (0.0, 0usize, 0.0);
        for chunk in order.chunks(cfg.batch) {
            // windows used by the batch, renumbered
            let mut local: BTreeMap<usize, usize> = BTreeMap::new();
            for &s in chunk {
                for &(k, _) in &set.segments[s].1 {
                    let n = local.len();
                    local.entry(k).or_insert(n);
                }
            }
            let nw = local.len();
            let mut x = vec![0f32; nw * per];
            let mut sin = vec![0f32; nw];
            let mut cos = vec![0f32; nw];
            let mut yd = vec![0f32; nw * 2];
            let mut mirrored = false;
            for (&k, &j) in &local {
                x[j * per..(j + 1) * per].copy_from_slice(&set.data[k * per..(k + 1) * per]);
                sin[j] = set.heading[k].sin();
                cos[j] = set.heading[k].cos();
                yd[2 * j..2 * j + 2].copy_from_slice(&set.dense[k]);
            }
            // left-right mirror of the whole batch: the right acceleration, the forward and
            // up angular rates, the frame heading, the label's east component and the dense
            // labels' right component change sign
            if cfg.mirror && rng.uniform() < 0.5 {
                mirror_windows(&mut x);
                for j in 0..nw {
                    sin[j] = -sin[j];
                    yd[2 * j + 1] = -yd[2 * j + 1];
                }
                mirrored = true;
            }
            let mut m = vec![0f32; chunk.len() * nw];
            let mut y = vec![0f32; chunk.len() * 2];
            for (r, &s) in chunk.iter().enumerate() {
                let (l, parts) = &set.segments[s];
                y[2 * r] = if mirrored { -l[0] } else { l[0] };
                y[2 * r + 1] = l[1];
                for &(k, f) in parts {
                    m[r * nw + local[&k]] += f;
                }
            }
            let x = Tensor::from_vec(x, (nw, CHANNELS, WINDOW), &dev)?;
            let sin = Tensor::from_vec(sin, (nw, 1), &dev)?;
            let cos = Tensor::from_vec(cos, (nw, 1), &dev)?;
            let m = Tensor::from_vec(m, (chunk.len(), nw), &dev)?;
            let y = Tensor::from_vec(y, (chunk.len(), 2), &dev)?;
            let out = net.forward(&x)?; // [nw, 4]
            let f = out.narrow(1, 0, 1)?;
            let r = out.narrow(1, 1, 1)?;
            // world = F (sin, cos) + R (cos, -sin)
            let dx = ((&f * &sin)? + (&r * &cos)?)?;
            let dy = ((&f * &cos)? - (&r * &sin)?)?;
            let d = Tensor::cat(&[&dx, &dy], 1)?; // [nw, 2]
            let seg = m.matmul(&d)?; // [b, 2]
            let res = (&y - &seg)?;
            let loss = if nll {
                let lv = out
                    .narrow(1, 2, 2)?
                    .clamp(LOG_VAR_RANGE.0, LOG_VAR_RANGE.1)?;
                let v = lv.exp()?;
                let vf = v.narrow(1, 0, 1)?;
                let vr = v.narrow(1, 1, 1)?;
                let ss = (&sin * &sin)?;
                let cc = (&cos * &cos)?;
                let sc = (&sin * &cos)?;
                let xx = ((&vf * &ss)? + (&vr * &cc)?)?;
                let yy = ((&vf * &cc)? + (&vr * &ss)?)?;
                let xy = ((&vf - &vr)? * &sc)?;
                let cov = m.matmul(&Tensor::cat(&[&xx, &xy, &yy], 1)?)?; // [b, 3]
                let a = cov.narrow(1, 0, 1)?;
                let b = cov.narrow(1, 1, 1)?;
                let c = cov.narrow(1, 2, 1)?;
                let det = ((&a * &c)? - (&b * &b)?)?;
                let rx = res.narrow(1, 0, 1)?;
                let ry = res.narrow(1, 1, 1)?;
                let q = ((((&c * &rx)? * &rx)? - (((&b * &rx)? * &ry)? * 2.0)?)?
                    + ((&a * &ry)? * &ry)?)?;
                let q = (q / &det)?;
                ((q + det.log()?)? * 0.5)?.mean_all()?
            } else {
                res.sqr()?.sum(1)?.mean_all()?
            };
            let total = if cfg.dense_weight > 0.0 {
                let yd = Tensor::from_vec(yd, (nw, 2), &dev)?;
                let dl = dense_mse(&out, &yd)?;
                dense_sum += f64::from(dl.to_scalar::<f32>()?) * chunk.len() as f64;
                (&loss + (dl * cfg.dense_weight)?)?
            } else {
                loss.clone()
            };
            opt.backward_step(&total)?;
            let l = f64::from(loss.to_scalar::<f32>()?);
            if !l.is_finite() {
                bail!("non-finite loss at epoch {epoch}");
            }
            sum += l * chunk.len() as f64;
            count += chunk.len();
        }
        last_loss = sum / count as f64;
        let dense = if cfg.dense_weight > 0.0 {
            format!(" dense mse {:.4}", dense_sum / count as f64)
        } else {
            String::new()
        };
        eprintln!(
            "  epoch {epoch:>3} {} loss {last_loss:.4}{dense} lr {lr:.2e}",
            if nll { "nll" } else { "mse" }
        );
        if epoch + cfg.swa_epochs >= cfg.epochs {
            let vars = varmap.all_vars();
            swa = Some(match swa {
                None => vars
                    .iter()
                    .map(|v| v.as_tensor().detach())
                    .collect::<Vec<_>>(),
                Some(acc) => acc
                    .iter()
                    .zip(&vars)
                    .map(|(a, v)| a + v.as_tensor().detach())
                    .collect::<Result<Vec<_>, _>>()?,
            });
        }
    }
    if let Some(acc) = swa {
        let n = cfg.swa_epochs.min(cfg.epochs) as f64;
        for (a, v) in acc.iter().zip(varmap.all_vars()) {
            v.set(&(a / n)?)?;
        }
    }
    Ok((varmap, last_loss))
}

/// Writes the varmap as safetensors with `metadata` (and the `strides` the Rust forward
/// pass reads).
pub fn save_safetensors(
    varmap: &VarMap,
    cfg: &TrainConfig,
    mut metadata: BTreeMap<String, String>,
    path: &std::path::Path,
) -> Result<()> {
    metadata.insert(
        "strides".into(),
        cfg.strides
            .iter()
            .map(|s| s.to_string())
            .collect::<Vec<_>>()
            .join(","),
    );
    let data = varmap
        .data()
        .lock()
        .map_err(|_| anyhow::anyhow!("varmap lock"))?;
    let sorted: BTreeMap<&String, &Var> = data.iter().collect();
    let mut header = serde_json::Map::new();
    header.insert("__metadata__".into(), serde_json::to_value(&metadata)?);
    let mut blob: Vec<u8> = Vec::new();
    for (name, var) in sorted {
        let vals: Vec<f32> = var.flatten_all()?.to_vec1()?;
        let b = blob.len();
        for v in &vals {
            blob.extend_from_slice(&v.to_le_bytes());
        }
        header.insert(
            name.clone(),
            serde_json::json!({"dtype": "F32", "shape": var.dims(), "data_offsets": [b, blob.len()]}),
        );
    }
    let mut h = serde_json::to_vec(&serde_json::Value::Object(header))?;
    while h.len() % 8 != 0 {
        h.push(b' ');
    }
    let mut out = (h.len() as u64).to_le_bytes().to_vec();
    out.extend_from_slice(&h);
    out.extend_from_slice(&blob);
    std::fs::write(path, out)?;
    Ok(())
}

/// Raw outputs of the candle network for `windows` (`[n, CHANNELS * WINDOW]` flattened).
pub fn candle_outputs(varmap: &VarMap, cfg: &TrainConfig, windows: &[f32]) -> Result<Vec<f32>> {
    let dev = Device::Cpu;
    let vb = VarBuilder::from_varmap(varmap, DType::F32, &dev);
    let net = Net::new(cfg, vb, &dev)?;
    let n = windows.len() / (CHANNELS * WINDOW);
    let x = Tensor::from_vec(windows.to_vec(), (n, CHANNELS, WINDOW), &dev)?;
    Ok(net.forward(&x)?.flatten_all()?.to_vec1()?)
}
