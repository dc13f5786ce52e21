//! What the workspace's tests share, in one place: the workspace's paths, the real robot
//! data directory (`DATASETS_DIR`, else `../shared/datasets` beside the workspace) and
//! whether this machine has the target tools (the `thumbv7em-none-eabihf` target,
//! `qemu-system-arm`). A test that needs something absent prints one `skipped: ...` line
//! and passes; CI has none of them.

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

/// The UR10e logs (`<datasets>/ur10e`, holding `ur10e.urdf`), or `None` after printing
/// the skip line.
pub fn ur10e_dir() -> Option<PathBuf> {
    match datasets_dir().map(|d| d.join("ur10e")) {
        Some(d) if d.join("ur10e.urdf").is_file() => Some(d),
        _ => {
            println!(
                "skipped: UR10e data not found (set DATASETS_DIR or provide ../shared/datasets/ur10e)"
            );
            None
        }
    }
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

/// Whether the QEMU target tests can run here: the firmware target and `qemu-system-arm`.
/// Prints the skip line naming what is missing when they cannot.
pub fn target_tools_or_skip(what: &str) -> bool {
    let mut missing = Vec::new();
    if !has_firmware_target() {
        missing.push("the thumbv7em-none-eabihf target");
    }
    if !has_program("qemu-system-arm") {
        missing.push("qemu-system-arm");
    }
    if missing.is_empty() {
        return true;
    }
    println!("skipped: {what} needs {}", missing.join(" and "));
    false
}

/// The text of the built-in default robot's description (`robots/default.toml`).
pub fn default_robot_toml() -> String {
    std::fs::read_to_string(robots_dir().join("default.toml")).expect("robots/default.toml")
}
