//! The budget file's one typed schema (`host-tests/budgets.toml`): the MCU, each
//! binary's flash and RAM limits, each workload's cycle limit. Read by the budget tool
//! (`host-tests`, [`Budgets::load`]: every section, validated) and by `model-export
//! export` (`fw-export`, [`Budgets::read`]: the board binary's limits and the memory
//! layout it names; a file holding only those is enough). Unknown fields are refused.
use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// The MCU the budgets are for.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Mcu {
    /// Part name.
    pub name: String,
    /// Core clock in Hz.
    pub clock_hz: u64,
    /// Control rates the report prints the tick share for, in Hz.
    pub control_rates_hz: Vec<u64>,
    /// A workload without its own cycle limit must fit in one tick at this rate.
    pub control_rate_hz: u64,
    /// The board's linker memory layout, relative to the budget file (the exporter
    /// reads its RAM length for a model's SRAM budget).
    pub memory_layout: Option<String>,
}

/// Flash and RAM limits of one binary.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct BinaryBudget {
    /// Flash limit in bytes.
    pub flash_bytes: u64,
    /// RAM limit in bytes (static data + the stack reserve must fit).
    pub ram_bytes: u64,
    /// Bytes of RAM reserved for the stack.
    pub stack_reserve_bytes: u64,
    /// Bytes of RAM the firmware's own static data may take beside a model's arrays
    /// (the exporter's SRAM budget for them is what remains).
    #[serde(default)]
    pub firmware_ram_bytes: Option<u64>,
    /// Bytes of CCM SRAM kept for the per-tick code (the exporter may place model data
    /// in the rest of the `CCMRAM` region).
    #[serde(default)]
    pub ccm_code_reserve_bytes: Option<u64>,
}

/// The budget file.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Budgets {
    /// The MCU.
    #[serde(default)]
    pub mcu: Mcu,
    /// Per binary (cargo binary name): flash and RAM limits.
    #[serde(default)]
    pub binary: BTreeMap<String, BinaryBudget>,
    /// Per workload (`Workload::NAME`): estimated cycles of its worst traced tick.
    #[serde(default)]
    pub cycles: BTreeMap<String, u64>,
}

impl Budgets {
    /// Parses a budget file (sections may be absent; [`Budgets::load`] requires them).
    /// Errors name the file (and the line and field, from the TOML reader).
    pub fn read(path: &Path) -> Result<Budgets> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        toml::from_str(&text).with_context(|| format!("parsing {}", path.display()))
    }

    /// Reads and validates a whole budget file, as the budget tool needs it: the MCU's
    /// part name, positive clock and control rates.
    pub fn load(path: &Path) -> Result<Budgets> {
        let b = Budgets::read(path)?;
        if b.mcu.name.is_empty() {
            bail!("{}: field `mcu.name` missing", path.display());
        }
        if b.mcu.clock_hz == 0 || b.mcu.control_rate_hz == 0 || b.mcu.control_rates_hz.contains(&0)
        {
            bail!(
                "{}: clock and control rates must be positive",
                path.display()
            );
        }
        Ok(b)
    }

    /// Cycle limit of a workload: its own, or one whole tick at the control rate.
    pub fn cycle_limit(&self, workload: &str) -> u64 {
        self.cycles
            .get(workload)
            .copied()
            .unwrap_or(self.mcu.clock_hz / self.mcu.control_rate_hz.max(1))
    }

    /// The board binary's limits (`binary.board`), or an error naming the file.
    pub fn board(&self, path: &Path) -> Result<&BinaryBudget> {
        self.binary
            .get("board")
            .with_context(|| format!("{}: section `binary.board` missing", path.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, text: &str) -> std::path::PathBuf {
        let p = dir.join("budgets.toml");
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn the_checked_in_file_loads() {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../host-tests/budgets.toml");
        let b = Budgets::load(&p).unwrap();
        assert_eq!(b.mcu.name, "STM32G474RE");
        assert!(b.board(&p).unwrap().flash_bytes > 0);
    }

    #[test]
    fn a_partial_file_reads_but_does_not_load_and_unknown_fields_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = write(
            dir.path(),
            "[binary.board]\nflash_bytes = 4096\nram_bytes = 1\nstack_reserve_bytes = 1\n",
        );
        assert_eq!(
            Budgets::read(&p).unwrap().board(&p).unwrap().flash_bytes,
            4096
        );
        let e = format!("{:#}", Budgets::load(&p).unwrap_err());
        assert!(e.contains("mcu.name"), "{e}");
        let p = write(dir.path(), "[mcu]\nclock = 1\n");
        let e = format!("{:#}", Budgets::read(&p).unwrap_err());
        assert!(e.contains("budgets.toml") && e.contains("clock"), "{e}");
        let p = write(dir.path(), "[binary.board]\nflash_bytes = -1\n");
        let e = format!("{:#}", Budgets::read(&p).unwrap_err());
        assert!(e.contains("budgets.toml") && e.contains("line 2"), "{e}");
    }
}
