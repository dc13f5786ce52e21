//! PyTorch interchange through `model-export import`: bad safetensors refused naming the
//! tensor and the file, nothing written; a linear input layer taken from the flag or the
//! file's metadata (the network itself: `crates/compnet/tests/lstm.rs`).
use compnet::{LstmModel, io};
use std::path::{Path, PathBuf};
use std::process::Command;

#[path = "../../crates/compnet/tests/support/torch_files.rs"]
mod torch_files;
use torch_files::torch_style_file;

fn fixtures() -> PathBuf {
    test_support::workspace_root().join("crates/compnet/tests/fixtures")
}

fn edit_fixture(edit: impl Fn(&mut LstmModel)) -> Vec<u8> {
    let mut m = io::read_model(&fixtures().join("torch_lstm.safetensors")).unwrap();
    edit(&mut m);
    // Bypass validation to produce a bad file.
    let dims = m.dims;
    let shapes = |n: &str, v: &Vec<f32>| -> Vec<usize> {
        match n {
            "input.weight" => vec![dims.embed, v.len() / dims.embed],
            "lstm.weight_ih_l0" | "lstm.weight_hh_l0" => {
                vec![4 * dims.hidden, v.len() / (4 * dims.hidden)]
            }
            "output.weight" => vec![dims.output, v.len() / dims.output],
            _ => vec![v.len()],
        }
    };
    let bufs: Vec<(String, Vec<usize>, Vec<u8>)> = m
        .tensors()
        .iter()
        .map(|(n, v)| {
            (
                n.to_string(),
                shapes(n, v),
                v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            )
        })
        .collect();
    let views: Vec<(String, safetensors::tensor::TensorView)> = bufs
        .iter()
        .filter(|(n, _, b)| !(b.is_empty() && n == "lstm.bias_hh_l0"))
        .map(|(n, s, b)| {
            (
                n.clone(),
                safetensors::tensor::TensorView::new(safetensors::Dtype::F32, s.clone(), b)
                    .unwrap(),
            )
        })
        .collect();
    safetensors::serialize(views, None).unwrap()
}

#[test]
fn bad_safetensors_are_refused_with_the_tensor_named() {
    let missing = edit_fixture(|m| m.b_hh.clear());
    let e = io::parse_model(&missing).unwrap_err().to_string();
    assert!(e.contains("missing tensor `lstm.bias_hh_l0`"), "{e}");
    let misshaped = edit_fixture(|m| m.w_hh.truncate(4 * 16 * 15));
    let e = format!("{:#}", io::parse_model(&misshaped).unwrap_err());
    assert!(
        e.contains("lstm.weight_hh_l0") && e.contains("[64, 16]"),
        "{e}"
    );
    let nan = edit_fixture(|m| m.w_ih[17] = f32::NAN);
    let e = format!("{:#}", io::parse_model(&nan).unwrap_err());
    assert!(
        e.contains("lstm.weight_ih_l0") && e.contains("17") && e.contains("NaN"),
        "{e}"
    );
    let e = format!(
        "{:#}",
        io::parse_model(b"not a safetensors file").unwrap_err()
    );
    assert!(e.contains("not a safetensors file"), "{e}");

    // The CLI exits non-zero, names the file and writes nothing.
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.safetensors");
    std::fs::write(&bad, &nan).unwrap();
    let out_path = dir.path().join("out.safetensors");
    let out = Command::new(env!("CARGO_BIN_EXE_model-export"))
        .args(["import", "--network"])
        .arg(&bad)
        .arg("--out")
        .arg(&out_path)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.safetensors") && err.contains("NaN"),
        "{err}"
    );
    assert!(!out_path.exists());
}

#[test]
fn import_takes_a_linear_input_layer_from_the_flag_or_the_metadata() {
    use firmware::nn::format::InputActivation;
    let dir = tempfile::tempdir().unwrap();
    let fixture = io::read_model(&fixtures().join("torch_linear.safetensors")).unwrap();
    // The same tensors without metadata, as a plain torch save would write them.
    let bare = torch_style_file(dir.path(), &fixture, &[], &[]);
    let reference = fixtures().join("torch_linear_reference.csv");
    let import = |flag: Option<&str>, out: &Path| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_model-export"));
        c.args(["import", "--network"])
            .arg(&bare)
            .arg("--out")
            .arg(out)
            .arg("--reference")
            .arg(&reference);
        if let Some(f) = flag {
            c.args(["--input-activation", f]);
        }
        c.output().unwrap()
    };
    // Without the flag: refused, nothing written.
    let out_path = dir.path().join("none.safetensors");
    let out = import(None, &out_path);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--input-activation"), "{err}");
    assert!(!out_path.exists());
    // Said wrongly: the reference check fails and nothing is written.
    let out_path = dir.path().join("tanh.safetensors");
    let out = import(Some("tanh"), &out_path);
    assert!(!out.status.success());
    assert!(!out_path.exists());
    // Said right: matches PyTorch and writes a file that says linear.
    let out_path = dir.path().join("linear.safetensors");
    let out = import(Some("linear"), &out_path);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let written = io::read_model(&out_path).unwrap();
    assert_eq!(written.input_activation, InputActivation::Linear);
    assert_eq!(written.w_in, fixture.w_in);
}
