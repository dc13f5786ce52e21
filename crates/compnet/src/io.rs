//! Safetensors interchange with PyTorch's own names and layouts.
//!
//! | name | shape | PyTorch |
//! |---|---|---|
//! | `input.weight` / `input.bias` | `[E, I]` / `[E]` | `nn.Linear(I, E)`, followed by `torch.tanh` or nothing (metadata `input_activation`) |
//! | `lstm.weight_ih_l0` / `lstm.weight_hh_l0` | `[4H, E]` / `[4H, H]` | `nn.LSTM(E, H, batch_first=True)`, gates i, f, g, o |
//! | `lstm.bias_ih_l0` / `lstm.bias_hh_l0` | `[4H]` | same |
//! | `output.weight` / `output.bias` | `[O, H]` / `[O]` | `nn.Linear(H, O)` |
//! | `norm.input_mean` / `norm.input_std` | `[I]` | buffers: `x_n = (x - mean) / std` |
//! | `norm.output_mean` / `norm.output_std` | `[O]` | buffers: `y = y_n * std + mean` |
//!
//! All tensors are F32 (F64 and F16/BF16 are accepted on import and converted).
//! Metadata: `input_names` and `output_names` (comma-separated column names, optional),
//! `preset` (optional), `input_activation` (`tanh` or `linear`; a file without it needs
//! the caller's word, `import --input-activation`, since guessing wrong changes every
//! output). A tensor
//! this layout does not use (a second LSTM layer's `*_l1`, a projection) is an error
//! naming it, never silently dropped.
use super::model::LstmModel;
use crate::data::Table;
use anyhow::{Context, Result, bail};
use firmware::nn::format::InputActivation;
use firmware::nn::reference::LstmDims;
use safetensors::{Dtype, SafeTensors, tensor::TensorView};
use std::collections::HashMap;
use std::path::Path;

/// Reads a model from a safetensors file, or from an ONNX file (`.onnx`, see
/// [`crate::onnx`]); names the file and the tensor or node on any error.
pub fn read_model(path: &Path) -> Result<LstmModel> {
    if crate::onnx::is_onnx(path) {
        return crate::onnx::read_onnx_model(path);
    }
    read_model_with(path, None)
}

/// [`read_model`] with the input layer's activation given by the caller (`tanh` or
/// `linear`) for files without `input_activation` metadata; it must agree with the
/// metadata where there is some.
pub fn read_model_with(path: &Path, input_activation: Option<&str>) -> Result<LstmModel> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    parse_model_with(&bytes, input_activation).with_context(|| format!("{}", path.display()))
}

fn to_f32(name: &str, t: &TensorView) -> Result<Vec<f32>> {
    let d = t.data();
    Ok(match t.dtype() {
        Dtype::F32 => d
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect(),
        Dtype::F64 => d
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().unwrap_or([0; 8])) as f32)
            .collect(),
        other => bail!("tensor `{name}`: dtype {other:?} is not supported (use F32 or F64)"),
    })
}

/// Parses a model from safetensors bytes (with `input_activation` metadata).
pub fn parse_model(bytes: &[u8]) -> Result<LstmModel> {
    parse_model_with(bytes, None)
}

/// Tensor names this layout reads.
const KNOWN_TENSORS: [&str; 13] = [
    "input.weight",
    "input.bias",
    "lstm.weight_ih_l0",
    "lstm.weight_hh_l0",
    "lstm.bias_ih_l0",
    "lstm.bias_hh_l0",
    "output.weight",
    "output.bias",
    "norm.input_mean",
    "norm.input_std",
    "norm.output_mean",
    "norm.output_std",
    LINEAR,
];

/// [`parse_model`] with the caller's word on the input activation (see
/// [`read_model_with`]).
pub fn parse_model_with(bytes: &[u8], input_activation: Option<&str>) -> Result<LstmModel> {
    let (_, meta) = SafeTensors::read_metadata(bytes).context("not a safetensors file")?;
    let st = SafeTensors::deserialize(bytes).context("not a safetensors file")?;
    let mut unused: Vec<String> = st
        .names()
        .into_iter()
        .filter(|n| !KNOWN_TENSORS.contains(n))
        .map(str::to_string)
        .collect();
    unused.sort();
    if !unused.is_empty() {
        let layers = if unused.iter().any(|n| n.contains("_l1")) {
            " (a second LSTM layer: the firmware runs one)"
        } else {
            ""
        };
        bail!(
            "tensors this network layout does not use{layers}: {}; the layout is input -> \
             one LSTM layer -> output (crates/compnet/README.md, PyTorch interchange)",
            unused.join(", ")
        );
    }
    let get = |name: &str| -> Result<(Vec<usize>, Vec<f32>)> {
        let t = st
            .tensor(name)
            .map_err(|_| anyhow::anyhow!("missing tensor `{name}`"))?;
        Ok((t.shape().to_vec(), to_f32(name, &t)?))
    };
    let (s_in, w_in) = get("input.weight")?;
    let (s_ih, w_ih) = get("lstm.weight_ih_l0")?;
    let (s_out, w_out) = get("output.weight")?;
    let two = |s: &[usize]| if s.len() == 2 { [s[0], s[1]] } else { [0, 0] };
    let ([e, i], [g4, e2], [o, h]) = (two(&s_in), two(&s_ih), two(&s_out));
    if e == 0 || i == 0 || h == 0 || o == 0 || g4 != 4 * h || e2 != e {
        bail!(
            "inconsistent layer shapes: input.weight {s_in:?}, lstm.weight_ih_l0 {s_ih:?}, output.weight {s_out:?} \
             (want [E, I], [4H, E], [O, H])"
        );
    }
    let dims = LstmDims {
        input: i,
        embed: e,
        hidden: h,
        output: o,
    };
    let shaped = |name: &str, want: &[usize]| -> Result<Vec<f32>> {
        let (s, v) = get(name)?;
        if s != want {
            bail!("tensor `{name}` has shape {s:?}, expected {want:?} for {dims:?}");
        }
        Ok(v)
    };
    let mut m = LstmModel {
        dims,
        input_names: names(meta.metadata(), "input_names", "x", i)?,
        output_names: names(meta.metadata(), "output_names", "y", o)?,
        preset: meta
            .metadata()
            .as_ref()
            .and_then(|m| m.get("preset").cloned())
            .unwrap_or_else(|| "custom".into()),
        input_mean: shaped("norm.input_mean", &[i])?,
        input_std: shaped("norm.input_std", &[i])?,
        w_in,
        b_in: shaped("input.bias", &[e])?,
        input_activation: InputActivation::Tanh,
        w_ih,
        w_hh: shaped("lstm.weight_hh_l0", &[4 * h, h])?,
        b_ih: shaped("lstm.bias_ih_l0", &[4 * h])?,
        b_hh: shaped("lstm.bias_hh_l0", &[4 * h])?,
        w_out,
        b_out: shaped("output.bias", &[o])?,
        output_mean: shaped("norm.output_mean", &[o])?,
        output_std: shaped("norm.output_std", &[o])?,
        linear: match st.tensor(LINEAR) {
            Ok(_) => shaped(LINEAR, &[o, firmware::features::FRICTION_FEATURES])?,
            Err(_) => Vec::new(),
        },
        envelope: Vec::new(),
    };
    m.validate()?;
    // After the tensors: a file that is broken says so first.
    let file_activation = meta
        .metadata()
        .as_ref()
        .and_then(|m| m.get("input_activation"))
        .map(String::as_str);
    let act = match (file_activation, input_activation) {
        (Some(f), Some(given)) if f != given => {
            bail!("metadata input_activation `{f}` disagrees with --input-activation {given}")
        }
        (None, None) => bail!(
            "no `input_activation` metadata: say which activation follows the input layer \
             (`model-export import --input-activation tanh|linear`)"
        ),
        (Some(act), _) | (None, Some(act)) => act,
    };
    m.input_activation = InputActivation::from_name(act).ok_or_else(|| {
        anyhow::anyhow!(
            "input_activation `{act}` is not supported: the input layer is followed by tanh \
             or nothing (`tanh`, `linear`)"
        )
    })?;
    if let Some(text) = meta
        .metadata()
        .as_ref()
        .and_then(|m| m.get(crate::envelope::METADATA_KEY))
    {
        m.envelope = crate::envelope::from_metadata(text, o)?;
    }
    Ok(m)
}

fn names(
    meta: &Option<HashMap<String, String>>,
    key: &str,
    default: &str,
    n: usize,
) -> Result<Vec<String>> {
    match meta.as_ref().and_then(|m| m.get(key)) {
        Some(s) => {
            let v: Vec<String> = s.split(',').map(|x| x.trim().to_string()).collect();
            if v.len() != n {
                bail!(
                    "metadata `{key}` names {} columns, the tensors have {n}",
                    v.len()
                );
            }
            Ok(v)
        }
        None => Ok((0..n).map(|k| format!("{default}{k}")).collect()),
    }
}

/// Name of the `drive` preset's linear stage tensor.
const LINEAR: &str = "linear.weight";

/// Serialises a model (F32, PyTorch names) to safetensors bytes.
pub fn model_bytes(m: &LstmModel) -> Result<Vec<u8>> {
    m.validate()?;
    let LstmDims {
        input: i,
        embed: e,
        hidden: h,
        output: o,
    } = m.dims;
    let shapes: HashMap<&str, Vec<usize>> = [
        ("input.weight", vec![e, i]),
        ("input.bias", vec![e]),
        ("lstm.weight_ih_l0", vec![4 * h, e]),
        ("lstm.weight_hh_l0", vec![4 * h, h]),
        ("lstm.bias_ih_l0", vec![4 * h]),
        ("lstm.bias_hh_l0", vec![4 * h]),
        ("output.weight", vec![o, h]),
        ("output.bias", vec![o]),
        ("norm.input_mean", vec![i]),
        ("norm.input_std", vec![i]),
        ("norm.output_mean", vec![o]),
        ("norm.output_std", vec![o]),
        (LINEAR, vec![o, firmware::features::FRICTION_FEATURES]),
    ]
    .into_iter()
    .collect();
    let linear = (!m.linear.is_empty()).then_some((LINEAR, &m.linear));
    let bufs: Vec<(&str, Vec<u8>)> = m
        .tensors()
        .into_iter()
        .chain(linear)
        .map(|(n, v)| (n, v.iter().flat_map(|x| x.to_le_bytes()).collect()))
        .collect();
    let views: Vec<(&str, TensorView)> = bufs
        .iter()
        .map(|(n, b)| Ok((*n, TensorView::new(Dtype::F32, shapes[n].clone(), b)?)))
        .collect::<Result<_>>()?;
    let envelope = (!m.envelope.is_empty())
        .then(|| crate::envelope::to_metadata(&m.envelope))
        .transpose()?
        .map(|text| (crate::envelope::METADATA_KEY.to_string(), text));
    let meta: HashMap<String, String> = [
        ("input_names".to_string(), m.input_names.join(",")),
        ("output_names".to_string(), m.output_names.join(",")),
        ("preset".to_string(), m.preset.clone()),
        (
            "input_activation".to_string(),
            m.input_activation.name().to_string(),
        ),
        (
            "format".to_string(),
            "joint-feedforward-lstm-v1".to_string(),
        ),
    ]
    .into_iter()
    .chain(envelope)
    .collect();
    canonical_header(safetensors::serialize(views, Some(meta))?)
}

/// Rewrites a safetensors file's JSON header with its keys in sorted order (the crate
/// writes its metadata map in hash order, which changes from run to run), so that the
/// same model always gives the same bytes. The header stays padded with spaces to a
/// multiple of 8 bytes; the tensor data, addressed relative to the header's end, is
/// unchanged.
fn canonical_header(bytes: Vec<u8>) -> Result<Vec<u8>> {
    let len = bytes
        .get(..8)
        .and_then(|b| <[u8; 8]>::try_from(b).ok())
        .map(u64::from_le_bytes)
        .context("safetensors bytes without a header length")?;
    let end = usize::try_from(len)
        .ok()
        .and_then(|n| n.checked_add(8))
        .filter(|&e| e <= bytes.len())
        .context("safetensors header longer than the bytes")?;
    // serde_json's maps are ordered by key.
    let header: serde_json::Value =
        serde_json::from_slice(&bytes[8..end]).context("safetensors header is not JSON")?;
    let mut text = serde_json::to_string(&header)?;
    while !(8 + text.len()).is_multiple_of(8) {
        text.push(' ');
    }
    let mut out = Vec::with_capacity(8 + text.len() + bytes.len() - end);
    out.extend_from_slice(&(text.len() as u64).to_le_bytes());
    out.extend_from_slice(text.as_bytes());
    out.extend_from_slice(&bytes[end..]);
    Ok(out)
}

/// Writes a model atomically (temp file in the same directory, then rename).
pub fn write_model(m: &LstmModel, path: &Path) -> Result<()> {
    let bytes = model_bytes(m)?;
    crate::write_atomic(path, &bytes)
}

/// Compares a model's streamed firmware output with a reference CSV (`x*` inputs,
/// `y*` outputs); returns the largest error relative to the reference outputs' RMS.
pub fn check_reference(
    model: &crate::LstmModel,
    reference: &std::path::Path,
) -> anyhow::Result<f64> {
    let t = Table::read(reference)?;
    if t.is_empty() {
        bail!(
            "{}: the reference has no rows: nothing to compare the network with",
            reference.display()
        );
    }
    let xs: Vec<&[f32]> = (0..model.dims.input)
        .map(|k| t.column(&format!("x{k}")))
        .collect::<Result<_>>()?;
    let ys: Vec<&[f32]> = (0..model.dims.output)
        .map(|k| t.column(&format!("y{k}")))
        .collect::<Result<_>>()?;
    let inputs: Vec<Vec<f32>> = (0..t.len())
        .map(|r| xs.iter().map(|c| c[r]).collect())
        .collect();
    let out = model.stream(&inputs)?;
    let mut worst = 0.0f64;
    for (k, y) in ys.iter().enumerate() {
        let rms = (y.iter().map(|v| (*v as f64).powi(2)).sum::<f64>() / y.len().max(1) as f64)
            .sqrt()
            .max(1e-12);
        for (r, v) in y.iter().enumerate() {
            worst = worst.max((out[r][k] as f64 - *v as f64).abs() / rms);
        }
    }
    Ok(worst)
}
