//! The top-level README's "ROS 2 recordings and ONNX networks" commands, run as written
//! (`$ME` = the model-export binary, paths relative to the workspace root, outputs in a
//! temporary directory).
use std::path::Path;
use std::process::Command;

/// The `$ME ...` lines of the README block that follows `marker`.
fn readme_commands(marker: &str) -> Vec<String> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("README.md")).unwrap();
    let start = text.find(marker).expect("the README section");
    let block = &text[start..];
    let open = block.find("```sh\n").expect("a sh block") + 6;
    let close = open + block[open..].find("```").expect("the block's end");
    block[open..close]
        .lines()
        .filter(|l| l.starts_with("$ME "))
        .map(str::to_string)
        .collect()
}

#[test]
fn readme_bag_and_onnx_commands_run() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let dir = tempfile::tempdir().unwrap();
    let lines = readme_commands("**ROS 2 recordings and ONNX networks.**");
    assert_eq!(lines.len(), 4, "{lines:?}");
    for line in &lines {
        let args: Vec<String> = line
            .split_whitespace()
            .skip(1)
            .map(|a| {
                if a.starts_with("crates/") || a.starts_with("robots/") {
                    root.join(a).display().to_string()
                } else {
                    a.to_string()
                }
            })
            .collect();
        let o = Command::new(env!("CARGO_BIN_EXE_model-export"))
            .args(&args)
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{line}\n{}\n{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        println!("{line}\n{}", String::from_utf8_lossy(&o.stdout));
    }
    for out in [
        "bag-model.json",
        "bag-data.csv",
        "ur-model.json",
        "onnx-lstm.safetensors",
    ] {
        assert!(dir.path().join(out).exists(), "{out}");
    }
}
