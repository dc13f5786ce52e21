//! The board's bench binary (`board-bench`) links for the STM32G474 with every group of
//! workloads it can time: its default group, and each paper-size network and the PWM
//! tick on its own (`BENCH_WORKLOADS`, board/src/bin/board_bench.rs). Each workload's
//! model is placed as its own board image would place it, so a group that does not fit the board's SRAM or
//! CCM SRAM fails at link time; this test keeps every group linking.

use host_tests::target::build_board_bench;
use test_support::{Need, available};

#[test]
fn board_bench_links_with_each_workload_group() {
    if !available("the board bench link", &[Need::FirmwareTarget]) {
        return;
    }
    for group in [
        None,
        Some("lstm_paper_f32"),
        Some("lstm_paper_int16"),
        Some("lstm_paper_int8"),
        Some("drive_pwm_tick"),
    ] {
        if let Err(e) = build_board_bench(group) {
            panic!("board-bench with BENCH_WORKLOADS={group:?} does not link: {e:#}");
        }
    }
}
