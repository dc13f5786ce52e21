//! Files by concern: no file of product code over [`LIMIT`] lines unless a reason is
//! written at its top (a `//! Size: ...` line among its first lines). Product code: the
//! `src/` folders of the host crates, the firmware, the board, the command line, the
//! QEMU images, the test kit, the xtask and the host tests; generated model files
//! (`firmware/src/model/default_model.rs`, `test-kit/src/fixtures/`) are left out.
//! [`PENDING`] names the files still waiting for their split (each with why it has not
//! happened yet); a listed file that is split, or that gains its reason, fails the test
//! until its entry is removed, so the list only shrinks.
use std::path::{Path, PathBuf};

/// Most lines of a product source file without a written reason.
const LIMIT: usize = 800;

/// How many of a file's first lines may hold its `//! Size:` reason.
const HEAD_LINES: usize = 30;

/// Files over the limit whose split is still open (path, why).
const PENDING: [(&str, &str); 11] = [
    (
        "crates/sil/src/wrist.rs",
        "the wrist plant, its loop and its report (with the monitor's figures) to split",
    ),
    (
        "firmware/src/dsp.rs",
        "the API / portable / assembly split is still open",
    ),
    (
        "firmware/src/control/compensator.rs",
        "the peer state as one type (open)",
    ),
    (
        "crates/logs/src/rosbag.rs",
        "the ROS readers by storage (open)",
    ),
    (
        "firmware/src/drivers/drv83x3.rs",
        "board drivers by peripheral (open)",
    ),
    (
        "crates/robot/src/lib.rs",
        "robot descriptions by format (open)",
    ),
    (
        "model-export/src/cmd/demo.rs",
        "the demo moves to the xtask (open)",
    ),
    ("firmware/src/nn/kernels.rs", "not yet split"),
    ("crates/compnet/src/fused_net.rs", "not yet split"),
    ("crates/compnet/src/onnx.rs", "not yet split"),
    (
        "crates/robot/src/urdf.rs",
        "urdf::parse into functions (open)",
    ),
];

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// Every product source file, relative to the workspace root.
fn product_files() -> Vec<(String, PathBuf)> {
    let root = test_support::workspace_root();
    let mut dirs: Vec<PathBuf> = [
        "firmware/src",
        "board/src",
        "board/ccm/src",
        "model-export/src",
    ]
    .iter()
    .chain(&[
        "firmware/qemu/src",
        "test-kit/src",
        "xtask/src",
        "host-tests/src",
    ])
    .map(|d| root.join(d))
    .collect();
    for e in std::fs::read_dir(root.join("crates")).unwrap().flatten() {
        dirs.push(e.path().join("src"));
    }
    let mut files = Vec::new();
    for d in &dirs {
        rust_files(d, &mut files);
    }
    let mut out: Vec<(String, PathBuf)> = files
        .into_iter()
        .map(|p| {
            let rel = p
                .strip_prefix(root)
                .unwrap_or(&p)
                .to_string_lossy()
                .replace('\\', "/");
            let rel = rel
                .trim_start_matches("crates/test-support/../../")
                .to_string();
            (rel, p)
        })
        .filter(|(rel, _)| {
            !rel.ends_with("firmware/src/model/default_model.rs")
                && !rel.contains("test-kit/src/fixtures/")
        })
        .collect();
    out.sort();
    out
}

#[test]
fn no_product_file_over_the_limit_without_a_written_reason() {
    let mut unexplained = Vec::new();
    let mut pending_seen = Vec::new();
    let files = product_files();
    assert!(
        files.len() > 100,
        "found only {} product files",
        files.len()
    );
    for (rel, path) in &files {
        let text = std::fs::read_to_string(path).unwrap();
        let lines = text.lines().count();
        let reason = text
            .lines()
            .take(HEAD_LINES)
            .any(|l| l.trim_start().starts_with("//! Size:"));
        let pending = PENDING.iter().any(|(p, _)| rel.ends_with(p));
        if pending {
            pending_seen.push(rel.clone());
            assert!(
                lines > LIMIT && !reason,
                "{rel}: {lines} lines{}: remove it from PENDING",
                if reason { ", reason written" } else { "" }
            );
        } else if lines > LIMIT && !reason {
            unexplained.push(format!("{rel}: {lines} lines"));
        }
    }
    assert!(
        unexplained.is_empty(),
        "over {LIMIT} lines without a `//! Size:` reason at the top (split by concern, or \
         write why not):\n  {}",
        unexplained.join("\n  ")
    );
    for (p, _) in PENDING {
        assert!(
            pending_seen.iter().any(|s| s.ends_with(p)),
            "{p} is in PENDING but not found"
        );
    }
}
