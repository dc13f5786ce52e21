//! The firmware's disassembly, from `llvm-objdump -d` (LLVM is the compiler's own
//! backend, so it decodes every instruction rustc emits for the Cortex-M4F).
use crate::cycles::Instr;
use anyhow::{Context, Result, bail};
use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

/// The disassembler executable (Debian: package `llvm`; `.ci/run` installs it).
pub const OBJDUMP: &str = "llvm-objdump";

/// Every instruction of the executable sections, by address.
#[derive(Clone, Debug, Default)]
pub struct Code {
    /// Instructions by address (literal-pool data left out).
    pub instrs: BTreeMap<u32, Instr>,
}

impl Code {
    /// The instruction at `addr`.
    pub fn at(&self, addr: u32) -> Option<&Instr> {
        self.instrs.get(&addr)
    }

    /// Instructions in `[start, end)`.
    pub fn range(&self, start: u32, end: u32) -> impl Iterator<Item = &Instr> {
        self.instrs.range(start..end).map(|(_, i)| i)
    }
}

/// Fails with what to install when `llvm-objdump` is missing.
pub fn require_objdump() -> Result<()> {
    match Command::new(OBJDUMP).arg("--version").output() {
        Ok(o) if o.status.success() => Ok(()),
        _ => bail!(
            "`{OBJDUMP}` was not found: install LLVM (Debian: `apt-get install -y llvm`, or run \
             `bash .ci/run`, which installs it)"
        ),
    }
}

/// Disassembles `elf` (or an object file) with `llvm-objdump -d --mcpu=cortex-m4`.
pub fn disassemble(elf: &Path) -> Result<Code> {
    require_objdump()?;
    let out = Command::new(OBJDUMP)
        .args(["-d", "--mcpu=cortex-m4"])
        .arg(elf)
        .output()
        .with_context(|| format!("running {OBJDUMP}"))?;
    if !out.status.success() {
        bail!(
            "{OBJDUMP} -d {} failed: {}",
            elf.display(),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    parse_objdump(&String::from_utf8_lossy(&out.stdout))
}

/// Parses `llvm-objdump -d` output: lines `  addr: bytes \tmnemonic\toperands @ comment`.
/// Data (`.word`, `.short`, `<unknown>`) is left out.
pub fn parse_objdump(text: &str) -> Result<Code> {
    let mut code = Code::default();
    for (n, line) in text.lines().enumerate() {
        let Some((addr, rest)) = line.split_once(':') else {
            continue;
        };
        let addr = addr.trim();
        if addr.is_empty() || !addr.bytes().all(|b| b.is_ascii_hexdigit()) || line.ends_with(':') {
            continue;
        }
        let Ok(addr) = u32::from_str_radix(addr, 16) else {
            continue;
        };
        let mut fields = rest.split('\t').map(str::trim).filter(|f| !f.is_empty());
        let bytes = fields.next().unwrap_or_default();
        let mnemonic = fields.next().unwrap_or_default();
        if mnemonic.is_empty() || mnemonic.starts_with('.') || mnemonic.starts_with('<') {
            continue;
        }
        let size = bytes.split_whitespace().filter(|b| b.len() == 2).count() as u32;
        if size != 2 && size != 4 {
            bail!(
                "llvm-objdump line {}: cannot read the encoding size: {line:?}",
                n + 1
            );
        }
        let operands = fields.collect::<Vec<_>>().join(" ");
        let operands = operands
            .split('@')
            .next()
            .unwrap_or_default()
            .trim()
            .to_string();
        code.instrs.insert(
            addr,
            Instr {
                addr,
                size,
                mnemonic: mnemonic.to_string(),
                operands,
            },
        );
    }
    if code.instrs.is_empty() {
        bail!("llvm-objdump output holds no instructions");
    }
    Ok(code)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SNIPPET: &str = "
00001904 <_ZN68_$LT$firmware..bench..Dot64$u20$as$u20$firmware..bench..Workload$GT$4tick17hd418c186fd89d8e5E>:
    1904: 80 b5        \tpush\t{r7, lr}
    1908: 9f ed 49 0a  \tvldr\ts0, [pc, #292]          @ 0x1a30 <$d>
    190c: 00 21        \tmovs\tr1, #0
    1910: 01 f0 56 fa  \tbl\t0x18b0 <__pre_init>     @ imm = #5292

00001a30 <$d>:
    1a30:\t00 00 80 33\t.word\t0x33800000
";

    #[test]
    fn parses_instructions_and_skips_data() {
        let code = parse_objdump(SNIPPET).unwrap();
        assert_eq!(code.instrs.len(), 4);
        let v = code.at(0x1908).unwrap();
        assert_eq!(
            (v.size, v.mnemonic.as_str(), v.operands.as_str()),
            (4, "vldr", "s0, [pc, #292]")
        );
        assert_eq!(code.at(0x1904).unwrap().size, 2);
        assert_eq!(code.at(0x1910).unwrap().direct_target(), Some(0x18b0));
        assert!(code.at(0x1a30).is_none());
    }
}
