//! Identification end to end through the `model-export identify` and `torque` binaries:
//! simulated logs of a UR-type 6R arm written as CSV, identified and evaluated; bad inputs
//! named by file, line and field (the library's own tests: `crates/identify/tests/`).
#![allow(clippy::needless_range_loop)]

use identify::model_file::ModelFile;
use logs::Samples;
use std::path::Path;
use std::process::Command;

#[path = "../../crates/identify/tests/support/arm.rs"]
mod arm;
use arm::{ROBOT, robot_model, simulate, true_beta};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_model-export"))
}

/// Writes a log in the `torque` preset layout plus qdd columns: time, q, qd, tau, qdd.
fn write_log(path: &Path, s: &Samples) {
    let mut out = String::new();
    for k in 0..s.len() {
        out.push_str(&format!("{:e}", s.time_s[k]));
        let tau = s.torque_nm.as_ref().unwrap();
        for v in [&s.q_rad, &s.qd_rad_s, tau, &s.qdd_rad_s2] {
            for col in v.iter() {
                out.push_str(&format!(",{:e}", col[k]));
            }
        }
        out.push('\n');
    }
    std::fs::write(path, out).unwrap();
}

const EXACT: [&str; 12] = [
    "--layout",
    "torque",
    "--qdd-cols",
    "20,21,22,23,24,25",
    "--use-logged-qd",
    "--q-cutoff-hz",
    "0",
    "--torque-cutoff-hz",
    "0",
    "--trim-rest-rad-s",
    "0",
    "--resample-hz",
];

#[test]
fn cli_identify_recovers_parameters_and_torque_evaluates_them() {
    let m = robot_model();
    let d = tempfile::tempdir().unwrap();
    let log = d.path().join("sim.csv");
    let val = d.path().join("val.csv");
    write_log(&log, &simulate(&m, 3000, 4, None));
    write_log(&val, &simulate(&m, 1000, 5, None));
    let model = d.path().join("model.json");
    let out = bin()
        .args(["identify", "--robot", ROBOT.as_str(), "--log"])
        .arg(&log)
        .arg("--validation-log")
        .arg(&val)
        .arg("-o")
        .arg(&model)
        .args(EXACT)
        .arg("100")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}\n{stdout}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("per-joint RMS torque error"), "{stdout}");
    let file = ModelFile::read(&model).unwrap();
    // The arm's own parameters are a rigid body: the least-squares first stage is kept.
    let first = file.first_stage.as_ref().expect("first_stage recorded");
    assert_eq!(first.solution, "unconstrained", "{first:?}");
    assert!(stdout.contains("physically consistent body"), "{stdout}");
    let beta = true_beta(&m);
    let scale = beta.amax();
    for (b, t) in file.base_parameters.iter().zip(beta.iter()) {
        assert!(
            (b.value - t).abs() <= (1e-6 * t.abs()).max(1e-9 * scale),
            "{}: {} vs {t}",
            b.expression,
            b.value
        );
    }
    assert_eq!(
        file.identification_logs[0].sha256,
        logs::sha256_file(&log).unwrap()
    );
    assert_eq!(file.friction.len(), 6);
    assert!((file.friction[3].viscous_nm_s_rad.unwrap() - 1.5).abs() < 1e-6);
    // f32 model RMS on validation data: single-precision level only.
    let val_all = file
        .errors
        .iter()
        .find(|e| e.data == "validation: all")
        .unwrap();
    assert!(
        val_all.rms_nm.iter().all(|r| *r < 1e-3),
        "{:?}",
        val_all.rms_nm
    );

    // torque: identified model and nominal parameters give the same torques here.
    for with_model in [true, false] {
        let csv = d.path().join(format!("tau{with_model}.csv"));
        let mut c = bin();
        c.args(["torque", "--robot", ROBOT.as_str(), "--log"])
            .arg(&val)
            .arg("-o")
            .arg(&csv)
            .args(EXACT)
            .arg("100");
        if with_model {
            c.arg("--identified").arg(&model);
        }
        let out = c.output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = std::fs::read_to_string(&csv).unwrap();
        let mut lines = text.lines();
        assert!(
            lines
                .next()
                .unwrap()
                .starts_with("time_s,tau_model_joint1_nm")
        );
        let mut worst: f64 = 0.0;
        let mut n = 0;
        for l in lines {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            assert_eq!(v.len(), 13);
            for j in 0..6 {
                worst = worst.max((v[1 + j] - v[7 + j]).abs());
            }
            n += 1;
        }
        assert_eq!(n, 1000);
        assert!(worst < 1e-2, "model {with_model}: {worst}");
    }
}

/// Runs `identify` with one log and returns (success, stderr); asserts no output file.
fn identify_err(robot: &Path, log: &Path, extra: &[&str]) -> String {
    let d = tempfile::tempdir().unwrap();
    let model = d.path().join("out.json");
    let out = bin()
        .args(["identify", "--robot"])
        .arg(robot)
        .arg("--log")
        .arg(log)
        .arg("-o")
        .arg(&model)
        .args(extra)
        .output()
        .unwrap();
    assert!(
        !out.status.success(),
        "expected failure: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(!model.exists(), "partial output left behind");
    assert_eq!(
        std::fs::read_dir(d.path()).unwrap().count(),
        0,
        "temporary files left behind"
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn cli_bad_inputs_name_file_line_and_field() {
    let m = robot_model();
    let d = tempfile::tempdir().unwrap();
    let good = d.path().join("good.csv");
    write_log(&good, &simulate(&m, 300, 6, None));
    let text = std::fs::read_to_string(&good).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let with_line = |name: &str, idx: usize, new: String| {
        let p = d.path().join(name);
        let mut l: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
        l[idx] = new;
        std::fs::write(&p, l.join("\n") + "\n").unwrap();
        p
    };
    let robot = Path::new(ROBOT.as_str());

    // NaN cell: line 5, column 3 (q2).
    let mut cells: Vec<String> = lines[4].split(',').map(str::to_string).collect();
    cells[2] = "NaN".into();
    let p = with_line("nan.csv", 4, cells.join(","));
    let e = identify_err(robot, &p, &["--layout", "torque"]);
    assert!(
        e.contains("nan.csv, line 5, column 3 (q2): non-finite value 'NaN'"),
        "{e}"
    );

    // Non-monotonic time at line 10.
    let mut cells: Vec<String> = lines[9].split(',').map(str::to_string).collect();
    cells[0] = "0.01".into();
    let p = with_line("mono.csv", 9, cells.join(","));
    let e = identify_err(robot, &p, &["--layout", "torque"]);
    assert!(
        e.contains("mono.csv, line 10, column 1 (time): time not strictly increasing"),
        "{e}"
    );

    // Missing column: row 7 cut short.
    let cells: Vec<&str> = lines[6].split(',').take(15).collect();
    let p = with_line("short.csv", 6, cells.join(","));
    let e = identify_err(robot, &p, &["--layout", "torque"]);
    assert!(
        e.contains("short.csv, line 7, column 16 (tau3): missing column"),
        "{e}"
    );

    // Malformed CSV: not a number.
    let mut cells: Vec<String> = lines[2].split(',').map(str::to_string).collect();
    cells[13] = "1.2.3".into();
    let p = with_line("text.csv", 2, cells.join(","));
    let e = identify_err(robot, &p, &["--layout", "torque"]);
    assert!(
        e.contains("text.csv, line 3, column 14 (tau1): not a number: '1.2.3'"),
        "{e}"
    );

    // Malformed CSV: invalid UTF-8.
    let p = d.path().join("bin.csv");
    let mut bytes = text.as_bytes().to_vec();
    bytes.splice(0..0, [0xff, 0xfe, b',', b'\n']);
    std::fs::write(&p, bytes).unwrap();
    let e = identify_err(robot, &p, &["--layout", "torque"]);
    assert!(e.contains("bin.csv") && e.contains("line 1"), "{e}");

    // A named column that does not exist.
    let e = identify_err(
        robot,
        &good,
        &["--layout", "torque", "--header", "yes", "--time-col", "t"],
    );
    assert!(
        e.contains("good.csv, line 1, column 't' (time): missing column"),
        "{e}"
    );

    // Too few samples.
    let p = d.path().join("few.csv");
    std::fs::write(&p, lines[..8].join("\n") + "\n").unwrap();
    let e = identify_err(robot, &p, &["--layout", "torque"]);
    assert!(e.contains("few.csv, line 8, time: too few samples"), "{e}");

    // Malformed robot files: URDF and TOML.
    let urdf = d.path().join("bad.urdf");
    std::fs::write(&urdf, "<robot name=\"r\">\n  <link name=\"a\">\n</robot>\n").unwrap();
    let e = identify_err(&urdf, &good, &["--layout", "torque"]);
    assert!(e.contains("bad.urdf"), "{e}");
    let toml = d.path().join("bad.toml");
    let src = std::fs::read_to_string(ROBOT.as_str()).unwrap().replacen(
        "mass = 13.051",
        "mass = \"heavy\"",
        1,
    );
    std::fs::write(&toml, &src).unwrap();
    let mass_line = src.lines().position(|l| l.contains("\"heavy\"")).unwrap() + 1;
    let e = identify_err(&toml, &good, &["--layout", "torque"]);
    assert!(
        e.contains(&format!("bad.toml:{mass_line}")) && e.contains("heavy"),
        "{e}"
    );

    // Unidentifiable parameters: a log where joint 6 never moves identifies what it
    // holds; the directions it cannot identify are printed, recorded and keep the
    // nominal values.
    let mut s = simulate(&m, 600, 7, None);
    for k in 0..s.len() {
        s.q_rad[5][k] = 0.2;
        s.qd_rad_s[5][k] = 0.0;
        s.qdd_rad_s2[5][k] = 0.0;
    }
    let p = d.path().join("still6.csv");
    write_log(&p, &s);
    let model = d.path().join("still6.json");
    let out = bin()
        .args(["identify", "--robot"])
        .arg(robot)
        .arg("--log")
        .arg(&p)
        .arg("-o")
        .arg(&model)
        .args([
            "--layout",
            "torque",
            "--use-logged-qd",
            "--qdd-cols",
            "20,21,22,23,24,25",
        ])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("dropped") && stdout.contains("fv6") && stdout.contains("fc6"),
        "{stdout}"
    );
    let file = identify::model_file::ModelFile::read(&model).unwrap();
    let named: Vec<&str> = file
        .dropped_directions
        .iter()
        .flat_map(|d| d.parameters.iter().map(|(n, _)| n.as_str()))
        .collect();
    assert!(named.iter().any(|n| n.ends_with("= fv6")), "{named:?}");
    assert!(named.iter().any(|n| n.ends_with("= fc6")), "{named:?}");
    let r6 = &file.identification_ranges[5];
    assert!(
        r6.q_rad.iter().all(|q| (q - 0.2).abs() < 1e-9) && r6.qd_rad_s == [0.0, 0.0],
        "{r6:?}"
    );
}
