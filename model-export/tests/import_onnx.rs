//! ONNX interchange through the command line: the committed export of the PyTorch network
//! (scripts/make_onnx_fixture.py, `torch.onnx.export`) imports to the same model as its
//! safetensors file and the firmware step matches PyTorch's outputs to 1e-6 (refused graphs:
//! `crates/compnet/tests/onnx.rs`).
use clap::Parser;
use compnet::io::check_reference;
use compnet::{io, onnx};
use model_export::cli::{Cli, run};
use std::path::PathBuf;

fn fixture(name: &str) -> PathBuf {
    test_support::workspace_root()
        .join("crates/compnet/tests/fixtures")
        .join(name)
}

#[test]
fn the_onnx_export_imports_like_its_safetensors_and_matches_pytorch() {
    let m = onnx::read_onnx_model(&fixture("torch_lstm.onnx")).unwrap();
    // The same network (same seed and sizes) as the safetensors fixture: weight for weight.
    let st = io::read_model(&fixture("torch_lstm.safetensors")).unwrap();
    assert_eq!(m.dims, st.dims);
    assert_eq!(m.tensors(), st.tensors());
    assert_eq!(m.input_names, st.input_names);
    assert_eq!(m.output_names, st.output_names);
    let err = check_reference(&m, &fixture("onnx_reference.csv")).unwrap();
    println!("ONNX import, firmware f32 step vs PyTorch: max error {err:.3e} of the output RMS");
    assert!(err < 1e-6, "{err}");

    // Through the command line.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.safetensors");
    let (model, reference) = (fixture("torch_lstm.onnx"), fixture("onnx_reference.csv"));
    let args = [
        "model-export",
        "import",
        "--network",
        model.to_str().unwrap(),
        "--reference",
        reference.to_str().unwrap(),
        "--tolerance",
        "1e-6",
        "--out",
        out.to_str().unwrap(),
    ];
    run(Cli::try_parse_from(args).unwrap()).unwrap();
    assert_eq!(io::read_model(&out).unwrap().tensors(), st.tensors());
}
