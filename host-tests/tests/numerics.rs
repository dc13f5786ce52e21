//! Identical numerics: the firmware's math primitives and dot products give the
//! same bits on the host and on the Cortex-M4F target (QEMU mps2-an386).
use host_tests::{golden, qemu, target};
use test_support::{Need, available};

#[test]
fn target_and_host_math_are_bit_identical() {
    if !available(
        "the QEMU golden suites",
        &[Need::FirmwareTarget, Need::Qemu],
    ) {
        return;
    }
    let elf = target::build(target::FirmwareBin::Qemu).unwrap_or_else(|e| panic!("{e:#}"));
    let report = qemu::run(&elf).unwrap_or_else(|e| panic!("{e:#}"));
    for check in golden::check_report(&report).unwrap_or_else(|e| panic!("{e:#}")) {
        match check.result {
            Ok(n) => println!("{}: {n} results bit-identical", check.name),
            Err(m) => panic!("{}: first mismatch: {m}", check.name),
        }
    }
}
