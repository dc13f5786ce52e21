//! ONNX interchange: graphs outside the supported pattern are refused naming the node, and
//! an input layer straight into the LSTM imports as the linear input layer (the committed
//! export of the PyTorch network, scripts/make_onnx_fixture.py, `torch.onnx.export`).
use compnet::onnx;
use onnx_protobuf::{Message, ModelProto};
use std::path::{Path, PathBuf};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

/// The fixture's graph after `edit`, as bytes.
fn edited(edit: impl Fn(&mut ModelProto)) -> Vec<u8> {
    let bytes = std::fs::read(fixture("torch_lstm.onnx")).unwrap();
    let mut m = ModelProto::parse_from_bytes(&bytes).unwrap();
    edit(&mut m);
    m.write_to_bytes().unwrap()
}

fn refused(what: &str, bytes: &[u8], expect: &str) {
    let e = format!("{:#}", onnx::parse_onnx_model(bytes).expect_err(what));
    assert!(e.contains(expect), "{what}: {e}");
}

fn node_mut<'a>(m: &'a mut ModelProto, op: &str) -> &'a mut onnx_protobuf::NodeProto {
    m.graph
        .as_mut()
        .unwrap()
        .node
        .iter_mut()
        .find(|n| n.op_type == op)
        .unwrap()
}

#[test]
fn graphs_outside_the_supported_network_are_refused_naming_the_node() {
    refused(
        "a ReLU input activation",
        &edited(|m| node_mut(m, "Tanh").op_type = "Relu".into()),
        "node '/Tanh' (Relu): the input layer must be followed by Tanh",
    );
    refused(
        "a bidirectional LSTM",
        &edited(|m| {
            let n = node_mut(m, "LSTM");
            let mut a = onnx_protobuf::AttributeProto::new();
            a.name = "direction".into();
            a.s = b"bidirectional".to_vec();
            n.attribute.push(a);
        }),
        "node '/lstm/LSTM' (LSTM): direction",
    );
    refused(
        "a used final state",
        &edited(|m| {
            let g = m.graph.as_mut().unwrap();
            let h = g.node.iter().find(|n| n.op_type == "LSTM").unwrap().output[1].clone();
            let mut extra = onnx_protobuf::NodeProto::new();
            extra.name = "/uses_state".into();
            extra.op_type = "Relu".into();
            extra.input.push(h);
            extra.output.push("state_relu".into());
            g.node.push(extra);
        }),
        "node '/lstm/LSTM' (LSTM): its output 1 (final state) is used",
    );
    refused(
        "a node after the output layer",
        &edited(|m| {
            let g = m.graph.as_mut().unwrap();
            let last = g.node.last_mut().unwrap();
            last.output[0] = "y_pre".into();
            let mut extra = onnx_protobuf::NodeProto::new();
            extra.name = "/clamp".into();
            extra.op_type = "Relu".into();
            extra.input.push("y_pre".into());
            extra.output.push("y".into());
            g.node.push(extra);
        }),
        "node '/clamp' (Relu) after the output layer is not supported",
    );
    refused(
        "a second consumer",
        &edited(|m| {
            let g = m.graph.as_mut().unwrap();
            let mut extra = onnx_protobuf::NodeProto::new();
            extra.name = "/side".into();
            extra.op_type = "Relu".into();
            extra.input.push("/Tanh_output_0".into());
            extra.output.push("side".into());
            g.node.push(extra);
        }),
        "feeds 2 nodes",
    );
    refused(
        "a hostile hidden size",
        &edited(|m| {
            let n = node_mut(m, "LSTM");
            for a in n.attribute.iter_mut().filter(|a| a.name == "hidden_size") {
                a.i = i64::MAX;
            }
        }),
        "node '/lstm/LSTM' (LSTM): hidden_size 9223372036854775807 is not in 1..=65536",
    );
    let bytes = std::fs::read(fixture("torch_lstm.onnx")).unwrap();
    refused(
        "a truncated file",
        &bytes[..bytes.len() / 2],
        "not an ONNX model",
    );
}

#[test]
fn an_input_layer_straight_into_the_lstm_imports_as_the_linear_input_layer() {
    // The fixture with its Tanh removed: what `torch.onnx.export` writes for a plain
    // `nn.Linear` input layer.
    let bytes = edited(|m| {
        let g = m.graph.as_mut().unwrap();
        let k = g.node.iter().position(|n| n.op_type == "Tanh").unwrap();
        let tanh = g.node.remove(k);
        for n in &mut g.node {
            for i in &mut n.input {
                if *i == tanh.output[0] {
                    *i = tanh.input[0].clone();
                }
            }
        }
    });
    let linear = onnx::parse_onnx_model(&bytes).unwrap();
    let tanh = onnx::read_onnx_model(&fixture("torch_lstm.onnx")).unwrap();
    assert_eq!(
        linear.input_activation,
        firmware::nn::format::InputActivation::Linear
    );
    assert_eq!(
        tanh.input_activation,
        firmware::nn::format::InputActivation::Tanh
    );
    assert_eq!(linear.tensors(), tanh.tensors());
}

/// Every exporter variant of scripts/make_onnx_fixture.py: (file, onnxruntime reference).
const VARIANTS: [(&str, &str); 4] = [
    ("torch_lstm.onnx", "onnx_reference.csv"),
    (
        "torch_lstm_time_first.onnx",
        "onnx_reference_time_first.csv",
    ),
    ("torch_lstm_dynamo.onnx", "onnx_reference_dynamo.csv"),
    (
        "torch_lstm_dynamo_batch_first.onnx",
        "onnx_reference_dynamo_batch_first.csv",
    ),
];

#[test]
fn both_exporters_either_layout_import_to_the_safetensors_network_and_match_onnxruntime() {
    // The same seeded network in every file: TorchScript and the dynamo-based default
    // exporter, batch-first and time-first (PyTorch's default) LSTMs.
    let st = compnet::io::read_model(&fixture("torch_lstm.safetensors")).unwrap();
    for (file, reference) in VARIANTS {
        let m = onnx::read_onnx_model(&fixture(file)).unwrap();
        assert_eq!(m.dims, st.dims, "{file}");
        assert_eq!(m.tensors(), st.tensors(), "{file}");
        assert_eq!(m.input_names, st.input_names, "{file}");
        // `io::read_model` takes the ONNX file by its extension.
        assert_eq!(
            compnet::io::read_model(&fixture(file)).unwrap().tensors(),
            st.tensors()
        );
        let err = compnet::io::check_reference(&m, &fixture(reference)).unwrap();
        println!("{file}: firmware f32 step vs {reference}: max error {err:.3e} of the output RMS");
        assert!(err < 1e-5, "{file}: {err}");
    }
}

#[test]
fn a_two_layer_lstm_is_refused_naming_the_layers_and_the_firmwares_one() {
    for file in ["torch_lstm_2layer.onnx", "torch_lstm_2layer_dynamo.onnx"] {
        let e = format!("{:#}", onnx::read_onnx_model(&fixture(file)).unwrap_err());
        assert!(
            e.contains(file)
                && e.contains("the graph has 2 LSTM layers")
                && e.contains("the firmware runs one LSTM layer"),
            "{file}: {e}"
        );
    }
}

#[test]
fn a_reshape_that_does_not_drop_the_direction_axis_is_refused() {
    let bytes = std::fs::read(fixture("torch_lstm_dynamo.onnx")).unwrap();
    let mut m = ModelProto::parse_from_bytes(&bytes).unwrap();
    let g = m.graph.as_mut().unwrap();
    let shape = g
        .node
        .iter()
        .find(|n| n.op_type == "Reshape")
        .unwrap()
        .input[1]
        .clone();
    let t = g.initializer.iter_mut().find(|t| t.name == shape);
    let t = match t {
        Some(t) => t,
        None => panic!("the Reshape's shape {shape} is not an initializer"),
    };
    // [T, B, H] -> [T, B * H / 2, 2]: same size, other meaning.
    t.raw_data.clear();
    t.int64_data = vec![400, 8, 2];
    let e = format!(
        "{:#}",
        onnx::parse_onnx_model(&m.write_to_bytes().unwrap()).unwrap_err()
    );
    assert!(
        e.contains("Reshape") && e.contains("expected [time, batch, 16]"),
        "{e}"
    );
}

#[test]
fn a_node_without_an_output_is_refused_not_a_panic() {
    // Found by the fuzzer on the dynamo export: an `Add` with its output removed.
    let bytes = std::fs::read(fixture("torch_lstm_dynamo.onnx")).unwrap();
    let mut m = ModelProto::parse_from_bytes(&bytes).unwrap();
    let n = m
        .graph
        .as_mut()
        .unwrap()
        .node
        .iter_mut()
        .find(|n| n.op_type == "Add")
        .unwrap();
    n.output.clear();
    let name = n.name.clone();
    refused(
        "an Add without output",
        &m.write_to_bytes().unwrap(),
        &format!("node '{name}' (Add): has no output"),
    );
}
