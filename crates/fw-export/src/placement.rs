//! Where the model's arrays live on the target (flash, SRAM, CCM SRAM) and the budget
//! the choice is weighed against: the budget file (`budgets`, the budget tool's schema)
//! and the board's linker memory layout.
use super::*;

/// The `link_section` attribute of the model's arrays placed in SRAM: an input section
/// of cortex-m-rt's `.data` (run address in RAM, load image in flash, copied by its
/// reset handler before `main`, so the static holds its value whenever Rust code reads
/// it; `unsafe_code` is allowed for this one attribute of the static). Host builds
/// ignore it.
pub const SRAM_SECTION_ATTRIBUTE: &str = "#[cfg_attr(target_os = \"none\", allow(unsafe_code), \
     unsafe(link_section = \".data.model_arrays\"))]";

/// The `link_section` attribute of the gate blocks placed in CCM SRAM: an input section
/// of `.ccmram_data` (both `memory.x` files: run address in CCM SRAM, load image in
/// flash, copied at start-up by `ccm::copy_code` before `main` reads it; the linker
/// fails when code and data outgrow CCM SRAM). Host builds ignore it.
pub const CCM_SECTION_ATTRIBUTE: &str = "#[cfg_attr(target_os = \"none\", allow(unsafe_code), \
     unsafe(link_section = \".ccmram_data.model_arrays\"))]";

/// Where the exporter puts the model's arrays (network, linear stage, rigid-body model).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Placement {
    /// Flash (`.rodata`), read over the flash interface every tick.
    Flash,
    /// SRAM (`.data`, copied from flash at reset): zero wait states.
    Sram,
}

/// Where `export --weights-in` puts the model's arrays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeightsIn {
    /// Flash.
    Flash,
    /// SRAM (an error when a budget file is given and they do not fit its SRAM budget).
    Sram,
    /// SRAM when they fit the budget file's SRAM budget, flash otherwise (and without a
    /// budget file).
    Auto,
}

impl WeightsIn {
    /// Every choice, in the order the command line lists them.
    pub const ALL: [Self; 3] = [Self::Flash, Self::Sram, Self::Auto];

    /// The choice's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Flash => "flash",
            Self::Sram => "sram",
            Self::Auto => "auto",
        }
    }
}

/// Reads the board's flash limit from a budget file (`budgets::Budgets`, the budget
/// tool's schema).
pub fn flash_budget(path: &std::path::Path) -> anyhow::Result<u64> {
    let b = budgets::Budgets::read(path)?;
    let flash = b.board(path)?.flash_bytes;
    if flash == 0 {
        bail!(
            "{}: field `binary.board.flash_bytes` = 0: must be a positive byte count",
            path.display()
        );
    }
    Ok(flash)
}

/// Reads the board's SRAM budget for a model's arrays from a budget file and the
/// linker memory layout it names (`mcu.memory_layout`, relative to the budget file).
pub fn sram_budget(path: &std::path::Path) -> anyhow::Result<SramBudget> {
    let b = budgets::Budgets::read(path)?;
    let board = b.board(path)?;
    let layout = b
        .mcu
        .memory_layout
        .as_deref()
        .with_context(|| format!("{}: field `mcu.memory_layout` missing", path.display()))?;
    let layout = path
        .parent()
        .unwrap_or(std::path::Path::new("."))
        .join(layout);
    let layout_text = std::fs::read_to_string(&layout).with_context(|| {
        format!(
            "reading {} (`mcu.memory_layout` of {})",
            layout.display(),
            path.display()
        )
    })?;
    let layout_ram_bytes =
        layout_ram_bytes(&layout_text).map_err(|e| anyhow::anyhow!("{}: {e}", layout.display()))?;
    let ram_limit_bytes = board.ram_bytes;
    let stack_reserve_bytes = board.stack_reserve_bytes;
    let firmware_ram_bytes = board.firmware_ram_bytes.with_context(|| {
        format!(
            "{}: field `binary.board.firmware_ram_bytes` missing",
            path.display()
        )
    })?;
    // CCM SRAM for model data: optional (a layout without the region, or a budget file
    // without the code reserve, places nothing there).
    let ccm_code_reserve_bytes = board.ccm_code_reserve_bytes;
    let layout_ccm_bytes = layout_region_bytes(&layout_text, "CCMRAM")
        .map_err(|e| anyhow::anyhow!("{}: {e}", layout.display()))?
        .unwrap_or(0);
    Ok(SramBudget {
        layout_ram_bytes,
        ram_limit_bytes,
        stack_reserve_bytes,
        firmware_ram_bytes,
        layout_ccm_bytes,
        ccm_code_reserve_bytes,
    })
}

/// Chooses where each of the model's arrays lives, and the activation tables its
/// network reads. `auto` fills the SRAM budget in the order of what a tick reads most:
/// the network, then the rigid-body model, then the linear stage; each goes to SRAM
/// when it fits what is left, to flash otherwise. The activation tables (an integer
/// network's; an f32 network reads none) go to SRAM when they fit what the arrays
/// left, with `auto` and with `sram` (which puts the arrays in SRAM or fails), to
/// flash otherwise; with `flash` everything stays in flash, and without a budget
/// `sram` puts the tables in SRAM too.
pub fn choose_placement(
    want: WeightsIn,
    bytes: ModelBytes,
    budget: Option<ModelBudget>,
) -> Result<PlacementChoice> {
    let sram_budget_bytes = budget.map(|b| b.sram_bytes);
    let total = bytes.network + bytes.dynamics + bytes.linear_stage;
    let all = |p| [p; 3];
    let [network, dynamics, linear_stage] = match (want, sram_budget_bytes) {
        (WeightsIn::Flash, _) | (WeightsIn::Auto, None) => all(Placement::Flash),
        (WeightsIn::Sram, None) => all(Placement::Sram),
        (WeightsIn::Sram, Some(b)) if total as u64 <= b => all(Placement::Sram),
        (WeightsIn::Sram, Some(b)) => bail!(
            "--weights-in sram: the model's arrays need {total} bytes, over the SRAM budget \
             of {b} bytes (the board's RAM less the stack reserve and the firmware's own RAM)"
        ),
        (WeightsIn::Auto, Some(b)) => {
            let mut left = b;
            [bytes.network, bytes.dynamics, bytes.linear_stage].map(|n| {
                if n as u64 <= left {
                    left -= n as u64;
                    Placement::Sram
                } else {
                    Placement::Flash
                }
            })
        }
    };
    let arrays_in_sram = [
        (network, bytes.network),
        (dynamics, bytes.dynamics),
        (linear_stage, bytes.linear_stage),
    ]
    .iter()
    .filter(|(p, _)| *p == Placement::Sram)
    .map(|(_, n)| *n as u64)
    .sum::<u64>();
    // A network too big for SRAM: the first blocks of its gate matrix fill what is left,
    // the next ones the CCM SRAM budget.
    let whole_blocks =
        |left: u64, at_most: usize| ((left / bytes.gate_block.max(1) as u64) as usize).min(at_most);
    let (gate_blocks_in_sram, gate_blocks_in_ccm) = match (want, budget, network) {
        (WeightsIn::Auto, Some(b), Placement::Flash) if bytes.gate_block > 0 => {
            let sram = whole_blocks(
                b.sram_bytes.saturating_sub(arrays_in_sram),
                bytes.gate_blocks,
            );
            let ccm = whole_blocks(b.ccm_bytes, bytes.gate_blocks - sram);
            (sram, ccm)
        }
        _ => (0, 0),
    };
    let in_sram = arrays_in_sram + (gate_blocks_in_sram * bytes.gate_block) as u64;
    let act_tables = (bytes.act_tables > 0).then(|| match (want, sram_budget_bytes) {
        (WeightsIn::Flash, _) | (WeightsIn::Auto, None) => Placement::Flash,
        (WeightsIn::Sram, None) => Placement::Sram,
        (WeightsIn::Sram | WeightsIn::Auto, Some(b)) => {
            if in_sram + bytes.act_tables as u64 <= b {
                Placement::Sram
            } else {
                Placement::Flash
            }
        }
    });
    Ok(PlacementChoice {
        network,
        dynamics,
        linear_stage,
        act_tables,
        gate_blocks_in_sram,
        gate_blocks_in_ccm,
        bytes,
        sram_budget_bytes,
        ccm_budget_bytes: budget.map(|b| b.ccm_bytes),
    })
}

/// Bytes of each of the model's arrays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModelBytes {
    /// `NETWORK`.
    pub network: usize,
    /// `DYNAMICS` (0 without a rigid-body model).
    pub dynamics: usize,
    /// `LINEAR_STAGE`.
    pub linear_stage: usize,
    /// The activation tables the network reads (`firmware::nn::act`; 0 when it reads
    /// none).
    pub act_tables: usize,
    /// Bytes of one block of the gate matrix when the network can place the first
    /// blocks of its gate matrix in SRAM apart from the rest (`F32GateRows`, f32
    /// networks), else 0.
    pub gate_block: usize,
    /// Blocks of the gate matrix (`H`).
    pub gate_blocks: usize,
}

/// Where each of the model's arrays lives, and the budget the choice was weighed against.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlacementChoice {
    /// `NETWORK`.
    pub network: Placement,
    /// `DYNAMICS`.
    pub dynamics: Placement,
    /// `LINEAR_STAGE`.
    pub linear_stage: Placement,
    /// The activation tables (`Format::ACT_TABLES`); `None` when the network reads none.
    pub act_tables: Option<Placement>,
    /// With the network in flash: the first blocks of its gate matrix placed in SRAM
    /// (`GATES_HEAD`; 0 for none, always 0 for an integer network).
    pub gate_blocks_in_sram: usize,
    /// With the network in flash: the blocks after those placed in CCM SRAM
    /// (`GATES_MIDDLE`; 0 for none).
    pub gate_blocks_in_ccm: usize,
    /// Their sizes.
    pub bytes: ModelBytes,
    /// The SRAM budget for the model's arrays [bytes], when a budget file was given.
    pub sram_budget_bytes: Option<u64>,
    /// The CCM SRAM budget for model data [bytes], when a budget file was given.
    pub ccm_budget_bytes: Option<u64>,
}

impl PlacementChoice {
    /// One line describing the choice (the generated file's header and `export`'s output).
    pub fn describe(&self) -> String {
        let at = |p: Placement| match p {
            Placement::Sram => "SRAM",
            Placement::Flash => "flash",
        };
        // The CCM SRAM budget is named where the choice used it.
        let budget = match (self.sram_budget_bytes, self.ccm_budget_bytes) {
            (Some(b), Some(c)) if self.gate_blocks_in_ccm > 0 => {
                format!("SRAM budget for the model {b} bytes, CCM SRAM budget {c} bytes")
            }
            (Some(b), _) => format!("SRAM budget for the model {b} bytes"),
            (None, _) => "no budget file".to_string(),
        };
        let tables = match self.act_tables {
            Some(p) => format!(
                "activation tables {} bytes in {}",
                self.bytes.act_tables,
                at(p)
            ),
            None => "no activation tables (f32)".to_string(),
        };
        let split = match (self.gate_blocks_in_sram, self.gate_blocks_in_ccm) {
            (0, 0) => String::new(),
            (k, 0) => format!(
                " (its gate matrix's first {k} of {} blocks, {} bytes, in SRAM)",
                self.bytes.gate_blocks,
                k * self.bytes.gate_block
            ),
            (k, m) => format!(
                " (its gate matrix's first {k} of {} blocks, {} bytes, in SRAM, the next {m}, \
                 {} bytes, in CCM SRAM)",
                self.bytes.gate_blocks,
                k * self.bytes.gate_block,
                m * self.bytes.gate_block
            ),
        };
        format!(
            "network {} bytes in {}{split}, rigid-body model {} bytes in {}, linear stage {} bytes in {}, \
             {tables} (SRAM: .data, copied from flash at reset; flash: .rodata); {budget}",
            self.bytes.network,
            at(self.network),
            self.bytes.dynamics,
            at(self.dynamics),
            self.bytes.linear_stage,
            at(self.linear_stage),
        )
    }
}

/// The board's SRAM budget for a model's arrays, from the budget file and the linker
/// memory layout it names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SramBudget {
    /// Length of the `RAM` region in the memory layout (`memory.x`) [bytes].
    pub layout_ram_bytes: u64,
    /// The board binary's RAM limit (`binary.board.ram_bytes`) [bytes].
    pub ram_limit_bytes: u64,
    /// The board's stack reserve (`binary.board.stack_reserve_bytes`) [bytes].
    pub stack_reserve_bytes: u64,
    /// RAM of the board firmware's own static data and buffers
    /// (`binary.board.firmware_ram_bytes`) [bytes].
    pub firmware_ram_bytes: u64,
    /// Length of the `CCMRAM` region in the memory layout [bytes] (0 without one).
    pub layout_ccm_bytes: u64,
    /// CCM SRAM kept for the per-tick code (`binary.board.ccm_code_reserve_bytes`)
    /// [bytes]; without the field no model data goes to CCM SRAM.
    pub ccm_code_reserve_bytes: Option<u64>,
}

/// What the board leaves for a model's arrays: SRAM and CCM SRAM [bytes].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModelBudget {
    /// SRAM (`.data`).
    pub sram_bytes: u64,
    /// CCM SRAM beside the per-tick code (`.ccmram_data`).
    pub ccm_bytes: u64,
}

impl SramBudget {
    /// Bytes left for the model's arrays: in SRAM the smaller of the two RAM sizes,
    /// less the stack reserve and the firmware's own static RAM; in CCM SRAM the
    /// region's length less the code reserve (0 without either).
    pub fn model_bytes(&self) -> ModelBudget {
        ModelBudget {
            sram_bytes: self
                .layout_ram_bytes
                .min(self.ram_limit_bytes)
                .saturating_sub(self.stack_reserve_bytes)
                .saturating_sub(self.firmware_ram_bytes),
            ccm_bytes: self
                .ccm_code_reserve_bytes
                .map_or(0, |r| self.layout_ccm_bytes.saturating_sub(r)),
        }
    }
}

/// Length in bytes of the `RAM` region of a linker memory layout (`memory.x`):
/// `RAM : ORIGIN = ..., LENGTH = 96K` (decimal or `0x` hex, optional `K` or `M`).
/// Errors name the line.
pub fn layout_ram_bytes(text: &str) -> Result<u64, String> {
    layout_region_bytes(text, "RAM")?.ok_or_else(|| "no RAM region".into())
}

/// Length in bytes of the region `name` of a linker memory layout (`memory.x`), `None`
/// when the layout has no such region. Errors name the line.
pub fn layout_region_bytes(text: &str, name: &str) -> Result<Option<u64>, String> {
    for (k, line) in text.lines().enumerate() {
        let code = line.split("/*").next().unwrap_or("");
        let Some((region, rest)) = code.split_once(':') else {
            continue;
        };
        if region.trim() != name {
            continue;
        }
        let length = rest
            .split(',')
            .filter_map(|f| f.split_once('='))
            .find(|(key, _)| key.trim() == "LENGTH")
            .map(|(_, v)| v.trim())
            .ok_or_else(|| format!("line {}: region {name} has no LENGTH", k + 1))?;
        return parse_layout_size(length).map(Some).ok_or_else(|| {
            format!(
                "line {}: field LENGTH of region {name} is not a size",
                k + 1
            )
        });
    }
    Ok(None)
}

pub(crate) fn parse_layout_size(v: &str) -> Option<u64> {
    let (digits, unit) = match v.as_bytes().last()? {
        b'K' | b'k' => (&v[..v.len() - 1], 1024),
        b'M' | b'm' => (&v[..v.len() - 1], 1024 * 1024),
        _ => (v, 1),
    };
    let n = match digits
        .strip_prefix("0x")
        .or_else(|| digits.strip_prefix("0X"))
    {
        Some(hex) => u64::from_str_radix(&hex.replace('_', ""), 16).ok()?,
        None => digits.replace('_', "").parse::<u64>().ok()?,
    };
    n.checked_mul(unit)
}
