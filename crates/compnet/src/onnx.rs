//! ONNX interchange: a network exported from PyTorch with `torch.onnx.export` (either
//! exporter: the TorchScript one, `dynamo=False`, and the dynamo-based default of current
//! PyTorch; an LSTM with `batch_first` either way) imports to the same [`LstmModel`] as
//! its safetensors file.
//!
//! The supported graph, from its one input `x` (`[batch, time, I]`, or `[time, batch, I]`
//! for a `batch_first=False` LSTM) to its one output:
//!
//! | stage | nodes | maps to |
//! |---|---|---|
//! | input normalisation (optional) | `Sub(x, mean)`, `Div(·, std)` | `input_mean`, `input_std` |
//! | input layer | `MatMul(·, W[I, E])` + `Add(b[E])`, or `Gemm` | `input.weight`, `input.bias` |
//! | activation | `Tanh`, or none | the firmware's input activation (tanh or linear) |
//! | LSTM | `LSTM` (layout 0), after `Transpose(perm 1,0,2)` for a batch-first input (then transposed back after it), or `LSTM` (layout 1); its direction axis dropped by `Squeeze`, or by `Transpose(perm 0,2,1,3)` + `Reshape` to `[T, B, H]` (dynamo) | `W`, `R`, `B` in ONNX gate order i, o, f, c, reordered to PyTorch's i, f, g, o |
//! | output layer | `MatMul(·, W[H, O])` + `Add(b[O])`, or `Gemm` | `output.weight`, `output.bias` |
//! | output scaling (optional) | `Mul(·, std)`, `Add(·, mean)` | `output_std`, `output_mean` |
//!
//! The LSTM is one forward layer (a graph with several LSTM nodes, `num_layers > 1`, is
//! refused saying how many it found: the firmware runs one) with the default activations,
//! no clip, no peepholes, no sequence lengths, and a zero initial state (absent, a zero
//! constant, or the `Shape`…`ConstantOfShape` zeros the exporter builds). Constants are
//! initializers or `Constant` nodes, in F32 or F64. Anything else (another node on the
//! path, a second consumer, another activation) is refused with a message naming the
//! node. Metadata (`metadata_props`): `input_names`, `output_names`, `preset`, as in the
//! safetensors file (optional).

use super::model::LstmModel;
use anyhow::{Context, Result, bail};
use firmware::nn::format::InputActivation;
use firmware::nn::reference::LstmDims;
use onnx_protobuf::{AttributeProto, Message, ModelProto, NodeProto, TensorProto};
use std::collections::HashMap;
use std::path::Path;

/// True when `path` names an ONNX file (extension `.onnx`).
pub fn is_onnx(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("onnx"))
}

/// Reads a model from an ONNX file; names the file and the node on any error.
pub fn read_onnx_model(path: &Path) -> Result<LstmModel> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    parse_onnx_model(&bytes).with_context(|| format!("{}", path.display()))
}

/// A constant tensor: shape and values.
#[derive(Debug, Clone)]
struct Constant {
    dims: Vec<usize>,
    values: Vec<f32>,
}

impl Constant {
    fn numel(&self) -> usize {
        self.values.len()
    }
}

/// ONNX `TensorProto.DataType` codes read here.
const FLOAT: i32 = 1;
const INT64: i32 = 7;
const DOUBLE: i32 = 11;

/// Values of a constant tensor as f32 (F32 and F64; INT64 for shape operands).
fn tensor_values(t: &TensorProto) -> Result<Constant> {
    let dims: Vec<usize> = t
        .dims
        .iter()
        .map(|&d| usize::try_from(d).map_err(|_| anyhow::anyhow!("negative dimension {d}")))
        .collect::<Result<_>>()?;
    let n = dims
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .context("tensor size overflows")?;
    if !t.external_data.is_empty() {
        bail!("data stored outside the file (external data) is not supported");
    }
    let raw = &t.raw_data;
    let values: Vec<f32> = match t.data_type {
        FLOAT if !raw.is_empty() => raw
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect(),
        FLOAT => t.float_data.clone(),
        DOUBLE if !raw.is_empty() => raw
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) as f32)
            .collect(),
        DOUBLE => t.double_data.iter().map(|&v| v as f32).collect(),
        INT64 if !raw.is_empty() => raw
            .chunks_exact(8)
            .map(|b| i64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) as f32)
            .collect(),
        INT64 => t.int64_data.iter().map(|&v| v as f32).collect(),
        other => bail!("data type {other} is not supported (use float32)"),
    };
    if values.len() != n {
        bail!("{} values for shape {dims:?}", values.len());
    }
    if values.iter().any(|v| !v.is_finite()) {
        bail!("non-finite value");
    }
    Ok(Constant { dims, values })
}

fn attr<'a>(n: &'a NodeProto, name: &str) -> Option<&'a AttributeProto> {
    n.attribute.iter().find(|a| a.name == name)
}

fn attr_i(n: &NodeProto, name: &str, default: i64) -> i64 {
    attr(n, name).map_or(default, |a| a.i)
}

fn attr_f(n: &NodeProto, name: &str, default: f32) -> f32 {
    attr(n, name).map_or(default, |a| a.f)
}

fn node_label(n: &NodeProto) -> String {
    format!("node '{}' ({})", n.name, n.op_type)
}

/// The graph with its constants and the consumers of every value.
struct Graph<'a> {
    nodes: &'a [NodeProto],
    constants: HashMap<&'a str, Constant>,
    consumers: HashMap<&'a str, Vec<usize>>,
    output: &'a str,
    visited: Vec<bool>,
}

impl<'a> Graph<'a> {
    fn constant(&self, name: &str) -> Option<&Constant> {
        self.constants.get(name)
    }

    /// The one node that continues the data path from `value` (the exporter's `Shape`
    /// side chains for the initial state are not on the path).
    fn next(&self, value: &str) -> Result<Option<usize>> {
        let users: Vec<usize> = self
            .consumers
            .get(value)
            .map(|v| {
                v.iter()
                    .copied()
                    .filter(|&k| self.nodes[k].op_type != "Shape")
                    .collect()
            })
            .unwrap_or_default();
        match users.as_slice() {
            [] => Ok(None),
            [k] => Ok(Some(*k)),
            many => bail!(
                "value '{value}' feeds {} nodes ({}): the supported network is one chain",
                many.len(),
                many.iter()
                    .map(|&k| node_label(&self.nodes[k]))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        }
    }

    /// The operand of binary node `k` that is not `value`, as a constant.
    fn other_operand(&self, k: usize, value: &str) -> Result<&Constant> {
        let n = &self.nodes[k];
        let other = match n.input.as_slice() {
            [a, b] if a == value => b,
            [a, b] if b == value => a,
            _ => bail!(
                "{}: expected two inputs, one of them '{value}'",
                node_label(n)
            ),
        };
        self.constant(other).with_context(|| {
            format!(
                "{}: operand '{other}' is not a constant (initializer or Constant node)",
                node_label(n)
            )
        })
    }
}

/// Parses a model from ONNX bytes.
pub fn parse_onnx_model(bytes: &[u8]) -> Result<LstmModel> {
    let model = ModelProto::parse_from_bytes(bytes).context("not an ONNX model (protobuf)")?;
    let g = model
        .graph
        .as_ref()
        .context("the ONNX model has no graph")?;
    let mut constants: HashMap<&str, Constant> = HashMap::new();
    for t in &g.initializer {
        constants.insert(
            t.name.as_str(),
            tensor_values(t).with_context(|| format!("initializer '{}'", t.name))?,
        );
    }
    for n in &g.node {
        if n.op_type == "Constant" {
            let (Some(out), Some(a)) = (n.output.first(), attr(n, "value")) else {
                bail!("{}: only a tensor `value` is supported", node_label(n));
            };
            let t =
                a.t.as_ref()
                    .with_context(|| format!("{}: `value` holds no tensor", node_label(n)))?;
            constants.insert(
                out.as_str(),
                tensor_values(t).with_context(|| node_label(n))?,
            );
        }
    }
    let lstms: Vec<String> = g
        .node
        .iter()
        .filter(|n| n.op_type == "LSTM")
        .map(node_label)
        .collect();
    if lstms.len() > 1 {
        bail!(
            "the graph has {} LSTM layers ({}): the firmware runs one LSTM layer (export \
             `nn.LSTM(..., num_layers=1)`)",
            lstms.len(),
            lstms.join(", ")
        );
    }
    let mut consumers: HashMap<&str, Vec<usize>> = HashMap::new();
    for (k, n) in g.node.iter().enumerate() {
        if !n.domain.is_empty() && n.domain != "ai.onnx" {
            bail!(
                "{}: operator domain '{}' is not supported",
                node_label(n),
                n.domain
            );
        }
        // Every node the walk may follow has its first output (found by the fuzzer: an
        // `Add` without outputs panicked).
        if n.output.first().is_none_or(String::is_empty) {
            bail!("{}: has no output", node_label(n));
        }
        for i in &n.input {
            if !i.is_empty() {
                consumers.entry(i.as_str()).or_default().push(k);
            }
        }
    }
    let inputs: Vec<&str> = g
        .input
        .iter()
        .map(|v| v.name.as_str())
        .filter(|n| !constants.contains_key(n))
        .collect();
    let [x] = inputs.as_slice() else {
        bail!(
            "the graph has {} inputs ({}); the supported network takes one, x [batch, time, features]",
            inputs.len(),
            inputs.join(", ")
        );
    };
    let [output] = g.output.as_slice() else {
        bail!(
            "the graph has {} outputs; the supported network has one (the compensation torque)",
            g.output.len()
        );
    };
    let mut graph = Graph {
        nodes: &g.node,
        constants,
        consumers,
        output: output.name.as_str(),
        visited: vec![false; g.node.len()],
    };
    let meta: HashMap<&str, &str> = model
        .metadata_props
        .iter()
        .map(|p| (p.key.as_str(), p.value.as_str()))
        .collect();
    let m = walk(&mut graph, x, &meta)?;
    // Every node must be on the path or build the zero initial state.
    for (k, n) in g.node.iter().enumerate() {
        if !graph.visited[k] && !SHAPE_OPS.contains(&n.op_type.as_str()) {
            bail!(
                "{} is not part of the supported network (input layer -> tanh -> LSTM -> output layer)",
                node_label(n)
            );
        }
    }
    m.validate()?;
    Ok(m)
}

/// Largest LSTM hidden size read (far above what a drive runs; bounds the shape checks).
const MAX_HIDDEN: usize = 1 << 16;

/// Nodes the exporter uses to build the zero initial state from the input's shape.
const SHAPE_OPS: [&str; 9] = [
    "Shape",
    "Gather",
    "Unsqueeze",
    "Concat",
    "Constant",
    "ConstantOfShape",
    "Slice",
    "Cast",
    "Expand",
];

/// A dense layer read from the graph.
struct Dense<'a> {
    /// Input size.
    inputs: usize,
    /// Output size.
    outputs: usize,
    /// Weight `[out, in]` (PyTorch's layout).
    weight: Vec<f32>,
    /// Bias `[out]`.
    bias: Vec<f32>,
    /// The value it produces.
    value: &'a str,
}

/// A dense layer: `MatMul` + `Add` or `Gemm`, from `value`.
fn dense<'a>(g: &mut Graph<'a>, value: &'a str, k: usize, what: &str) -> Result<Dense<'a>> {
    let nodes = g.nodes;
    let n = &nodes[k];
    match n.op_type.as_str() {
        "MatMul" => {
            if n.input.first().map(String::as_str) != Some(value) {
                bail!(
                    "{}: {what} must multiply the data by the weight",
                    node_label(n)
                );
            }
            let w = g.other_operand(k, value)?.clone();
            let [i, o] = w.dims[..] else {
                bail!(
                    "{}: {what} weight has shape {:?}, expected [in, out]",
                    node_label(n),
                    w.dims
                );
            };
            g.visited[k] = true;
            let after = n.output[0].as_str();
            let add = g
                .next(after)?
                .filter(|&a| nodes[a].op_type == "Add")
                .with_context(|| format!("{}: {what} has no bias Add after it", node_label(n)))?;
            let b = g.other_operand(add, after)?.clone();
            if b.numel() != o {
                bail!(
                    "{}: {what} bias has {} values for {o} outputs",
                    node_label(&nodes[add]),
                    b.numel()
                );
            }
            g.visited[add] = true;
            // MatMul's weight is [in, out]; PyTorch's [out, in].
            let mut wt = vec![0.0f32; i * o];
            for r in 0..i {
                for c in 0..o {
                    wt[c * i + r] = w.values[r * o + c];
                }
            }
            Ok(Dense {
                inputs: i,
                outputs: o,
                weight: wt,
                bias: b.values,
                value: nodes[add].output[0].as_str(),
            })
        }
        "Gemm" => {
            if attr_i(n, "transA", 0) != 0
                || attr_f(n, "alpha", 1.0) != 1.0
                || attr_f(n, "beta", 1.0) != 1.0
                || n.input.first().map(String::as_str) != Some(value)
                || n.input.len() != 3
            {
                bail!(
                    "{}: {what}: only Gemm(x, W, b) with alpha = beta = 1 and transA = 0 is supported",
                    node_label(n)
                );
            }
            let w = g
                .constant(&n.input[1])
                .with_context(|| format!("{}: weight is not a constant", node_label(n)))?
                .clone();
            let b = g
                .constant(&n.input[2])
                .with_context(|| format!("{}: bias is not a constant", node_label(n)))?
                .clone();
            let [r, c] = w.dims[..] else {
                bail!("{}: {what} weight has shape {:?}", node_label(n), w.dims);
            };
            let (i, o, wt) = if attr_i(n, "transB", 0) == 1 {
                (c, r, w.values)
            } else {
                let mut wt = vec![0.0f32; r * c];
                for a in 0..r {
                    for b in 0..c {
                        wt[b * r + a] = w.values[a * c + b];
                    }
                }
                (r, c, wt)
            };
            if b.numel() != o {
                bail!(
                    "{}: {what} bias has {} values for {o} outputs",
                    node_label(n),
                    b.numel()
                );
            }
            g.visited[k] = true;
            Ok(Dense {
                inputs: i,
                outputs: o,
                weight: wt,
                bias: b.values,
                value: n.output[0].as_str(),
            })
        }
        _ => bail!(
            "{}: expected the {what} (MatMul + Add or Gemm)",
            node_label(n)
        ),
    }
}

/// The integer values of a constant (perm, axes).
fn ints(c: &Constant) -> Vec<i64> {
    c.values.iter().map(|&v| v as i64).collect()
}

/// Walks the data path from `x` and builds the model.
fn walk<'a>(g: &mut Graph<'a>, x: &'a str, meta: &HashMap<&str, &str>) -> Result<LstmModel> {
    let nodes = g.nodes;
    let mut cur: &'a str = x;
    let step = |g: &Graph<'a>, cur: &str, what: &str| -> Result<usize> {
        g.next(cur)?
            .with_context(|| format!("value '{cur}' ends the graph before the {what}"))
    };

    // Input normalisation.
    let mut k = step(g, cur, "input layer")?;
    let mut input_mean = None;
    let mut input_std = None;
    if nodes[k].op_type == "Sub" && nodes[k].input.first().map(String::as_str) == Some(cur) {
        input_mean = Some(g.other_operand(k, cur)?.values.clone());
        g.visited[k] = true;
        cur = nodes[k].output[0].as_str();
        k = step(g, cur, "input layer")?;
    }
    if nodes[k].op_type == "Div" && nodes[k].input.first().map(String::as_str) == Some(cur) {
        input_std = Some(g.other_operand(k, cur)?.values.clone());
        g.visited[k] = true;
        cur = nodes[k].output[0].as_str();
        k = step(g, cur, "input layer")?;
    }

    // Input layer and its activation: Tanh, or none (a plain `nn.Linear` straight into
    // the LSTM).
    let Dense {
        inputs: i,
        outputs: e,
        weight: w_in,
        bias: b_in,
        value: after,
    } = dense(g, cur, k, "input layer")?;
    cur = after;
    k = step(g, cur, "input activation")?;
    let input_activation = match nodes[k].op_type.as_str() {
        "Tanh" => {
            g.visited[k] = true;
            cur = nodes[k].output[0].as_str();
            InputActivation::Tanh
        }
        "Transpose" | "LSTM" => InputActivation::Linear,
        _ => bail!(
            "{}: the input layer must be followed by Tanh or go straight to the LSTM (the \
             firmware's input activations: tanh, linear)",
            node_label(&nodes[k])
        ),
    };

    // LSTM, with the exporter's transposes.
    k = step(g, cur, "LSTM")?;
    let mut transposed = false;
    if nodes[k].op_type == "Transpose" {
        let perm = attr(&nodes[k], "perm")
            .map(|a| a.ints.clone())
            .unwrap_or_default();
        if perm != [1, 0, 2] {
            bail!(
                "{}: perm {perm:?}, expected [1, 0, 2] (batch-first to time-first)",
                node_label(&nodes[k])
            );
        }
        transposed = true;
        g.visited[k] = true;
        cur = nodes[k].output[0].as_str();
        k = step(g, cur, "LSTM")?;
    }
    let n = &nodes[k];
    if n.op_type != "LSTM" {
        bail!(
            "{}: expected the LSTM after the input activation",
            node_label(n)
        );
    }
    let label = node_label(n);
    let h = usize::try_from(attr_i(n, "hidden_size", 0)).unwrap_or(0);
    if h == 0 || h > MAX_HIDDEN {
        bail!("{label}: hidden_size {h} is not in 1..={MAX_HIDDEN}");
    }
    let layout = attr_i(n, "layout", 0);
    let direction = attr(n, "direction").map(|a| String::from_utf8_lossy(&a.s).into_owned());
    if direction.as_deref().is_some_and(|d| d != "forward") {
        bail!("{label}: direction {direction:?}: only a forward LSTM is supported");
    }
    if let Some(a) = attr(n, "activations") {
        let acts: Vec<String> = a
            .strings
            .iter()
            .map(|s| String::from_utf8_lossy(s).into_owned())
            .collect();
        if acts != ["Sigmoid", "Tanh", "Tanh"] {
            bail!("{label}: activations {acts:?}: only Sigmoid, Tanh, Tanh are supported");
        }
    }
    if attr(n, "clip").is_some() || attr_i(n, "input_forget", 0) != 0 {
        bail!("{label}: clip and input_forget are not supported");
    }
    // Three ways in: a batch-first input transposed to [time, batch, features] for
    // layout 0 (TorchScript, `batch_first=True`), a batch-first input read with layout 1,
    // or a time-first input straight into layout 0 (`batch_first=False`). Streamed one
    // sequence at a time, all three are the same network.
    if !(layout == 0 || layout == 1) || (layout == 1 && transposed) {
        bail!(
            "{label}: layout {layout} with {} input: the LSTM must read [time, batch, features] (layout 0) or [batch, time, features] (layout 1, untransposed)",
            if transposed {
                "a transposed"
            } else {
                "an untransposed"
            }
        );
    }
    let input = |j: usize| n.input.get(j).map(String::as_str).filter(|s| !s.is_empty());
    if input(0) != Some(cur) {
        bail!("{label}: its input X is not the input layer's output");
    }
    let w = g
        .constant(input(1).unwrap_or(""))
        .with_context(|| format!("{label}: W is not a constant"))?
        .clone();
    let r = g
        .constant(input(2).unwrap_or(""))
        .with_context(|| format!("{label}: R is not a constant"))?
        .clone();
    if w.dims != [1, 4 * h, e] || r.dims != [1, 4 * h, h] {
        bail!(
            "{label}: W {:?} and R {:?} for hidden_size {h} and {e} inputs (one forward layer: [1, 4H, E] and [1, 4H, H])",
            w.dims,
            r.dims
        );
    }
    let b = match input(3) {
        None => vec![0.0; 8 * h],
        Some(name) => {
            let b = g
                .constant(name)
                .with_context(|| format!("{label}: B is not a constant"))?;
            if b.dims != [1, 8 * h] {
                bail!("{label}: B has shape {:?}, expected [1, {}]", b.dims, 8 * h);
            }
            b.values.clone()
        }
    };
    if input(4).is_some() {
        bail!("{label}: sequence_lens is not supported (every step is streamed)");
    }
    for (j, what) in [(5, "initial_h"), (6, "initial_c")] {
        if let Some(name) = input(j) {
            zero_state(g, name).with_context(|| format!("{label}: {what}"))?;
        }
    }
    if input(7).is_some() {
        bail!("{label}: peephole weights P are not supported");
    }
    for (j, out) in n.output.iter().enumerate().skip(1) {
        if !out.is_empty() && (g.consumers.contains_key(out.as_str()) || out == g.output) {
            bail!(
                "{label}: its output {j} (final state) is used; only the sequence output Y is supported"
            );
        }
    }
    g.visited[k] = true;
    // ONNX gate blocks i, o, f, c -> PyTorch i, f, g, o.
    const FROM_ONNX: [usize; 4] = [0, 2, 3, 1];
    let reorder = |v: &[f32], block: usize| -> Vec<f32> {
        FROM_ONNX
            .iter()
            .flat_map(|&s| v[s * block..(s + 1) * block].iter().copied())
            .collect()
    };
    let w_ih = reorder(&w.values, h * e);
    let w_hh = reorder(&r.values, h * h);
    let b_ih = reorder(&b[..4 * h], h);
    let b_hh = reorder(&b[4 * h..], h);
    cur = n.output[0].as_str();

    // Back to [batch, time, H]: the LSTM's direction axis dropped, by `Squeeze`
    // (TorchScript exporter) or by `Transpose` [T, 1, B, H] -> [T, B, 1, H] and `Reshape`
    // to [T, B, H] (the dynamo-based exporter, layout 0).
    k = step(g, cur, "output layer")?;
    let squeeze_axis = if layout == 0 { 1 } else { 2 };
    match nodes[k].op_type.as_str() {
        "Squeeze" => {
            let axes = match nodes[k].input.get(1) {
                Some(a) => ints(g.constant(a).with_context(|| {
                    format!("{}: axes are not a constant", node_label(&nodes[k]))
                })?),
                None => attr(&nodes[k], "axes")
                    .map(|a| a.ints.clone())
                    .unwrap_or_default(),
            };
            if axes != [squeeze_axis] {
                bail!(
                    "{}: axes {axes:?}, expected [{squeeze_axis}] (the LSTM's direction axis)",
                    node_label(&nodes[k])
                );
            }
        }
        "Transpose" if layout == 0 => {
            let perm = attr(&nodes[k], "perm")
                .map(|a| a.ints.clone())
                .unwrap_or_default();
            if perm != [0, 2, 1, 3] {
                bail!(
                    "{}: perm {perm:?}, expected [0, 2, 1, 3] (the LSTM's direction axis next to its hidden axis)",
                    node_label(&nodes[k])
                );
            }
            g.visited[k] = true;
            cur = nodes[k].output[0].as_str();
            k = step(g, cur, "output layer")?;
            let n = &nodes[k];
            let shape = match (n.op_type.as_str(), n.input.as_slice()) {
                ("Reshape", [data, shape]) if data == cur => {
                    ints(g.constant(shape).with_context(|| {
                        format!("{}: the shape is not a constant", node_label(n))
                    })?)
                }
                _ => bail!(
                    "{}: expected Reshape of the LSTM's output to [time, batch, hidden]",
                    node_label(n)
                ),
            };
            if attr_i(n, "allowzero", 0) != 0
                || !matches!(shape[..], [a, b, c] if a != 0 && b != 0 && (c == h as i64 || c == -1))
            {
                bail!(
                    "{}: shape {shape:?}, expected [time, batch, {h}] (the LSTM's direction axis dropped)",
                    node_label(n)
                );
            }
        }
        _ => bail!(
            "{}: expected Squeeze of the LSTM's direction axis (or Transpose + Reshape)",
            node_label(&nodes[k])
        ),
    }
    g.visited[k] = true;
    cur = nodes[k].output[0].as_str();
    k = step(g, cur, "output layer")?;
    if transposed {
        let perm = attr(&nodes[k], "perm")
            .map(|a| a.ints.clone())
            .unwrap_or_default();
        if nodes[k].op_type != "Transpose" || perm != [1, 0, 2] {
            bail!(
                "{}: expected Transpose perm [1, 0, 2] back to batch-first",
                node_label(&nodes[k])
            );
        }
        g.visited[k] = true;
        cur = nodes[k].output[0].as_str();
        k = step(g, cur, "output layer")?;
    }

    // Output layer and scaling.
    let Dense {
        inputs: h2,
        outputs: o,
        weight: w_out,
        bias: b_out,
        value: after,
    } = dense(g, cur, k, "output layer")?;
    if h2 != h {
        bail!(
            "{}: the output layer takes {h2} inputs, the LSTM has {h}",
            node_label(&nodes[k])
        );
    }
    cur = after;
    let mut output_std = None;
    let mut output_mean = None;
    if let Some(k) = g.next(cur)?
        && nodes[k].op_type == "Mul"
    {
        output_std = Some(g.other_operand(k, cur)?.values.clone());
        g.visited[k] = true;
        cur = nodes[k].output[0].as_str();
    }
    if let Some(k) = g.next(cur)?
        && nodes[k].op_type == "Add"
    {
        output_mean = Some(g.other_operand(k, cur)?.values.clone());
        g.visited[k] = true;
        cur = nodes[k].output[0].as_str();
    }
    if let Some(k) = g.next(cur)? {
        bail!(
            "{} after the output layer is not supported",
            node_label(&nodes[k])
        );
    }
    if cur != g.output {
        bail!(
            "the graph's output '{}' is not the network's output '{cur}'",
            g.output
        );
    }

    let sized = |v: Option<Vec<f32>>, n: usize, fill: f32, what: &str| -> Result<Vec<f32>> {
        match v {
            None => Ok(vec![fill; n]),
            Some(v) if v.len() == n => Ok(v),
            Some(v) => bail!("{what} has {} values for {n}", v.len()),
        }
    };
    let names = |key: &str, default: &str, n: usize| -> Result<Vec<String>> {
        match meta.get(key) {
            Some(s) => {
                let v: Vec<String> = s.split(',').map(|x| x.trim().to_string()).collect();
                if v.len() != n {
                    bail!(
                        "metadata `{key}` names {} columns, the network has {n}",
                        v.len()
                    );
                }
                Ok(v)
            }
            None => Ok((0..n).map(|k| format!("{default}{k}")).collect()),
        }
    };
    Ok(LstmModel {
        input_activation,
        dims: LstmDims {
            input: i,
            embed: e,
            hidden: h,
            output: o,
        },
        input_names: names("input_names", "x", i)?,
        output_names: names("output_names", "y", o)?,
        preset: meta
            .get("preset")
            .map_or_else(|| "custom".to_string(), |s| s.to_string()),
        input_mean: sized(input_mean, i, 0.0, "the input normalisation's mean")?,
        input_std: sized(input_std, i, 1.0, "the input normalisation's std")?,
        w_in,
        b_in,
        w_ih,
        w_hh,
        b_ih,
        b_hh,
        w_out,
        b_out,
        output_mean: sized(output_mean, o, 0.0, "the output scaling's mean")?,
        output_std: sized(output_std, o, 1.0, "the output scaling's std")?,
        linear: Vec::new(),
        envelope: Vec::new(),
    })
}

/// Checks that an LSTM initial state is zero: a zero constant, or `ConstantOfShape` with
/// a zero (or absent) value.
fn zero_state(g: &Graph, name: &str) -> Result<()> {
    if let Some(c) = g.constant(name) {
        if c.values.iter().all(|&v| v == 0.0) {
            return Ok(());
        }
        bail!("'{name}' is a non-zero constant: only a zero initial state is supported");
    }
    let producer = g
        .nodes
        .iter()
        .find(|n| n.output.iter().any(|o| o == name))
        .with_context(|| {
            format!("'{name}' is a graph input: only a zero initial state is supported")
        })?;
    if producer.op_type != "ConstantOfShape" {
        bail!(
            "{} makes it: only a zero initial state is supported",
            node_label(producer)
        );
    }
    if let Some(t) = attr(producer, "value").and_then(|a| a.t.as_ref()) {
        let v = tensor_values(t).with_context(|| node_label(producer))?;
        if v.values.iter().any(|&x| x != 0.0) {
            bail!(
                "{} fills {:?}: only a zero initial state is supported",
                node_label(producer),
                v.values
            );
        }
    }
    Ok(())
}
