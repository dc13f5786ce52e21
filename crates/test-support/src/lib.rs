//! What the workspace's tests share, in one place: the workspace's paths, the real robot
//! data directory (`DATASETS_DIR`, else `../shared/datasets` beside the workspace) and the
//! one environment policy for what a machine may lack ([`available`], [`skip`]): a test
//! that needs something absent prints one `skipped: <test>: needs <what>` line and
//! passes; with `CI=true` the same absence fails the test when it is something CI
//! provides (the `thumbv7em-none-eabihf` target, `qemu-system-arm`, the tools `.ci/run`
//! installs, the shared data).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

pub mod bench;
pub mod readme;

/// The workspace root (the folder holding the root `Cargo.toml`).
pub fn workspace_root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

/// The workspace's robot descriptions (`robots/`: the built-in default robot, examples).
pub fn robots_dir() -> PathBuf {
    workspace_root().join("robots")
}

/// The real robot data directory, when it exists: `$DATASETS_DIR`, else
/// `../shared/datasets` beside the workspace.
pub fn datasets_dir() -> Option<PathBuf> {
    let dir = match std::env::var_os("DATASETS_DIR") {
        Some(d) => PathBuf::from(d),
        None => workspace_root().join("../shared/datasets"),
    };
    dir.is_dir().then_some(dir)
}

/// The UR10e logs (`<datasets>/ur10e`, holding `ur10e.urdf`), or `None` after the skip
/// line for `test` ([`Need::Datasets`]).
pub fn ur10e_dir(test: &str) -> Option<PathBuf> {
    available(test, &[Need::Datasets])
        .then(|| datasets_dir().map(|d| d.join("ur10e")))
        .flatten()
}

/// Something a test needs from the machine that a machine may lack.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Need {
    /// The firmware target's standard library (`rustup target add thumbv7em-none-eabihf`).
    FirmwareTarget,
    /// `qemu-system-arm`.
    Qemu,
    /// The shared real-robot data: `<datasets>/ur10e/ur10e.urdf` ([`datasets_dir`]).
    Datasets,
    /// `python3` that imports `torch` (CI does not install it).
    Torch,
    /// A program on `PATH` that answers `--version`; `ci`: whether CI installs it.
    Program {
        /// The program's name.
        name: &'static str,
        /// Whether `.ci/run` installs it (then its absence fails under `CI=true`).
        ci: bool,
    },
}

impl Need {
    /// Whether CI provides it (its absence fails a test when `CI=true`).
    pub fn ci_provides(self) -> bool {
        match self {
            Need::FirmwareTarget | Need::Qemu | Need::Datasets => true,
            Need::Torch => false,
            Need::Program { ci, .. } => ci,
        }
    }

    /// Whether this machine has it.
    pub fn is_present(self) -> bool {
        match self {
            Need::FirmwareTarget => has_firmware_target(),
            Need::Qemu => has_program("qemu-system-arm"),
            Need::Datasets => datasets_dir().is_some_and(|d| d.join("ur10e/ur10e.urdf").is_file()),
            Need::Torch => Command::new("python3")
                .args(["-c", "import torch"])
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .status()
                .is_ok_and(|s| s.success()),
            Need::Program { name, .. } => has_program(name),
        }
    }

    /// What to name in the skip line.
    pub fn describe(self) -> String {
        match self {
            Need::FirmwareTarget => "the thumbv7em-none-eabihf target".into(),
            Need::Qemu => "qemu-system-arm".into(),
            Need::Datasets => {
                "the UR10e data (set DATASETS_DIR or provide ../shared/datasets/ur10e)".into()
            }
            Need::Torch => "python3 with torch".into(),
            Need::Program { name, .. } => name.into(),
        }
    }
}

/// Whether `CI=true` (set by `.ci/run` and by CI services).
pub fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true")
}

/// Whether everything in `needs` is here; otherwise the one skip line for `test` naming
/// what is missing ([`skip`]), and `false`.
pub fn available(test: &str, needs: &[Need]) -> bool {
    let missing: Vec<Need> = needs.iter().copied().filter(|n| !n.is_present()).collect();
    if missing.is_empty() {
        return true;
    }
    let names: Vec<String> = missing.iter().map(|n| n.describe()).collect();
    skip(
        test,
        &names.join(" and "),
        missing.iter().any(|n| n.ci_provides()),
    );
    false
}

/// The one skip: prints `skipped: <test>: needs <missing>`; panics instead when `CI=true`
/// and `ci_provides` (CI has it, so its absence there is a failure, not a skip). For an
/// absence a test finds itself (a debug probe, a given file); [`available`] for the
/// [`Need`]s.
pub fn skip(test: &str, missing: &str, ci_provides: bool) {
    assert!(
        !(ci_provides && in_ci()),
        "{test}: needs {missing}, which CI provides (CI=true)"
    );
    println!("skipped: {test}: needs {missing}");
}

/// Whether `program --version` runs on this machine.
pub fn has_program(program: &str) -> bool {
    Command::new(program)
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Whether the firmware target's standard library is installed (`rustup target add
/// thumbv7em-none-eabihf`).
pub fn has_firmware_target() -> bool {
    let rustc = std::env::var_os("RUSTC").unwrap_or_else(|| "rustc".into());
    let Ok(out) = Command::new(rustc)
        .args(["--print", "sysroot"])
        .stderr(Stdio::null())
        .output()
    else {
        return false;
    };
    let sysroot = String::from_utf8_lossy(&out.stdout).trim().to_string();
    Path::new(&sysroot)
        .join("lib/rustlib/thumbv7em-none-eabihf/lib")
        .is_dir()
}

/// Whether the QEMU target tests can run here: the firmware target and `qemu-system-arm`
/// ([`available`]).
pub fn target_tools_or_skip(what: &str) -> bool {
    available(what, &[Need::FirmwareTarget, Need::Qemu])
}

/// The text of the built-in default robot's description (`robots/default.toml`).
pub fn default_robot_toml() -> String {
    std::fs::read_to_string(robots_dir().join("default.toml")).expect("robots/default.toml")
}
