//! Both release board images (`board`, the generic STM32G474RE board; `board-moteus`,
//! the moteus r4.11 bring-up image) contain no panic path: no function whose name is
//! a panic entry point (`core::panicking::*`, `rust_begin_unwind`, a
//! `#[panic_handler]`) is linked, and with `--gc-sections` an unreferenced function is
//! not linked, so none is reachable. Builds both (release, thumbv7em-none-eabihf,
//! `target/thumb`, without `defmt`).

use host_tests::elf;
use host_tests::target::{self, FirmwareBin};
use test_support::{Need, available};

/// A function name that is a panic path's entry.
fn is_panic_function(name: &str) -> bool {
    let n = name.to_ascii_lowercase();
    n.contains("panic") || n.contains("rust_begin_unwind") || n.contains("unwrap_failed")
}

#[test]
fn the_detector_knows_the_panic_entry_points() {
    for name in [
        "core::panicking::panic",
        "core::panicking::panic_bounds_check",
        "core::panicking::panic_fmt",
        "core::option::unwrap_failed",
        "core::result::unwrap_failed",
        "rust_begin_unwind",
        "panic_halt::panic",
    ] {
        assert!(is_panic_function(name), "{name}");
    }
    for name in [
        "board::pins::init",
        "firmware::drivers::drv83x3::Drv83x3::start_up",
        "ADC1_2",
    ] {
        assert!(!is_panic_function(name), "{name}");
    }
}

#[test]
fn no_panic_path_in_either_board_image() {
    if !available("the board images' panic check", &[Need::FirmwareTarget]) {
        return;
    }
    for bin in [FirmwareBin::Board, FirmwareBin::BoardMoteus] {
        let elf_path = target::build(bin).unwrap_or_else(|e| panic!("{e:#}"));
        let fns = elf::functions(&elf_path).unwrap_or_else(|e| panic!("{e:#}"));
        // The image parsed: cortex-m-rt's reset handler is among its functions.
        assert!(
            fns.iter().any(|f| f.name == "Reset"),
            "{}: no Reset among {} functions",
            bin.name(),
            fns.len()
        );
        let panics: Vec<_> = fns
            .iter()
            .filter(|f| is_panic_function(&f.name))
            .map(|f| f.name.as_str())
            .collect();
        println!(
            "{}: {} functions, {} panic functions",
            bin.name(),
            fns.len(),
            panics.len()
        );
        assert!(
            panics.is_empty(),
            "{} links panic paths: {panics:?}",
            bin.name()
        );
    }
}
