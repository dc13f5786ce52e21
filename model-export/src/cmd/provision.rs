//! `model-export provision`: a drive's configuration block (which robot joint it
//! drives, the robot's state-bus key) as the `.bin` the debug probe writes into the
//! board's configuration page, and the `probe-rs download` line that writes it.
use anyhow::{Context, Result, bail};
use clap::Args;
use firmware::control::JointConfigBlock;
use std::path::{Path, PathBuf};

/// Start of the board's configuration page (`BOARD_CONFIG` in board/memory.x).
pub const CONFIG_BLOCK_ADDRESS: u32 = 0x0807_F800;

/// `provision` options.
#[derive(Debug, Args)]
pub struct ProvisionArgs {
    /// The robot joint the drive runs as, counted from 1 (as `--joints`).
    #[arg(long)]
    pub joint: u8,
    /// The robot's state-bus key: a file holding 32 hex digits (16 bytes; spaces and
    /// line breaks are ignored), the same for every drive of one robot.
    #[arg(long)]
    pub key_file: PathBuf,
    /// The configuration block to write (`.bin`, 32 bytes).
    #[arg(long, short = 'o')]
    pub out: PathBuf,
}

/// The 16-byte key of a key file's text (`path` names the file in errors).
pub fn parse_key(path: &Path, text: &str) -> Result<[u8; 16]> {
    let mut digits = Vec::new();
    for (n, line) in text.lines().enumerate() {
        for (col, c) in line.chars().enumerate() {
            if c.is_whitespace() {
                continue;
            }
            let Some(d) = c.to_digit(16) else {
                bail!(
                    "{}:{}:{}: the bus key: `{c}` is not a hex digit",
                    path.display(),
                    n + 1,
                    col + 1
                );
            };
            digits.push(d as u8);
        }
    }
    if digits.len() != 32 {
        bail!(
            "{}: the bus key: {} hex digits, 32 wanted (16 bytes)",
            path.display(),
            digits.len()
        );
    }
    let mut key = [0u8; 16];
    for (k, pair) in key.iter_mut().zip(digits.chunks(2)) {
        *k = (pair[0] << 4) | pair[1];
    }
    if key.iter().all(|&b| b == 0) || key.iter().all(|&b| b == 0xFF) {
        bail!(
            "{}: the bus key is all {}: draw a random one",
            path.display(),
            if key[0] == 0 { "zero" } else { "0xFF" }
        );
    }
    Ok(key)
}

/// The `probe-rs download` line that writes `bin` into the configuration page.
pub fn probe_rs_line(bin: &Path) -> String {
    format!(
        "probe-rs download --chip STM32G474RETx --binary-format bin --base-address 0x{CONFIG_BLOCK_ADDRESS:08X} {}",
        bin.display()
    )
}

/// Runs `provision`.
pub fn run(a: &ProvisionArgs) -> Result<()> {
    if a.joint == 0 {
        bail!("--joint: joints are counted from 1");
    }
    let text = std::fs::read_to_string(&a.key_file)
        .with_context(|| format!("reading {}", a.key_file.display()))?;
    let bus_key = parse_key(&a.key_file, &text)?;
    let block = JointConfigBlock {
        joint_number: a.joint,
        bus_key,
    }
    .encode();
    // What the board's start-up reads back (a layout mistake fails here, not on the robot).
    if JointConfigBlock::decode(&block).map(|b| (b.joint_number, b.bus_key))
        != Ok((a.joint, bus_key))
    {
        bail!("the block for joint {} does not read back", a.joint);
    }
    artifacts::write_atomic(&a.out, &block)?;
    println!(
        "{}: configuration block for joint {} ({} bytes); write it with the debug probe:",
        a.out.display(),
        a.joint,
        block.len()
    );
    println!("{}", probe_rs_line(&a.out));
    Ok(())
}
