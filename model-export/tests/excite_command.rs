//! `model-export excite` on the default robot: the outputs written, bad input refused
//! without partial files (the design itself: `crates/excitation/tests/excite_robot.rs`).

#[path = "../../crates/excitation/tests/support/design.rs"]
mod design;
use design::test_robot;

#[test]
fn cli_writes_outputs_and_rejects_bad_input_without_partial_files() {
    let Some((robot, _)) = test_robot() else {
        return;
    };
    let robot_path = robot.source.clone();
    let dir = tempfile::tempdir().unwrap();
    let bin = env!("CARGO_BIN_EXE_model-export");
    let out = std::process::Command::new(bin)
        .args([
            "excite",
            "--joints",
            "wrist",
            "--restarts",
            "1",
            "--evaluations",
            "200",
        ])
        .args([
            "--samples",
            "50",
            "--qdd-max",
            "8",
            "--zero-at",
            "3.8",
            "--name",
            "test",
        ])
        .arg("--robot")
        .arg(&robot_path)
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("tightest:") && stdout.contains("condition number"),
        "{stdout}"
    );
    let file = excitation::output::ExcitationFile::read(&dir.path().join("test.json")).unwrap();
    assert_eq!(file.layout.moving, vec![3, 4, 5]);
    let p = file.trajectory.eval(3.8);
    assert!(p.q_rad.iter().all(|q| q.abs() < 1e-9));
    let csv = std::fs::read_to_string(dir.path().join("test.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 1001);
    assert!(dir.path().join("test.svg").exists());

    // A rest pose outside the position limits: error naming the joint, no output files.
    let bad = tempfile::tempdir().unwrap();
    let out = std::process::Command::new(bin)
        .args([
            "excite",
            "--joints",
            "wrist",
            "--qdd-max",
            "8",
            "--rest",
            "0,20,0",
        ])
        .arg("--robot")
        .arg(&robot_path)
        .arg("--out")
        .arg(bad.path())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("moving joint #1: rest pose 20 rad lies outside")
            && stderr.contains("#1 = joint 5"),
        "{stderr}"
    );
    assert_eq!(std::fs::read_dir(bad.path()).unwrap().count(), 0);
}
