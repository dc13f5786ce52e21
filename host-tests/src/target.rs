//! Building the firmware's target binaries from the host.
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The firmware's target triple.
pub const TARGET: &str = "thumbv7em-none-eabihf";

/// The workspace root (where `Cargo.toml` and `.cargo/` live).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("host-tests lives one level below the workspace root")
        .to_path_buf()
}

/// Target directory for the thumb builds: separate from the host's, so a build
/// started from inside `cargo test` never waits on the outer cargo's lock.
pub fn target_dir() -> PathBuf {
    workspace_root().join("target").join("thumb")
}

/// A firmware binary for the target.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FirmwareBin {
    /// The STM32G474RE board binary (package `board`, `board/memory.x`).
    Board,
    /// The mjbots moteus r4.11 bring-up binary (package `board`, `board/memory.x`).
    BoardMoteus,
    /// The QEMU mps2-an386 test binary (package `firmware/qemu`).
    Qemu,
    /// The QEMU mps2-an386 bench binary: runs every registered workload
    /// (`test_kit::bench`) for the cycle estimator (package `firmware/qemu`).
    QemuBench,
    /// The board's bench binary: times a group of workloads with DWT CYCCNT on the
    /// STM32G474 (package `board`, [`build_board_bench`]).
    BoardBench,
}

impl FirmwareBin {
    /// Cargo binary name (also the ELF's file name).
    pub const fn name(self) -> &'static str {
        match self {
            FirmwareBin::Board => "board",
            FirmwareBin::BoardMoteus => "board-moteus",
            FirmwareBin::Qemu => "firmware-qemu",
            FirmwareBin::QemuBench => "firmware-qemu-bench",
            FirmwareBin::BoardBench => "board-bench",
        }
    }

    /// Cargo arguments that select this binary's package and features.
    fn cargo_args(self) -> &'static [&'static str] {
        match self {
            FirmwareBin::Board | FirmwareBin::BoardMoteus => &["-p", "board"],
            FirmwareBin::BoardBench => &["-p", "board", "--features", "bench"],
            FirmwareBin::Qemu | FirmwareBin::QemuBench => {
                &["--manifest-path", "firmware/qemu/Cargo.toml"]
            }
        }
    }
}

/// Fails with what to install when the Rust target is missing.
pub fn require_target() -> Result<()> {
    let out = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .current_dir(workspace_root())
        .output();
    match out {
        Ok(o)
            if String::from_utf8_lossy(&o.stdout)
                .lines()
                .any(|l| l.trim() == TARGET) =>
        {
            Ok(())
        }
        Ok(_) => bail!(
            "the Rust target {TARGET} is not installed: run `rustup target add {TARGET}` \
             (or `bash .ci/run`, which installs it)"
        ),
        Err(e) => bail!("cannot run rustup to check for the {TARGET} target ({e}); install rustup"),
    }
}

/// Builds a firmware binary in release for the target and returns the ELF path.
pub fn build(bin: FirmwareBin) -> Result<PathBuf> {
    build_with(bin, None)
}

/// Builds a firmware binary in release, optionally with another `opt-level` than the
/// checked-in release profile (`CARGO_PROFILE_RELEASE_OPT_LEVEL`, in its own target
/// directory `target/thumb-opt-LEVEL` so the default build stays cached).
pub fn build_with(bin: FirmwareBin, opt_level: Option<&str>) -> Result<PathBuf> {
    match opt_level {
        None => cargo_build(bin, target_dir(), &[]),
        Some(level) => cargo_build(
            bin,
            workspace_root()
                .join("target")
                .join(format!("thumb-opt-{level}")),
            &[("CARGO_PROFILE_RELEASE_OPT_LEVEL", Some(level))],
        ),
    }
}

/// Builds a firmware binary in release with `model` (a file written by `model-export
/// export`) compiled in as the firmware's model (`FIRMWARE_MODEL`), in its own target
/// directory `target/thumb-model` so the default build stays cached.
pub fn build_with_model(bin: FirmwareBin, model: &Path) -> Result<PathBuf> {
    let model = model
        .canonicalize()
        .with_context(|| format!("resolving {}", model.display()))?;
    let model = model
        .to_str()
        .with_context(|| format!("{}: not a UTF-8 path", model.display()))?;
    cargo_build(
        bin,
        workspace_root().join("target").join("thumb-model"),
        &[("FIRMWARE_MODEL", Some(model))],
    )
}

/// Builds the board's bench binary in release with the workloads named in `workloads`
/// (`BENCH_WORKLOADS`, comma-separated), or its default group for `None`.
pub fn build_board_bench(workloads: Option<&str>) -> Result<PathBuf> {
    cargo_build(
        FirmwareBin::BoardBench,
        target_dir(),
        &[("BENCH_WORKLOADS", workloads)],
    )
}

/// `cargo build --release` of `bin` for the target into `dir`, with `env` set (a value)
/// or removed (`None`); the ELF path.
fn cargo_build(bin: FirmwareBin, dir: PathBuf, env: &[(&str, Option<&str>)]) -> Result<PathBuf> {
    require_target()?;
    let mut cmd = Command::new(env!("CARGO"));
    cmd.current_dir(workspace_root())
        .args([
            "build",
            "--release",
            "--target",
            TARGET,
            "--bin",
            bin.name(),
        ])
        .args(bin.cargo_args())
        .arg("--target-dir")
        .arg(&dir);
    for (name, value) in env {
        match value {
            Some(v) => cmd.env(name, v),
            None => cmd.env_remove(name),
        };
    }
    let status = cmd
        .status()
        .context("running cargo to build the firmware")?;
    if !status.success() {
        bail!(
            "building firmware binary `{}` for {TARGET} failed ({status})",
            bin.name()
        );
    }
    let elf = dir.join(TARGET).join("release").join(bin.name());
    if !elf.is_file() {
        bail!("cargo reported success but {} is missing", elf.display());
    }
    Ok(elf)
}
