//! The network's forward pass, hand-written so the library needs no training stack: 1D
//! convolutions (`conv{i}`, "same" padding `k / 2`, the stride of each given by the file's
//! `strides` metadata, ReLU after each), the mean over time, then fully connected layers
//! (`fc{i}`, ReLU between them, none after the last). Weights are read from a safetensors
//! file (`F32` tensors: `conv{i}.weight` `[out, in, k]`, `conv{i}.bias` `[out]`,
//! `fc{i}.weight` `[out, in]`, `fc{i}.bias` `[out]`), the format the training program
//! (`tools/odometry-train`, candle) writes.

use super::OdometryError;
use super::features::{CHANNELS, WINDOW};
use std::collections::BTreeMap;

/// Scale the inputs are divided by before the first layer, per channel (acceleration
/// m/s², angular rate rad/s): brings them near unit range. Shared with the training program.
pub const INPUT_SCALE: [f32; CHANNELS] = [2.0, 2.0, 2.0, 1.0, 1.0, 1.0];

/// Number of outputs: displacement forward and right (m over one stride), and their log
/// variances.
pub const OUTPUTS: usize = 4;

#[derive(Debug, Clone)]
struct Conv {
    w: Vec<f32>,
    b: Vec<f32>,
    out: usize,
    inp: usize,
    k: usize,
    stride: usize,
}

#[derive(Debug, Clone)]
struct Dense {
    w: Vec<f32>,
    b: Vec<f32>,
    out: usize,
    inp: usize,
}

/// The network: its layers and their weights.
#[derive(Debug, Clone)]
pub struct Network {
    convs: Vec<Conv>,
    dense: Vec<Dense>,
    metadata: BTreeMap<String, String>,
}

struct RawTensor {
    shape: Vec<usize>,
    data: Vec<f32>,
}

fn fmt_err(msg: impl Into<String>) -> OdometryError {
    OdometryError::Format(msg.into())
}

/// Tensors by name, and the file's string metadata.
type Parsed = (BTreeMap<String, RawTensor>, BTreeMap<String, String>);

/// Parses the `F32` tensors and the metadata of a safetensors buffer.
fn parse_safetensors(bytes: &[u8]) -> Result<Parsed, OdometryError> {
    let head: [u8; 8] = bytes
        .get(..8)
        .and_then(|b| b.try_into().ok())
        .ok_or_else(|| fmt_err("shorter than its 8-byte header length"))?;
    let n = usize::try_from(u64::from_le_bytes(head))
        .map_err(|_| fmt_err("header length does not fit in memory"))?;
    let end = n
        .checked_add(8)
        .filter(|&e| e <= bytes.len())
        .ok_or_else(|| fmt_err(format!("header of {n} bytes past the end of the file")))?;
    let header: serde_json::Value = serde_json::from_slice(&bytes[8..end])
        .map_err(|e| fmt_err(format!("header is not JSON: {e}")))?;
    let obj = header
        .as_object()
        .ok_or_else(|| fmt_err("header is not a JSON object"))?;
    let data = &bytes[end..];
    let mut tensors = BTreeMap::new();
    let mut metadata = BTreeMap::new();
    for (name, v) in obj {
        if name == "__metadata__" {
            if let Some(m) = v.as_object() {
                for (k, s) in m {
                    if let Some(s) = s.as_str() {
                        metadata.insert(k.clone(), s.to_string());
                    }
                }
            }
            continue;
        }
        let dtype = v.get("dtype").and_then(|d| d.as_str()).unwrap_or("");
        if dtype != "F32" {
            return Err(fmt_err(format!("tensor {name}: dtype {dtype}, want F32")));
        }
        let shape: Vec<usize> = v
            .get("shape")
            .and_then(|s| s.as_array())
            .ok_or_else(|| fmt_err(format!("tensor {name}: no shape")))?
            .iter()
            .map(|d| d.as_u64().and_then(|d| usize::try_from(d).ok()))
            .collect::<Option<_>>()
            .ok_or_else(|| fmt_err(format!("tensor {name}: bad shape")))?;
        let offs: Vec<usize> = v
            .get("data_offsets")
            .and_then(|s| s.as_array())
            .ok_or_else(|| fmt_err(format!("tensor {name}: no data_offsets")))?
            .iter()
            .map(|d| d.as_u64().and_then(|d| usize::try_from(d).ok()))
            .collect::<Option<_>>()
            .ok_or_else(|| fmt_err(format!("tensor {name}: bad data_offsets")))?;
        let (b, e) = match offs[..] {
            [b, e] if b <= e && e <= data.len() => (b, e),
            _ => return Err(fmt_err(format!("tensor {name}: data_offsets out of range"))),
        };
        let count: usize = shape.iter().product();
        if e - b != count * 4 {
            return Err(fmt_err(format!(
                "tensor {name}: {} bytes for shape {shape:?}",
                e - b
            )));
        }
        let values: Vec<f32> = data[b..e]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        if values.iter().any(|x| !x.is_finite()) {
            return Err(fmt_err(format!("tensor {name}: non-finite weight")));
        }
        tensors.insert(
            name.clone(),
            RawTensor {
                shape,
                data: values,
            },
        );
    }
    Ok((tensors, metadata))
}

impl Network {
    /// Reads a network from safetensors bytes; errors name the tensor or field at fault.
    pub fn from_safetensors(bytes: &[u8]) -> Result<Self, OdometryError> {
        let (mut t, metadata) = parse_safetensors(bytes)?;
        let strides: Vec<usize> = metadata
            .get("strides")
            .ok_or_else(|| fmt_err("metadata has no `strides`"))?
            .split(',')
            .map(|s| s.trim().parse::<usize>())
            .collect::<Result<_, _>>()
            .map_err(|e| fmt_err(format!("metadata `strides`: {e}")))?;
        let mut convs = Vec::new();
        let mut inp = CHANNELS;
        let mut len = WINDOW;
        while let Some(w) = t.remove(&format!("conv{}.weight", convs.len())) {
            let i = convs.len();
            let b = t
                .remove(&format!("conv{i}.bias"))
                .ok_or_else(|| OdometryError::Missing(format!("conv{i}.bias")))?;
            let stride = *strides
                .get(i)
                .filter(|&&s| s >= 1)
                .ok_or_else(|| fmt_err(format!("no stride >= 1 for conv{i}")))?;
            let [out, ci, k] = w.shape[..] else {
                return Err(fmt_err(format!("conv{i}.weight: shape {:?}", w.shape)));
            };
            if ci != inp || b.shape != [out] || k == 0 {
                return Err(fmt_err(format!(
                    "conv{i}: weight {:?} bias {:?} after {inp} channels",
                    w.shape, b.shape
                )));
            }
            len = (len + 2 * (k / 2) - k) / stride + 1;
            convs.push(Conv {
                w: w.data,
                b: b.data,
                out,
                inp: ci,
                k,
                stride,
            });
            inp = out;
        }
        if convs.is_empty() || len == 0 {
            return Err(OdometryError::Missing("conv0.weight".into()));
        }
        let mut dense = Vec::new();
        while let Some(w) = t.remove(&format!("fc{}.weight", dense.len())) {
            let i = dense.len();
            let b = t
                .remove(&format!("fc{i}.bias"))
                .ok_or_else(|| OdometryError::Missing(format!("fc{i}.bias")))?;
            let [out, ci] = w.shape[..] else {
                return Err(fmt_err(format!("fc{i}.weight: shape {:?}", w.shape)));
            };
            if ci != inp || b.shape != [out] {
                return Err(fmt_err(format!(
                    "fc{i}: weight {:?} bias {:?} after {inp} features",
                    w.shape, b.shape
                )));
            }
            dense.push(Dense {
                w: w.data,
                b: b.data,
                out,
                inp: ci,
            });
            inp = out;
        }
        if inp != OUTPUTS || dense.is_empty() {
            return Err(fmt_err(format!(
                "the last layer gives {inp} outputs, want {OUTPUTS}"
            )));
        }
        if let Some(name) = t.keys().next() {
            return Err(fmt_err(format!("unused tensor {name}")));
        }
        Ok(Network {
            convs,
            dense,
            metadata,
        })
    }

    /// The file's metadata (training command, data hash, training time, ...).
    pub fn metadata(&self) -> &BTreeMap<String, String> {
        &self.metadata
    }

    /// Number of parameters.
    pub fn parameters(&self) -> usize {
        self.convs
            .iter()
            .map(|c| c.w.len() + c.b.len())
            .sum::<usize>()
            + self
                .dense
                .iter()
                .map(|d| d.w.len() + d.b.len())
                .sum::<usize>()
    }

    /// The raw outputs `[d_forward, d_right, log var_forward, log var_right]` of one window
    /// (`CHANNELS * WINDOW` values, channel-major, before [`INPUT_SCALE`]).
    pub fn forward(&self, window: &[f32]) -> Result<[f32; OUTPUTS], OdometryError> {
        if window.len() != CHANNELS * WINDOW {
            return Err(OdometryError::Input(format!(
                "window of {} values, want {}",
                window.len(),
                CHANNELS * WINDOW
            )));
        }
        let mut x: Vec<f32> = window
            .chunks_exact(WINDOW)
            .zip(INPUT_SCALE)
            .flat_map(|(ch, s)| ch.iter().map(move |v| v / s))
            .collect();
        let mut len = WINDOW;
        for c in &self.convs {
            let pad = c.k / 2;
            let out_len = (len + 2 * pad - c.k) / c.stride + 1;
            // zero-padded input, one row of `len + 2 pad` per channel: no bounds tests in the
            // inner loop
            let plen = len + 2 * pad;
            let mut xp = vec![0.0f32; c.inp * plen];
            for i in 0..c.inp {
                xp[i * plen + pad..i * plen + pad + len]
                    .copy_from_slice(&x[i * len..(i + 1) * len]);
            }
            let mut y = vec![0.0f32; c.out * out_len];
            for o in 0..c.out {
                let row = &mut y[o * out_len..(o + 1) * out_len];
                row.iter_mut().for_each(|v| *v = c.b[o]);
                for i in 0..c.inp {
                    let xi = &xp[i * plen..(i + 1) * plen];
                    let wi = &c.w[(o * c.inp + i) * c.k..(o * c.inp + i + 1) * c.k];
                    for (j, &w) in wi.iter().enumerate() {
                        for (p, yv) in row.iter_mut().enumerate() {
                            *yv += w * xi[p * c.stride + j];
                        }
                    }
                }
                row.iter_mut().for_each(|v| *v = v.max(0.0));
            }
            x = y;
            len = out_len;
        }
        let channels = self.convs.last().map_or(CHANNELS, |c| c.out);
        let mut h: Vec<f32> = (0..channels)
            .map(|c| x[c * len..(c + 1) * len].iter().sum::<f32>() / len as f32)
            .collect();
        let last = self.dense.len() - 1;
        for (li, d) in self.dense.iter().enumerate() {
            let mut y: Vec<f32> =
                d.b.iter()
                    .enumerate()
                    .map(|(o, b)| {
                        b + d.w[o * d.inp..(o + 1) * d.inp]
                            .iter()
                            .zip(&h)
                            .map(|(w, v)| w * v)
                            .sum::<f32>()
                    })
                    .collect();
            if li < last {
                y.iter_mut().for_each(|v| *v = v.max(0.0));
            }
            debug_assert_eq!(y.len(), d.out);
            h = y;
        }
        let mut out = [0.0f32; OUTPUTS];
        out.copy_from_slice(&h);
        if out.iter().any(|v| !v.is_finite()) {
            return Err(OdometryError::NonFinite);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A safetensors buffer of `tensors` (name, shape, values) and `strides`.
    fn file(tensors: &[(&str, Vec<usize>, Vec<f32>)], strides: &str) -> Vec<u8> {
        let mut header = serde_json::Map::new();
        header.insert(
            "__metadata__".into(),
            serde_json::json!({ "strides": strides }),
        );
        let mut blob = Vec::new();
        for (name, shape, vals) in tensors {
            let b = blob.len();
            for v in vals {
                blob.extend_from_slice(&v.to_le_bytes());
            }
            header.insert(
                (*name).into(),
                serde_json::json!({"dtype": "F32", "shape": shape, "data_offsets": [b, blob.len()]}),
            );
        }
        let h = serde_json::to_vec(&serde_json::Value::Object(header)).unwrap();
        let mut out = (h.len() as u64).to_le_bytes().to_vec();
        out.extend_from_slice(&h);
        out.extend_from_slice(&blob);
        out
    }

    /// One conv (one output channel, kernel 1, reading channel 0 with weight 1) and a dense
    /// layer copying the mean into all four outputs: the output is the mean of channel 0
    /// over the window, divided by its input scale.
    fn tiny() -> Vec<(&'static str, Vec<usize>, Vec<f32>)> {
        let mut w = vec![0.0; CHANNELS];
        w[0] = 1.0;
        vec![
            ("conv0.weight", vec![1, CHANNELS, 1], w),
            ("conv0.bias", vec![1], vec![0.0]),
            ("fc0.weight", vec![OUTPUTS, 1], vec![1.0, 2.0, 0.0, -1.0]),
            ("fc0.bias", vec![OUTPUTS], vec![0.0, 0.0, 0.5, 0.0]),
        ]
    }

    #[test]
    fn tiny_network_computes_the_scaled_mean() {
        let net = Network::from_safetensors(&file(&tiny(), "1")).unwrap();
        assert_eq!(net.parameters(), CHANNELS + 1 + 4 + 4);
        let mut x = vec![0.0f32; CHANNELS * WINDOW];
        for (k, v) in x[..WINDOW].iter_mut().enumerate() {
            *v = if k % 2 == 0 { 4.0 } else { 0.0 };
        }
        let out = net.forward(&x).unwrap();
        let m = 2.0 / INPUT_SCALE[0]; // mean 2 m/s², scaled
        assert!((out[0] - m).abs() < 1e-6 && (out[1] - 2.0 * m).abs() < 1e-6);
        assert!((out[2] - 0.5).abs() < 1e-6 && (out[3] + m).abs() < 1e-6);
        assert!(matches!(net.forward(&x[1..]), Err(OdometryError::Input(_))));
    }

    #[test]
    fn malformed_files_are_typed_errors() {
        let good = file(&tiny(), "1");
        assert!(matches!(
            Network::from_safetensors(&good[..5]),
            Err(OdometryError::Format(_))
        ));
        assert!(matches!(
            Network::from_safetensors(&good[..good.len() - 4]),
            Err(OdometryError::Format(_))
        ));
        let mut no_bias = tiny();
        no_bias.remove(1);
        assert!(matches!(
            Network::from_safetensors(&file(&no_bias, "1")),
            Err(OdometryError::Missing(_))
        ));
        let mut nan = tiny();
        nan[2].2[0] = f32::NAN;
        assert!(matches!(
            Network::from_safetensors(&file(&nan, "1")),
            Err(OdometryError::Format(_))
        ));
        assert!(matches!(
            Network::from_safetensors(&file(&tiny(), "0")),
            Err(OdometryError::Format(_))
        ));
    }
}
