//! Builds the QEMU test binary, runs it under qemu-system-arm, compares every
//! result with the host's and prints a summary table (`--raw`: the raw report).
use host_tests::{golden, qemu, target};

fn main() -> std::process::ExitCode {
    let raw = std::env::args().any(|a| a == "--raw");
    let run = || -> anyhow::Result<bool> {
        let elf = target::build(target::FirmwareBin::Qemu)?;
        let report = qemu::run(&elf)?;
        if raw {
            print!("{report}");
            return Ok(true);
        }
        println!("| suite | results | target vs host |");
        println!("|---|---:|---|");
        let mut all_same = true;
        for check in golden::check_report(&report)? {
            match check.result {
                Ok(n) => println!("| {} | {n} | bit-identical |", check.name),
                Err(m) => {
                    all_same = false;
                    println!("| {} | - | first mismatch: {m} |", check.name);
                }
            }
        }
        Ok(all_same)
    };
    match run() {
        Ok(true) => std::process::ExitCode::SUCCESS,
        Ok(false) => std::process::ExitCode::FAILURE,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
