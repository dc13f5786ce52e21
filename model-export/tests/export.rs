//! `model-export export`: the committed golden model files are what the exporter
//! writes today (deterministic, in sync); quantised outputs track f32; bad input is
//! refused with a clear error and leaves no file behind.
use compnet::model::LstmModel;
use firmware::features::DRIVE_INPUTS_PER_JOINT;
use firmware::nn::reference::LstmDims;
use fw_export::{ExportError, Exported, Placement, Precision, WeightsIn};
use model_export::cmd::export::ExportArgs;
use std::path::{Path, PathBuf};

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("workspace")
        .to_path_buf()
}

fn args(out: PathBuf, precision: Precision) -> ExportArgs {
    ExportArgs {
        network: None,
        dims: vec![5, 12, 8, 3],
        seed: 7,
        preset: firmware::nn::format::FeaturePreset::Custom,
        joints: vec![1, 2, 3],
        control_rate_hz: 100,
        precision,
        robot: None,
        out,
        budgets: Some(workspace().join("host-tests/budgets.toml")),
        weights_in: WeightsIn::Auto,
        self_check_steps: 10_000,
        accuracy_log: None,
        identified: None,
        chain: Default::default(),
        report: None,
        gate_data: Vec::new(),
        allow_worse: false,
        adapt_time_constant_s: None,
        monitor_window_s: None,
        envelope_data: Vec::new(),
        no_envelope: false,
        no_monitor: false,
    }
}

#[test]
fn regenerating_the_golden_models_gives_the_committed_files() {
    let dir = tempfile::tempdir().expect("tempdir");
    for p in Precision::ALL {
        let out = dir.path().join(format!("golden_{}.rs", p.name()));
        let a = args(out.clone(), p);
        let m = model_export::cmd::export::model(&a).expect("model");
        model_export::cmd::export::export(&m, &a).expect("export");
        let fresh = std::fs::read_to_string(&out).expect("read");
        let committed = workspace().join(format!("test-kit/src/fixtures/golden_{}.rs", p.name()));
        let committed = std::fs::read_to_string(&committed).expect("committed golden file");
        assert!(
            fresh == committed,
            "{}: regenerate with firmware/scripts/regenerate-models.sh",
            p.name()
        );
        assert!(fresh.contains("pub const CONTENT_HASH: u64 = 0x"));
    }
}

#[test]
fn quantised_networks_track_the_f32_step_on_the_pytorch_fixture() {
    let fx = workspace().join("crates/compnet/tests/fixtures/torch_lstm.safetensors");
    let m = compnet::io::read_model(&fx).expect("fixture");
    let inputs = fw_export::golden_inputs(m.dims.input, 400);
    let table =
        fw_export::accuracy_markdown(&fw_export::accuracy(&m, &inputs, None).expect("accuracy"));
    println!("{table}");
    let reference = m.stream(&inputs).expect("f32");
    // RMS of the difference to the f32 firmware step, per output, over 400 steps.
    for (p, tol) in [
        (Precision::F32, 1e-6f64),
        (Precision::Int16, 1.5e-3),
        (Precision::Int8, 3e-3),
    ] {
        let y = Exported::new(&m, p).expect("export").stream(&inputs);
        for j in 0..m.dims.output {
            let ms = y
                .iter()
                .zip(&reference)
                .map(|(a, b)| ((a[j] - b[j]) as f64).powi(2))
                .sum::<f64>()
                / y.len() as f64;
            assert!(
                ms.sqrt() <= tol,
                "{} output {j}: RMS vs f32 {}",
                p.name(),
                ms.sqrt()
            );
        }
    }
}

/// Max |exported - PyTorch| over the PyTorch reference run, per output, relative to the
/// output's RMS.
fn error_vs_reference(y: &[Vec<f32>], reference: &[Vec<f32>]) -> f64 {
    let outputs = reference.first().map_or(0, Vec::len);
    (0..outputs)
        .map(|k| {
            let rms = (reference.iter().map(|r| (r[k] as f64).powi(2)).sum::<f64>()
                / reference.len() as f64)
                .sqrt();
            y.iter()
                .zip(reference)
                .map(|(a, b)| (a[k] as f64 - b[k] as f64).abs())
                .fold(0.0, f64::max)
                / rms
        })
        .fold(0.0, f64::max)
}

#[test]
fn the_pytorch_fixtures_export_within_each_precisions_bound() {
    // Both input layers, tanh and linear, against PyTorch's own outputs.
    for (name, reference) in [
        ("torch_lstm.safetensors", "torch_reference.csv"),
        ("torch_linear.safetensors", "torch_linear_reference.csv"),
    ] {
        exported_forms_match_pytorch(name, reference);
    }
}

fn exported_forms_match_pytorch(name: &str, reference: &str) {
    let fixtures = workspace().join("crates/compnet/tests/fixtures");
    let m = compnet::io::read_model(&fixtures.join(name)).expect("fixture");
    let t = compnet::data::Table::read(&fixtures.join(reference)).expect("reference");
    let col = |n: String| t.column(&n).expect("column").to_vec();
    let xs: Vec<Vec<f32>> = (0..m.dims.input).map(|k| col(format!("x{k}"))).collect();
    let ys: Vec<Vec<f32>> = (0..m.dims.output).map(|k| col(format!("y{k}"))).collect();
    let inputs: Vec<Vec<f32>> = (0..t.len())
        .map(|r| xs.iter().map(|c| c[r]).collect())
        .collect();
    let torch: Vec<Vec<f32>> = (0..t.len())
        .map(|r| ys.iter().map(|c| c[r]).collect())
        .collect();
    // The bound of each precision: max error over the run, relative to the output RMS.
    for (p, bound) in [
        (Precision::F32, 1e-5f64),
        (Precision::Int16, 2e-3),
        (Precision::Int8, 2e-2),
    ] {
        let y = Exported::new(&m, p).expect("export").stream(&inputs);
        let err = error_vs_reference(&y, &torch);
        println!(
            "{name} ({} input layer), {}: max error vs PyTorch {err:.2e} of the output RMS \
             (bound {bound:.0e})",
            m.input_activation.name(),
            p.name()
        );
        assert!(err <= bound, "{}: {err} > {bound}", p.name());
    }
}

#[test]
fn regenerating_the_linear_input_golden_models_gives_the_committed_files() {
    let dir = tempfile::tempdir().expect("tempdir");
    for p in Precision::ALL {
        let out = dir.path().join(format!("golden_linear_{}.rs", p.name()));
        let mut a = args(out.clone(), p);
        a.network =
            Some(workspace().join("crates/compnet/tests/fixtures/torch_linear.safetensors"));
        a.joints = vec![1, 2];
        a.allow_worse = true;
        // An imported network carries no training envelope: refused unless the user
        // names its training data or exports it without one, explicitly.
        let err = model_export::cmd::export::model(&a).unwrap_err();
        assert!(
            format!("{err:#}").contains("--envelope-data") && !out.exists(),
            "{err:#}"
        );
        a.no_envelope = true;
        let m = model_export::cmd::export::model(&a).expect("model");
        model_export::cmd::export::export(&m, &a).expect("export");
        let fresh = std::fs::read_to_string(&out).expect("read");
        let committed = workspace().join(format!(
            "test-kit/src/fixtures/golden_linear_{}.rs",
            p.name()
        ));
        let committed = std::fs::read_to_string(&committed).expect("committed golden file");
        assert!(
            fresh == committed,
            "golden_linear_{}: regenerate with firmware/scripts/regenerate-models.sh",
            p.name()
        );
        assert!(fresh.contains("InputActivation::Linear"));
    }
}

fn small() -> LstmModel {
    LstmModel::init(
        LstmDims {
            input: 3,
            embed: 4,
            hidden: 4,
            output: 1,
        },
        5,
    )
}

#[test]
fn nan_or_infinite_weights_are_refused_naming_the_tensor() {
    for bad in [f32::NAN, f32::INFINITY] {
        let mut m = small();
        m.w_hh[6] = bad;
        for p in Precision::ALL {
            let err = Exported::new(&m, p).unwrap_err();
            assert!(
                matches!(
                    err,
                    ExportError::NotFinite {
                        tensor: "lstm.weight_hh_l0",
                        index: 6,
                        ..
                    }
                ),
                "{err}"
            );
            assert!(err.to_string().contains("lstm.weight_hh_l0"), "{err}");
        }
    }
}

#[test]
fn scales_that_overflow_the_q_format_are_refused() {
    let mut m = small();
    for w in m.w_in.iter_mut() {
        *w *= 1.0e9;
    }
    let err = Exported::new(&m, Precision::Int16).unwrap_err();
    assert!(
        matches!(err, ExportError::ScaleOverflow { layer: "input", .. }),
        "{err}"
    );
    assert!(err.to_string().contains("overflow the Q format"), "{err}");
    // f32 has no Q format: the same weights export.
    assert!(Exported::new(&m, Precision::F32).is_ok());
}

#[test]
fn joint_numbers_start_at_one() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("model.rs");
    let mut a = args(out.clone(), Precision::F32);
    a.joints = vec![0, 1, 2];
    let err = model_export::cmd::export::model(&a)
        .and_then(|m| model_export::cmd::export::export(&m, &a))
        .unwrap_err();
    assert!(format!("{err:#}").contains("start at 1"), "{err:#}");
    assert!(!out.exists());
}

#[test]
fn an_increment_network_is_refused_and_writes_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("model.rs");
    let mut a = args(out.clone(), Precision::Int16);
    a.dims = vec![3, 4, 4, 1];
    let mut m = small();
    m.preset = "paper".into();
    let spec = compnet::data::FeatureSpec::paper_increment(&[4]);
    m.input_names = spec.inputs.clone();
    m.output_names = spec.output_names();
    let err = model_export::cmd::export::export(&m, &a).unwrap_err();
    let text = format!("{err:#}");
    assert!(text.contains("tau_meas_j4@+1-tau_meas_j4@0"), "{text}");
    assert!(text.contains("--preset paper_relative"), "{text}");
    assert!(!out.exists(), "a refused export left {}", out.display());
    // The same network with the next-step output exports, and so does the form relative
    // to the model torque, as its own preset.
    m.output_names = compnet::data::FeatureSpec::paper(&[4]).output_names();
    model_export::cmd::export::export(&m, &a).expect("next-step paper network exports");
    assert!(out.exists());
    let relative = compnet::data::FeatureSpec::paper_relative(&[4]);
    m.preset = relative.preset.clone();
    m.input_names = relative.inputs.clone();
    m.output_names = relative.output_names();
    model_export::cmd::export::export(&m, &a).expect("relative paper network exports");
    let text = std::fs::read_to_string(&out).expect("read");
    assert!(
        text.contains("FEATURE_PRESET: FeaturePreset = FeaturePreset::PaperRelative;"),
        "{text}"
    );
}

#[test]
fn a_model_over_the_flash_budget_is_refused_and_writes_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let budgets = dir.path().join("budgets.toml");
    std::fs::write(
        &budgets,
        "[binary.board]\nflash_bytes = 4096\nram_bytes = 1\nstack_reserve_bytes = 1\n",
    )
    .expect("write");
    let out = dir.path().join("model.rs");
    let mut a = args(out.clone(), Precision::Int16);
    a.dims = vec![9, 64, 64, 3];
    a.budgets = Some(budgets);
    let m = model_export::cmd::export::model(&a).expect("model");
    let err = model_export::cmd::export::export(&m, &a).unwrap_err();
    let text = format!("{err:#}");
    assert!(text.contains("over the budget of 4096 bytes"), "{text}");
    assert!(!out.exists(), "a refused export left {}", out.display());
    // The checked-in budget accepts it.
    a.budgets = Some(workspace().join("host-tests/budgets.toml"));
    model_export::cmd::export::export(&m, &a).expect("fits the board budget");
    assert!(out.exists());
}

/// A `drive` network for joint 4, and a validation run on which the model alone is
/// exact: any non-zero correction makes the network worse.
fn gate_case(dir: &Path) -> (LstmModel, PathBuf) {
    let mut m = LstmModel::init(
        LstmDims {
            input: DRIVE_INPUTS_PER_JOINT,
            embed: 4,
            hidden: 4,
            output: 1,
        },
        9,
    );
    let spec = compnet::data::FeatureSpec::drive(&[4]);
    m.preset = "drive".into();
    m.input_names = spec.inputs.clone();
    m.output_names = spec.output_names();
    let run = dir.join("validation.csv");
    let mut csv = String::from("time_s");
    for name in ["tau_meas_j4"]
        .iter()
        .copied()
        .chain(spec.inputs.iter().map(String::as_str))
    {
        csv += &format!(",{name}");
    }
    csv += "\n";
    for k in 0..200 {
        let t = k as f64 * 0.01;
        let (q, qd) = ((0.7 * t).sin(), 0.7 * (0.7 * t).cos());
        let tau = 2.0 * q.sin() + 0.3 * qd;
        // tau_meas, sin q, cos q, qd, qdd, tau_model, rest_dir, presliding states, the
        // residual measured over the previous tick (0: the model is exact)
        csv += &format!(
            "{t},{tau},{},{},{qd},0,{tau},0,0,0,0,0,0\n",
            q.sin(),
            q.cos()
        );
    }
    std::fs::write(&run, csv).unwrap();
    (m, run)
}

#[test]
fn the_do_no_harm_gate_refuses_a_network_worse_than_the_model() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("model.rs");
    let (mut m, run) = gate_case(dir.path());
    let mut a = args(out.clone(), Precision::Int16);
    a.dims = vec![DRIVE_INPUTS_PER_JOINT, 4, 4, 1];
    a.preset = firmware::nn::format::FeaturePreset::Drive;
    a.joints = vec![4];
    a.network = Some(dir.path().join("trained.safetensors"));
    // A trained network needs validation runs (or --allow-worse).
    let text = format!(
        "{:#}",
        model_export::cmd::export::export(&m, &a).unwrap_err()
    );
    assert!(text.contains("--gate-data"), "{text}");
    assert!(!out.exists());
    // A seeded network corrects an exact model: worse, refused, nothing written.
    a.gate_data = vec![run.clone()];
    let text = format!(
        "{:#}",
        model_export::cmd::export::export(&m, &a).unwrap_err()
    );
    assert!(text.contains("worse than the model alone"), "{text}");
    assert!(text.contains("1 | 4 | 0.0000 |"), "{text}");
    assert!(!out.exists(), "a refused export left {}", out.display());
    // --allow-worse exports it with the figures as a warning in the file.
    a.allow_worse = true;
    model_export::cmd::export::export(&m, &a).expect("--allow-worse exports");
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(
        text.starts_with("// WARNING: exported with --allow-worse"),
        "{text}"
    );
    assert!(
        !text.contains("validation.csv"),
        "input pasted into the file"
    );
    // A network that outputs no correction is as good as the model: it passes.
    std::fs::remove_file(&out).unwrap();
    a.allow_worse = false;
    m.w_out.iter_mut().for_each(|w| *w = 0.0);
    m.b_out.iter_mut().for_each(|b| *b = 0.0);
    m.output_mean.iter_mut().for_each(|b| *b = 0.0);
    model_export::cmd::export::export(&m, &a).expect("a network that does no harm exports");
    assert!(!std::fs::read_to_string(&out).unwrap().contains("WARNING"));
}

#[test]
fn model_metadata_never_reaches_the_generated_code_as_text() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("model.rs");
    let a = args(out.clone(), Precision::F32);
    let mut m = small();
    // A preset and names that would end a `//` comment or a string literal.
    m.preset = "paper\npub static EVIL: u8 = 1; //".into();
    m.input_names = vec!["a\"b".into(), "c\n#[x]".into(), "d".into()];
    m.output_names = vec!["y\\\"".into()];
    model_export::cmd::export::export(&m, &a).expect("exports as a custom network");
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(!text.contains("EVIL"), "metadata pasted into the file");
    assert!(!text.contains("\n#[x]"), "a name broke out of its literal");
    assert!(
        text.contains("FeaturePreset::Custom"),
        "an unknown preset is Custom"
    );
    assert!(
        text.contains(r#""c\n#[x]""#),
        "names are escaped string literals"
    );
}

#[test]
fn auto_places_a_model_in_sram_when_it_fits_the_board_budget_and_in_flash_otherwise() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("model.rs");
    // The paper int16 network (68 968 B) fits the SRAM budget of budgets.toml and
    // memory.x (96 KiB - 16 KiB stack - 8 KiB firmware = 73 728 B); the f32 one
    // (135 800 B) does not, its linear stage does.
    let mut a = args(out.clone(), Precision::Int16);
    a.dims = vec![9, 64, 64, 3];
    let m = model_export::cmd::export::model(&a).expect("model");
    let (_, p) = model_export::cmd::export::export(&m, &a).expect("export");
    assert_eq!(p.sram_budget_bytes, Some(73_728));
    assert_eq!(
        (p.network, p.linear_stage),
        (Placement::Sram, Placement::Sram)
    );
    let text = std::fs::read_to_string(&out).expect("read");
    assert!(
        text.lines()
            .nth(2)
            .is_some_and(|l| l.starts_with("// Placement: network 68968 bytes in SRAM")),
        "{}",
        text.lines().nth(2).unwrap_or("")
    );
    assert_eq!(text.matches(fw_export::SRAM_SECTION_ATTRIBUTE).count(), 2);
    assert!(text.contains(&format!(
        "{}\npub static NETWORK",
        fw_export::SRAM_SECTION_ATTRIBUTE
    )));
    a.precision = Precision::F32;
    let (_, p) = model_export::cmd::export::export(&m, &a).expect("export");
    assert_eq!(
        (p.network, p.linear_stage),
        (Placement::Flash, Placement::Sram)
    );
    let text = std::fs::read_to_string(&out).expect("read");
    assert!(!text.contains(&format!(
        "{}\npub static NETWORK",
        fw_export::SRAM_SECTION_ATTRIBUTE
    )));
    // Forced to flash: no attribute at all.
    a.weights_in = WeightsIn::Flash;
    model_export::cmd::export::export(&m, &a).expect("export");
    let text = std::fs::read_to_string(&out).expect("read");
    assert!(!text.contains("link_section"));
    // Forced to SRAM over the budget: an error naming both sizes, the file untouched.
    a.weights_in = WeightsIn::Sram;
    let err = format!(
        "{:#}",
        model_export::cmd::export::export(&m, &a).unwrap_err()
    );
    assert!(err.contains("over the SRAM budget of 73728 bytes"), "{err}");
    assert_eq!(std::fs::read_to_string(&out).expect("read"), text);
}

#[test]
fn a_broken_memory_layout_is_refused_naming_file_line_and_field() {
    let dir = tempfile::tempdir().expect("tempdir");
    let layout = dir.path().join("memory.x");
    std::fs::write(
        &layout,
        "MEMORY\n{\n  FLASH : ORIGIN = 0x08000000, LENGTH = 512K\n  RAM : ORIGIN = 0x20000000, LENGTH = lots\n}\n",
    )
    .expect("write");
    let budgets = dir.path().join("budgets.toml");
    std::fs::write(
        &budgets,
        "[mcu]\nmemory_layout = \"memory.x\"\n[binary.board]\nflash_bytes = 524288\n\
         ram_bytes = 98304\nstack_reserve_bytes = 16384\nfirmware_ram_bytes = 8192\n",
    )
    .expect("write");
    let out = dir.path().join("model.rs");
    let mut a = args(out.clone(), Precision::Int16);
    a.budgets = Some(budgets.clone());
    let m = model_export::cmd::export::model(&a).expect("model");
    let err = format!(
        "{:#}",
        model_export::cmd::export::export(&m, &a).unwrap_err()
    );
    assert!(
        err.contains("memory.x") && err.contains("line 4") && err.contains("LENGTH"),
        "{err}"
    );
    assert!(!out.exists());
    // A budget file without the firmware's own RAM names the field.
    std::fs::write(
        &layout,
        "MEMORY\n{\n  RAM : ORIGIN = 0x20000000, LENGTH = 96K\n}\n",
    )
    .expect("write");
    std::fs::write(
        &budgets,
        "[mcu]\nmemory_layout = \"memory.x\"\n[binary.board]\nflash_bytes = 524288\n\
         ram_bytes = 98304\nstack_reserve_bytes = 16384\n",
    )
    .expect("write");
    let err = format!(
        "{:#}",
        model_export::cmd::export::export(&m, &a).unwrap_err()
    );
    assert!(err.contains("binary.board.firmware_ram_bytes"), "{err}");
    assert!(!out.exists());
    // Sizes in hex and K/M, comments ignored.
    assert_eq!(
        fw_export::layout_ram_bytes(
            "/* RAM : LENGTH = 1 */\n  RAM : ORIGIN = 0x20000000, LENGTH = 0x18000\n"
        ),
        Ok(0x18000)
    );
    assert_eq!(
        fw_export::layout_ram_bytes("RAM : ORIGIN = 0x20000000, LENGTH = 4M"),
        Ok(4 << 20)
    );
    assert!(fw_export::layout_ram_bytes("FLASH : ORIGIN = 0, LENGTH = 4M").is_err());
}

#[test]
fn the_gate_refuses_empty_header_only_one_row_and_still_gate_data() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("model.rs");
    let (m, run) = gate_case(dir.path());
    let mut a = args(out.clone(), Precision::Int16);
    a.dims = vec![DRIVE_INPUTS_PER_JOINT, 4, 4, 1];
    a.preset = firmware::nn::format::FeaturePreset::Drive;
    a.joints = vec![4];
    a.network = Some(dir.path().join("trained.safetensors"));
    let text = std::fs::read_to_string(&run).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_string();
    let first_row = lines.next().unwrap().to_string();
    let cases = [
        ("empty.csv", String::new()),
        ("header_only.csv", format!("{header}\n")),
        ("one_row.csv", format!("{header}\n{first_row}\n")),
    ];
    for (name, body) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, body).unwrap();
        // Alone, or beside a good run: refused, naming the file, nothing written.
        for gate in [vec![path.clone()], vec![run.clone(), path.clone()]] {
            a.gate_data = gate;
            for allow_worse in [false, true] {
                a.allow_worse = allow_worse;
                let err = model_export::cmd::export::export(&m, &a).unwrap_err();
                let msg = format!("{err:#}");
                assert!(msg.contains(name), "{name}: {msg}");
                assert!(
                    !out.exists(),
                    "{name}: a refused export left {}",
                    out.display()
                );
            }
        }
    }
    // A run where joint 4 is held (|qd| below the threshold): refused, naming the joint.
    let held: String = std::iter::once(header.clone())
        .chain(text.lines().skip(1).map(|l| {
            let mut f: Vec<String> = l.split(',').map(String::from).collect();
            let qd = header.split(',').position(|c| c == "qd_j4").unwrap();
            f[qd] = "0.001".into();
            f.join(",")
        }))
        .collect::<Vec<_>>()
        .join("\n");
    let path = dir.path().join("held.csv");
    std::fs::write(&path, held + "\n").unwrap();
    a.gate_data = vec![path];
    a.allow_worse = true;
    let msg = format!(
        "{:#}",
        model_export::cmd::export::export(&m, &a).unwrap_err()
    );
    assert!(msg.contains("joint 4 moves"), "{msg}");
    assert!(msg.contains("0.05 rad/s"), "{msg}");
    assert!(!out.exists());
    // The moving run passes the data checks (the seeded network is then judged worse,
    // exported here with --allow-worse).
    a.gate_data = vec![run];
    model_export::cmd::export::export(&m, &a).expect("moving gate data is accepted");
    assert!(out.exists());
}
