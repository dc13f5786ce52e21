//! The LSTM compensation network: firmware step vs candle graph, PyTorch interchange,
//! reset semantics, bad input, and learning a synthetic system with memory.
use candle_core::Device;
use compnet::data::{FeatureSpec, Sequence, Table};
use compnet::model::normalised_sequence;
use compnet::train::{TrainConfig, new_model, train};
use compnet::{LstmModel, Net, eval, io};
use firmware::nn::format::InputActivation;
use firmware::nn::reference::LstmDims;
use std::path::{Path, PathBuf};

#[path = "support/torch_files.rs"]
mod torch_files;
use torch_files::torch_style_file;

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")
}

/// A paper-size model with non-trivial normalisation, and a 1000-step input sequence.
fn paper_model() -> (LstmModel, Vec<Vec<f32>>) {
    let mut m = LstmModel::init(
        LstmDims {
            input: 9,
            embed: 64,
            hidden: 64,
            output: 3,
        },
        7,
    );
    m.input_mean = (0..9).map(|k| k as f32 * 0.3 - 1.0).collect();
    m.input_std = (0..9).map(|k| 0.5 + k as f32 * 0.2).collect();
    m.output_mean = vec![2.0, -1.0, 0.5];
    m.output_std = vec![3.0, 0.5, 1.5];
    let xs = (0..1000)
        .map(|t| {
            (0..9)
                .map(|k| {
                    2.0 * (t as f32 * 0.017 * (k + 1) as f32).sin()
                        + ((t * 7 + k * 13) % 11) as f32 * 0.1
                })
                .collect()
        })
        .collect();
    (m, xs)
}

fn max_rel(a: &[Vec<f32>], b: &[Vec<f32>]) -> f64 {
    let rms = (b.iter().flatten().map(|v| (*v as f64).powi(2)).sum::<f64>()
        / b.iter().flatten().count() as f64)
        .sqrt();
    a.iter()
        .flatten()
        .zip(b.iter().flatten())
        .map(|(x, y)| (*x as f64 - *y as f64).abs())
        .fold(0.0, f64::max)
        / rms
}

#[test]
fn firmware_stream_matches_the_candle_forward_over_1000_steps() {
    for activation in [InputActivation::Tanh, InputActivation::Linear] {
        let (mut m, xs) = paper_model();
        m.input_activation = activation;
        firmware_stream_matches_candle(&m, &xs);
    }
}

fn firmware_stream_matches_candle(m: &LstmModel, xs: &[Vec<f32>]) {
    let dev = Device::Cpu;
    let net = Net::from_model(m, &dev).unwrap();
    let y = net
        .forward(&normalised_sequence(m, xs, &dev).unwrap())
        .unwrap();
    let y: Vec<Vec<f32>> = y.squeeze(0).unwrap().to_vec2().unwrap();
    let candle: Vec<Vec<f32>> = y
        .iter()
        .map(|r| {
            r.iter()
                .enumerate()
                .map(|(k, v)| v * m.output_std[k] + m.output_mean[k])
                .collect()
        })
        .collect();
    let fw = m.stream(xs).unwrap();
    let err = max_rel(&fw, &candle);
    println!(
        "{} input layer: firmware vs candle over 1000 steps: max error {err:.2e} of the output RMS",
        m.input_activation.name()
    );
    assert!(err < 1e-5, "{err}");
}

#[test]
fn a_reset_mid_sequence_equals_a_fresh_start() {
    let (m, xs) = paper_model();
    let mut s = m.streamer().unwrap();
    for x in &xs[..400] {
        s.step(x).unwrap();
    }
    s.reset();
    let continued: Vec<Vec<f32>> = xs[400..].iter().map(|x| s.step(x).unwrap()).collect();
    assert_eq!(continued, m.stream(&xs[400..]).unwrap());
}

#[test]
fn a_pytorch_model_imports_and_matches_its_reference() {
    let m = io::read_model(&fixtures().join("torch_lstm.safetensors")).unwrap();
    assert_eq!(
        m.dims,
        LstmDims {
            input: 5,
            embed: 12,
            hidden: 16,
            output: 2
        }
    );
    let err = compnet::io::check_reference(&m, &fixtures().join("torch_reference.csv")).unwrap();
    println!("firmware f32 step vs PyTorch reference: max error {err:.2e} of the output RMS");
    assert!(err < 1e-5, "{err}");
    // Round trip through our writer is lossless.
    let bytes = io::model_bytes(&m).unwrap();
    let again = io::parse_model(&bytes).unwrap();
    assert_eq!(again, m);
    // The same model gives the same bytes (the metadata keys in one order).
    for _ in 0..8 {
        assert_eq!(io::model_bytes(&again).unwrap(), bytes);
    }
}

#[test]
fn a_pytorch_model_with_a_linear_input_layer_imports_and_matches_its_reference() {
    use firmware::nn::format::InputActivation;
    let path = fixtures().join("torch_linear.safetensors");
    let m = io::read_model(&path).unwrap();
    assert_eq!(m.input_activation, InputActivation::Linear);
    let err =
        compnet::io::check_reference(&m, &fixtures().join("torch_linear_reference.csv")).unwrap();
    println!(
        "linear input layer: firmware f32 step vs PyTorch: max error {err:.2e} of the output RMS"
    );
    assert!(err < 1e-5, "{err}");
    // Run as tanh, the same weights are far off: the activation is what was imported.
    let mut as_tanh = m.clone();
    as_tanh.input_activation = InputActivation::Tanh;
    let wrong =
        compnet::io::check_reference(&as_tanh, &fixtures().join("torch_linear_reference.csv"))
            .unwrap();
    println!("the same weights run with tanh: max error {wrong:.2e} of the output RMS");
    assert!(wrong > 1e-2, "{wrong}");
    // Our writer keeps the activation; the caller's word must agree with the metadata.
    let again = io::parse_model(&io::model_bytes(&m).unwrap()).unwrap();
    assert_eq!(again, m);
    assert!(io::read_model_with(&path, Some("linear")).is_ok());
    let e = format!(
        "{:#}",
        io::read_model_with(&path, Some("tanh")).unwrap_err()
    );
    assert!(e.contains("disagrees"), "{e}");
}

/// A nonlinear system with memory: a leaky integrator of a product of inputs.
fn synthetic(n: usize, seed: u32) -> Table {
    let mut s = 0.0f32;
    let mut cols = vec![Vec::new(), Vec::new(), Vec::new()];
    for t in 0..n {
        let tf = t as f32 + seed as f32 * 1000.0;
        let u1 = (tf * 0.031).sin() + 0.5 * (tf * 0.0071).sin();
        let u2 = (tf * 0.017).cos() * (1.0 + 0.5 * (tf * 0.0023).sin());
        s = 0.95 * s + 0.3 * u1.tanh() * u2;
        cols[0].push(u1);
        cols[1].push(u2);
        cols[2].push(s + 0.2 * u1 * u1);
    }
    Table {
        path: "synthetic".into(),
        names: vec!["u1".into(), "u2".into(), "y".into()],
        columns: cols,
    }
}

#[test]
fn training_learns_a_system_with_memory() {
    let spec = FeatureSpec::custom(&["u1".into(), "u2".into()], &["y".into()], 0).unwrap();
    let seq = spec.sequence(&synthetic(6000, 0)).unwrap();
    let cfg = TrainConfig {
        embed: 16,
        hidden: 16,
        window: 50,
        burn_in: 25,
        batch: 16,
        lr: Some(0.003),
        epochs: 80,
        patience: 20,
        val_fraction: 0.2,
        test_fraction: 0.2,
        progress: false,
        ..Default::default()
    };
    let (tr, va, te) = seq.split(cfg.val_fraction, cfg.test_fraction).unwrap();
    let init = new_model(
        &tr,
        spec.inputs.clone(),
        spec.output_names(),
        "custom",
        &cfg,
    )
    .unwrap();
    let (m, h) = train(&init, &[&tr], &[&va], &cfg).unwrap();
    let before = eval::evaluate(&init, &te).unwrap()[0].rms_after;
    let after = eval::evaluate(&m, &te).unwrap()[0].rms_after;
    let std = compnet::data::mean_std(&te.targets).1[0] as f64;
    println!(
        "val loss {:.4} -> {:.4}; streamed test RMS {before:.4} -> {after:.4} (target std {std:.4})",
        h.val[0], h.val[h.best_epoch]
    );
    assert!(
        after < 0.15 * std,
        "streamed test RMS {after} vs target std {std}"
    );
    assert!(h.val[h.best_epoch] < 0.3 * h.val[0]);
    // Same seed, same model.
    let (m2, _) = train(&init, &[&tr], &[&va], &cfg).unwrap();
    assert_eq!(m, m2);
    // The training kernel runs tanh: a linear input layer is refused, not retrained as
    // another network.
    let mut linear = init.clone();
    linear.input_activation = firmware::nn::format::InputActivation::Linear;
    let e = format!("{:#}", train(&linear, &[&tr], &[&va], &cfg).unwrap_err());
    assert!(e.contains("linear"), "{e}");
}

#[test]
fn a_model_for_other_features_is_refused() {
    let m = io::read_model(&fixtures().join("torch_lstm.safetensors")).unwrap();
    let e = FeatureSpec::paper(&[4, 5, 6])
        .check_model(&m)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("do not match") && e.contains("tau_model_j4"),
        "{e}"
    );
}

#[test]
fn presets_align_inputs_and_targets() {
    let names = ["q_j4", "qd_j4", "tau_meas_j4", "tau_model_j4"];
    let table = Table {
        path: "t".into(),
        names: names.iter().map(|s| s.to_string()).collect(),
        columns: (0..4)
            .map(|c| (0..5).map(|t| (10 * c + t) as f32).collect())
            .collect(),
    };
    let p = FeatureSpec::paper(&[4]).sequence(&table).unwrap();
    assert_eq!(p.len(), 4);
    assert_eq!(p.inputs[0], vec![30.0, 20.0, 0.0]);
    assert_eq!(p.targets[0], vec![21.0]);
    assert_eq!(p.offset[0], vec![0.0]);
    assert_eq!(p.model_only[0], vec![31.0]);
    assert_eq!(p.persistence[0], vec![Some(20.0)]);
    let f = FeatureSpec::feedforward(&[4]).sequence(&table).unwrap();
    assert_eq!(f.len(), 5);
    assert_eq!(f.inputs[2], vec![32.0, 2.0, 12.0]);
    assert_eq!(f.targets[2], vec![22.0 - 32.0]);
    assert_eq!(f.offset[2], vec![32.0]);
    assert_eq!(f.model_only[2], vec![0.0]);
    assert_eq!(f.persistence[2], vec![None]);
    // The increment form (`paper_increment`, `minus_now`): the target, the model's
    // prediction and persistence all relative to the subtracted column at the input step.
    let inc = FeatureSpec::paper_increment(&[4]);
    assert_eq!(inc.inputs, FeatureSpec::paper(&[4]).inputs);
    assert_eq!(inc.output_names(), ["tau_meas_j4@+1-tau_meas_j4@0"]);
    use compnet::data::is_increment_name as loop_closing;
    assert!(loop_closing(&inc.output_names()[0]));
    for spec in [
        FeatureSpec::paper(&[4]),
        FeatureSpec::paper_relative(&[4]),
        FeatureSpec::feedforward(&[4]),
        FeatureSpec::drive(&[4]),
    ] {
        assert!(!loop_closing(&spec.output_names()[0]), "{spec:?}");
    }
    let p = inc.sequence(&table).unwrap();
    assert_eq!(p.targets[0], vec![1.0]);
    assert_eq!(p.offset[0], vec![20.0]);
    assert_eq!(p.model_only[0], vec![11.0]);
    assert_eq!(p.persistence[0], vec![Some(0.0)]);
    // The relative form: the measured residual in, everything relative to the model's
    // torque at the target step out.
    let rel = FeatureSpec::paper_relative(&[4]);
    assert_eq!(rel.preset, "paper_relative");
    assert_eq!(
        rel.inputs,
        ["tau_model_j4", "tau_meas_j4-tau_model_j4", "q_j4"]
    );
    assert_eq!(rel.output_names(), ["tau_meas_j4-tau_model_j4@+1"]);
    let p = rel.sequence(&table).unwrap();
    assert_eq!(p.inputs[0], vec![30.0, 20.0 - 30.0, 0.0]);
    assert_eq!(p.targets[0], vec![21.0 - 31.0]);
    assert_eq!(p.offset[0], vec![31.0]);
    assert_eq!(p.model_only[0], vec![0.0]);
    assert_eq!(p.persistence[0], vec![Some(20.0 - 31.0)]);
    let _ = Sequence::default();
}

/// The `drive` preset's linear stage: least squares recovers a target that is a
/// combination of the friction features, the stage round-trips through safetensors, the
/// streamed output adds it to the network's, and a linear stage on another preset is
/// refused.
#[test]
fn drive_linear_stage_is_fitted_stored_and_streamed() {
    use compnet::{io, train};
    use firmware::features::{
        DRIVE_INPUTS_PER_JOINT as PER_JOINT, FRICTION_FEATURES, friction_features,
    };
    let joints = [4, 5];
    let spec = FeatureSpec::drive(&joints);
    let truth: Vec<f32> = (0..2 * FRICTION_FEATURES)
        .map(|k| ((k * 7 % 11) as f32 - 5.0) * 0.1)
        .collect();
    let mut seq = Sequence::default();
    for t in 0..400 {
        let x: Vec<f32> = (0..2 * PER_JOINT)
            .map(|i| ((t * (i + 3)) as f32 * 0.013).sin() * (1.0 + i as f32 * 0.3))
            .collect();
        let y: Vec<f32> = (0..2)
            .map(|k| {
                let xk: [f32; PER_JOINT] = std::array::from_fn(|kind| x[kind * 2 + k]);
                let f = friction_features(&xk);
                (0..FRICTION_FEATURES)
                    .map(|c| truth[k * FRICTION_FEATURES + c] * f[c])
                    .sum()
            })
            .collect();
        seq.inputs.push(x);
        seq.targets.push(y);
    }
    let w = train::fit_linear_stage(std::slice::from_ref(&seq), 2).unwrap();
    let worst = w
        .iter()
        .zip(&truth)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-3, "coefficients off by {worst}");
    let mut left = vec![seq.clone()];
    train::subtract_linear_stage(&w, &mut left);
    let rest = left[0]
        .targets
        .iter()
        .flatten()
        .fold(0.0f32, |m, v| m.max(v.abs()));
    assert!(rest < 1e-3, "the stage leaves {rest}");

    let mut m = LstmModel::init(
        firmware::nn::reference::LstmDims {
            input: 2 * PER_JOINT,
            embed: 4,
            hidden: 4,
            output: 2,
        },
        3,
    );
    m.preset = "drive".into();
    m.input_names = spec.inputs.clone();
    m.output_names = spec.output_names();
    let plain = m.stream(&seq.inputs).unwrap();
    m.linear = w.clone();
    let with = m.stream(&seq.inputs).unwrap();
    for (t, (a, b)) in plain.iter().zip(&with).enumerate() {
        for k in 0..2 {
            let want = a[k] + seq.targets[t][k];
            assert!(
                (b[k] - want).abs() < 1e-3,
                "step {t} output {k}: {} vs {want}",
                b[k]
            );
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("drive.safetensors");
    io::write_model(&m, &path).unwrap();
    assert_eq!(io::read_model(&path).unwrap(), m);
    m.preset = "feedforward".into();
    let e = format!("{:#}", m.validate().unwrap_err());
    assert!(e.contains("linear.weight") && e.contains("drive"), "{e}");
}

#[test]
fn pytorch_files_that_would_import_wrongly_are_refused_naming_why() {
    use firmware::nn::format::InputActivation;
    let dir = tempfile::tempdir().unwrap();
    let m = LstmModel::init(
        LstmDims {
            input: 3,
            embed: 4,
            hidden: 5,
            output: 2,
        },
        4,
    );
    // No metadata: the input activation must be said, and must be one the firmware runs.
    let bare = torch_style_file(dir.path(), &m, &[], &[]);
    let e = format!("{:#}", io::read_model(&bare).unwrap_err());
    assert!(e.contains("--input-activation"), "{e}");
    let ok = io::read_model_with(&bare, Some("tanh")).expect("said tanh");
    assert_eq!(ok.w_ih, m.w_ih);
    assert_eq!(ok.input_activation, InputActivation::Tanh);
    let linear = io::read_model_with(&bare, Some("linear")).expect("said linear");
    assert_eq!(linear.input_activation, InputActivation::Linear);
    // An activation the firmware does not run is named.
    let relu = torch_style_file(dir.path(), &m, &[], &[("input_activation", "relu")]);
    let e = format!("{:#}", io::read_model(&relu).unwrap_err());
    assert!(e.contains("relu") && e.contains("not supported"), "{e}");
    // A 2-layer nn.LSTM: the second layer's tensors are named, not dropped.
    let h4 = 4 * 5;
    let extra = [
        ("lstm.weight_ih_l1", vec![h4, 5], vec![0.1; h4 * 5]),
        ("lstm.weight_hh_l1", vec![h4, 5], vec![0.1; h4 * 5]),
    ];
    let two = torch_style_file(dir.path(), &m, &extra, &[("input_activation", "tanh")]);
    let e = format!("{:#}", io::read_model(&two).unwrap_err());
    assert!(
        e.contains("lstm.weight_hh_l1")
            && e.contains("lstm.weight_ih_l1")
            && e.contains("second LSTM layer"),
        "{e}"
    );
    // A bias the layout does not expect (here a LayerNorm's after the input layer, and
    // an LSTM projection's weight) is named, not dropped.
    let extra = [
        ("input_norm.bias", vec![4], vec![0.5; 4]),
        ("lstm.weight_hr_l0", vec![5, 5], vec![0.1; 25]),
    ];
    let odd = torch_style_file(dir.path(), &m, &extra, &[("input_activation", "tanh")]);
    let e = format!("{:#}", io::read_model(&odd).unwrap_err());
    assert!(
        e.contains("input_norm.bias") && e.contains("lstm.weight_hr_l0") && e.contains("not use"),
        "{e}"
    );
    // Metadata and the caller disagree.
    let tagged = torch_style_file(dir.path(), &m, &[], &[("input_activation", "tanh")]);
    let e = format!(
        "{:#}",
        io::read_model_with(&tagged, Some("linear")).unwrap_err()
    );
    assert!(e.contains("disagrees"), "{e}");
}
