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
