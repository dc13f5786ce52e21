//! `model-export simulate`: the log written atomically, bad trajectory files named, an
//! excitation file's layout selecting the driven joints (the simulator itself:
//! `crates/plant-sim/tests/sim_plant.rs`).
use excitation::ExcitationTrajectory;

/// The CLI writes the log atomically and names a bad trajectory file's line and field.
#[test]
fn cli_simulate_writes_log_and_rejects_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let traj = dir.path().join("t.csv");
    let mut text = String::from("t,q1,qd1,qdd1\n");
    for k in 0..=100 {
        let t = k as f64 * 0.01;
        text += &format!(
            "{t},{},{},{}\n",
            0.1 * t.sin(),
            0.1 * t.cos(),
            -0.1 * t.sin()
        );
    }
    std::fs::write(&traj, &text).unwrap();
    let out = dir.path().join("log.csv");
    let exe = env!("CARGO_BIN_EXE_model-export");
    let st = std::process::Command::new(exe)
        .args(["simulate", "--joints", "5", "--seed", "1", "--trajectory"])
        .arg(&traj)
        .arg("-o")
        .arg(&out)
        .status()
        .unwrap();
    assert!(st.success());
    let log = std::fs::read_to_string(&out).unwrap();
    assert!(log.starts_with("t_s,q1_rad,"));
    assert_eq!(log.lines().count(), 102);
    std::fs::write(&traj, "t,q1,qd1,qdd1\n0,0,0,0\n0.01,0,zero,0\n").unwrap();
    let bad_out = dir.path().join("bad.csv");
    let o = std::process::Command::new(exe)
        .args(["simulate", "--joints", "5", "--trajectory"])
        .arg(&traj)
        .arg("-o")
        .arg(&bad_out)
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("line 3") && err.contains("qd1"), "{err}");
    assert!(!bad_out.exists());
}

/// An excitation file (the `model-export excite` format: coefficients under
/// `trajectory`, joints under `layout`) drives the joints it names.
#[test]
fn excitation_file_layout_selects_the_driven_joints() {
    let dir = tempfile::tempdir().unwrap();
    let series = ExcitationTrajectory::seeded_rest_to_rest(
        4,
        &[0.0; 3],
        5,
        10.0,
        plant_sim::trajectory::DEMO_LIMITS,
    );
    let file = serde_json::json!({
        "format": "excitation", "version": 1,
        "layout": { "joint_names": ["a", "b", "c", "d", "e", "f"], "moving": [3, 4, 5],
                    "fixed_rad": [0.0, -1.0, 0.5, 0.0, 0.0, 0.0] },
        "trajectory": series,
    });
    let traj = dir.path().join("exc.json");
    std::fs::write(&traj, file.to_string()).unwrap();
    let out = dir.path().join("log.csv");
    let st = std::process::Command::new(env!("CARGO_BIN_EXE_model-export"))
        .args(["simulate", "--trajectory"])
        .arg(&traj)
        .arg("-o")
        .arg(&out)
        .status()
        .unwrap();
    assert!(st.success());
    let text = std::fs::read_to_string(&out).unwrap();
    let row: Vec<f64> = text
        .lines()
        .nth(500)
        .unwrap()
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    assert_eq!(&row[1..4], &[0.0, -1.0, 0.5]);
    assert!(row[4..7].iter().any(|q| q.abs() > 1e-3));
}
