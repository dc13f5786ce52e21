//! Runs the top README's "A URDF with a gripper" walkthrough as written: the commands of
//! its marked block, with a log made from the excitation and the nominal model (the
//! rigid-body torques of the chain) where the robot's run would be.
use robot::dynamics::rnea;
use robot::{ChainSelection, Robot};
use std::path::{Path, PathBuf};
use std::process::Command;

const MARKER: &str = "<!-- walkthrough: urdf-gripper -->";

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// The lines of the fenced block after the marker.
fn walkthrough_lines() -> Vec<String> {
    let readme = std::fs::read_to_string(repo_root().join("README.md")).unwrap();
    let after = &readme[readme
        .find(MARKER)
        .expect("walkthrough marker in README.md")..];
    let block = after
        .split("```")
        .nth(1)
        .expect("fenced block after the marker");
    block
        .lines()
        .skip(1)
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .map(str::to_string)
        .collect()
}

/// The value after `flag` in `tokens`.
fn flag<'a>(tokens: &'a [String], flag: &str) -> Option<&'a str> {
    tokens
        .iter()
        .position(|t| t == flag)
        .map(|i| tokens[i + 1].as_str())
}

/// The log a robot would record: the excitation playback with the chain's torques.
fn write_log(chain: &[String], playback: &Path, log: &Path) {
    let selection = ChainSelection {
        base_link: flag(chain, "--base-link").map(str::to_string),
        tip_link: flag(chain, "--tip-link").map(str::to_string),
        side_joint_positions: flag(chain, "--side-joint")
            .map(|s| {
                s.split(',')
                    .map(|kv| {
                        let (k, v) = kv.split_once('=').unwrap();
                        (k.to_string(), v.parse().unwrap())
                    })
                    .collect()
            })
            .unwrap_or_default(),
        ..ChainSelection::default()
    };
    let robot = Robot::load_chain(flag(chain, "--robot").unwrap(), &selection)
        .unwrap()
        .robot;
    let theta = robot.standard_parameters();
    let n = robot.dof();
    let text = std::fs::read_to_string(playback).unwrap();
    let mut out = String::new();
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        assert_eq!(v.len(), 1 + 3 * n, "playback columns t, q, qd, qdd");
        let (q, qd, qdd) = (&v[1..1 + n], &v[1 + n..1 + 2 * n], &v[1 + 2 * n..]);
        let tau = rnea(&robot, &theta, q, qd, qdd, &robot.gravity);
        let row: Vec<String> = std::iter::once(v[0])
            .chain(q.iter().copied())
            .chain(qd.iter().copied())
            .chain(tau.iter().copied())
            .map(|x| x.to_string())
            .collect();
        out.push_str(&row.join(","));
        out.push('\n');
    }
    std::fs::write(log, out).unwrap();
}

#[test]
fn the_readme_urdf_with_gripper_walkthrough_runs() {
    let dir = tempfile::tempdir().unwrap();
    let mut f = String::new();
    let mut chain: Vec<String> = Vec::new();
    let mut ran = Vec::new();
    for line in walkthrough_lines() {
        if let Some(v) = line.strip_prefix("F=") {
            f = repo_root().join(v).display().to_string();
            continue;
        }
        if let Some(v) = line.strip_prefix("CHAIN=") {
            chain = v
                .trim_matches('"')
                .replace("$F", &f)
                .split_whitespace()
                .map(str::to_string)
                .collect();
            continue;
        }
        if line.starts_with('#') {
            continue;
        }
        let rest = line
            .strip_prefix("$ME ")
            .unwrap_or_else(|| panic!("unexpected walkthrough line: {line}"));
        let mut args: Vec<String> = Vec::new();
        for t in rest.split_whitespace() {
            if t == "$CHAIN" {
                args.extend(chain.iter().cloned());
            } else {
                args.push(t.replace("$F", &f));
            }
        }
        if args.iter().any(|a| a == "panda-log.csv") && !dir.path().join("panda-log.csv").exists() {
            write_log(
                &chain,
                &dir.path().join("exc/panda.csv"),
                &dir.path().join("panda-log.csv"),
            );
        }
        let out = Command::new(env!("CARGO_BIN_EXE_model-export"))
            .args(&args)
            .current_dir(dir.path())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr).to_string();
        assert!(out.status.success(), "{line}\n{stderr}");
        ran.push((args[0].clone(), stderr));
    }
    let commands: Vec<&str> = ran.iter().map(|(c, _)| c.as_str()).collect();
    assert_eq!(commands, ["excite", "identify", "torque"]);
    // The chain's commands warn about the fingers they hold fixed.
    for (c, stderr) in &ran[..2] {
        assert!(
            stderr.contains("panda_finger_joint1 (prismatic) at 0.02 m, on panda_hand"),
            "{c}: {stderr}"
        );
    }
    // The model file records the chain; torque reloaded it from there.
    let model: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("panda-model.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(model["robot"]["chain"]["tip_link"], "panda_hand");
    assert_eq!(model["modelled_joints"].as_array().unwrap().len(), 7);
    // The identified model predicts the log's torques.
    let text = std::fs::read_to_string(dir.path().join("panda-torque.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header.len(), 1 + 2 * 7, "{header:?}");
    let (mut err2, mut tau2) = (0.0, 0.0);
    for l in lines {
        let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
        for j in 0..7 {
            err2 += (v[1 + j] - v[8 + j]).powi(2);
            tau2 += v[8 + j].powi(2);
        }
    }
    let relative = (err2 / tau2).sqrt();
    println!("panda walkthrough: identified model vs log torque, relative RMS {relative:.3e}");
    assert!(relative < 0.02, "relative RMS {relative}");
}
