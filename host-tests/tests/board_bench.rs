//! The board's bench binary (`board-bench`) links for the STM32G474 with every group of
//! workloads it can time: its default group and each paper-size network on its own
//! (`BENCH_WORKLOADS`, board/src/bin/board_bench.rs). Each workload's model is placed as
//! its own board image would place it, so a group that does not fit the board's SRAM or
//! CCM SRAM fails at link time; this test keeps every group linking.

use host_tests::target::{TARGET, require_target, target_dir, workspace_root};
use std::process::Command;

#[test]
fn board_bench_links_with_each_workload_group() {
    if let Err(e) = require_target() {
        panic!("{e:#}");
    }
    for group in [
        None,
        Some("lstm_paper_f32"),
        Some("lstm_paper_int16"),
        Some("lstm_paper_int8"),
    ] {
        let mut cmd = Command::new(env!("CARGO"));
        cmd.current_dir(workspace_root())
            .args(["build", "--release", "--target", TARGET, "-p", "board"])
            .args(["--bin", "board-bench", "--target-dir"])
            .arg(target_dir());
        match group {
            Some(g) => cmd.env("BENCH_WORKLOADS", g),
            None => cmd.env_remove("BENCH_WORKLOADS"),
        };
        let out = cmd.output().expect("running cargo");
        assert!(
            out.status.success(),
            "board-bench with BENCH_WORKLOADS={group:?} does not link:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}
