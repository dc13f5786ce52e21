//! Running the QEMU binary on `qemu-system-arm -M mps2-an386`.
use anyhow::{Context, Result, bail};
use std::path::Path;
use std::process::Command;

/// The QEMU executable.
pub const QEMU: &str = "qemu-system-arm";

/// The machine and options every run uses: no display, semihosting to the host's
/// stdout, and a deterministic instruction-counting clock.
pub const BASE_ARGS: [&str; 8] = [
    "-M",
    "mps2-an386",
    "-nographic",
    "-semihosting-config",
    "enable=on,target=native",
    "-icount",
    "shift=0",
    "-no-reboot",
];

/// Fails with what to install when QEMU is missing.
pub fn require_qemu() -> Result<()> {
    match Command::new(QEMU).arg("--version").output() {
        Ok(o) if o.status.success() => Ok(()),
        _ => bail!(
            "`{QEMU}` was not found: install it (Debian: `apt-get install -y qemu-system-arm`, \
             or run `bash .ci/run`, which installs it)"
        ),
    }
}

/// Runs `elf` under QEMU and returns its semihosting output. A non-zero exit (a
/// failed semihosting exit, a panic or a HardFault) is an error carrying the output.
pub fn run(elf: &Path) -> Result<String> {
    require_qemu()?;
    let out = Command::new(QEMU)
        .args(BASE_ARGS)
        .arg("-kernel")
        .arg(elf)
        .output()
        .with_context(|| format!("starting {QEMU}"))?;
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    if !out.status.success() {
        let tail: Vec<&str> = stdout.lines().rev().take(5).collect();
        bail!(
            "{} exited with {} under {QEMU}; last lines: {:?}; stderr: {}",
            elf.display(),
            out.status,
            tail,
            String::from_utf8_lossy(&out.stderr)
        );
    }
    Ok(stdout)
}
