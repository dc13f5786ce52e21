//! Reading a firmware ELF with the `object` crate: flash and RAM use per section,
//! the biggest symbols, and the function symbols the cycle estimator needs.
use anyhow::{Context, Result, bail};
use object::{Object, ObjectSection, ObjectSymbol, SectionFlags, SectionKind, SymbolKind};
use serde::Serialize;
use std::path::Path;

/// Start of the Cortex-M SRAM region (0x2000_0000..0x4000_0000 in the architecture's
/// memory map): allocated sections placed there occupy RAM.
pub const RAM_START: u64 = 0x2000_0000;
/// End (exclusive) of the Cortex-M SRAM region.
pub const RAM_END: u64 = 0x4000_0000;
/// The section of the code that runs from CCM SRAM (`memory.x`): not counted as RAM.
pub const CCM_CODE_SECTION: &str = ".ccmram_text";
/// The section of the model data placed in CCM SRAM (`memory.x`): not counted as RAM.
pub const CCM_DATA_SECTION: &str = ".ccmram_data";

/// One allocated section and where it lands.
#[derive(Clone, Debug, Serialize)]
pub struct SectionUse {
    /// Section name (`.vector_table`, `.text`, `.rodata`, `.data`, `.bss`, `.uninit`).
    pub name: String,
    /// Run-time address.
    pub addr: u64,
    /// Size in bytes.
    pub size: u64,
    /// Bytes it takes in flash (its contents, or its load image for `.data`).
    pub flash_bytes: u64,
    /// Bytes it takes in RAM at run time.
    pub ram_bytes: u64,
}

/// A symbol and its size.
#[derive(Clone, Debug, Serialize)]
pub struct SymbolSize {
    /// Demangled name without the hash.
    pub name: String,
    /// Size in bytes.
    pub size: u64,
    /// Section it lives in.
    pub section: String,
}

/// Flash and RAM use of one ELF.
#[derive(Clone, Debug, Serialize)]
pub struct SizeReport {
    /// Allocated sections.
    pub sections: Vec<SectionUse>,
    /// Flash bytes: vector table + text + rodata + the load image of data.
    pub flash_bytes: u64,
    /// Static RAM bytes: data + bss + uninit (the stack reserve is added by the budget).
    pub static_ram_bytes: u64,
    /// The biggest symbols, largest first.
    pub biggest_symbols: Vec<SymbolSize>,
}

/// A function's address range (Thumb bit clear).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Function {
    /// Demangled name without the hash.
    pub name: String,
    /// First address.
    pub start: u32,
    /// One past the last byte.
    pub end: u32,
}

/// Demangles a Rust symbol (legacy or v0) without its hash; other names unchanged.
pub fn demangle(name: &str) -> String {
    format!("{:#}", rustc_demangle::demangle(name))
}

fn read(elf: &Path) -> Result<Vec<u8>> {
    std::fs::read(elf).with_context(|| format!("reading {}", elf.display()))
}

/// Flash and RAM use of `elf`, with its `top` biggest symbols.
pub fn size_report(elf: &Path, top: usize) -> Result<SizeReport> {
    let data = read(elf)?;
    let file = object::File::parse(&*data).with_context(|| format!("parsing {}", elf.display()))?;
    let mut sections = Vec::new();
    for s in file.sections() {
        let alloc = match s.flags() {
            SectionFlags::Elf { sh_flags } => sh_flags & u64::from(object::elf::SHF_ALLOC) != 0,
            _ => false,
        };
        if !alloc || s.size() == 0 {
            continue;
        }
        let name = s.name().unwrap_or("?").to_string();
        // `.ccmram_text` and `.ccmram_data` are the board's CCM SRAM (0x1000_0000), not
        // its SRAM: the QEMU image keeps them in the last 128 KiB of its RAM, which the
        // board does not have.
        let in_ram = (RAM_START..RAM_END).contains(&s.address())
            && name != CCM_CODE_SECTION
            && name != CCM_DATA_SECTION;
        let has_bytes = !matches!(
            s.kind(),
            SectionKind::UninitializedData | SectionKind::UninitializedTls
        );
        let flash_bytes = if has_bytes { s.size() } else { 0 };
        let ram_bytes = if in_ram { s.size() } else { 0 };
        sections.push(SectionUse {
            name,
            addr: s.address(),
            size: s.size(),
            flash_bytes,
            ram_bytes,
        });
    }
    if sections.is_empty() {
        bail!("{} has no allocated sections", elf.display());
    }
    let mut symbols: Vec<SymbolSize> = file
        .symbols()
        .filter(|s| s.size() > 0 && matches!(s.kind(), SymbolKind::Text | SymbolKind::Data))
        .map(|s| SymbolSize {
            name: demangle(s.name().unwrap_or("?")),
            size: s.size(),
            section: s
                .section_index()
                .and_then(|i| file.section_by_index(i).ok())
                .and_then(|sec| sec.name().ok().map(str::to_string))
                .unwrap_or_default(),
        })
        .collect();
    symbols.sort_by(|a, b| b.size.cmp(&a.size).then_with(|| a.name.cmp(&b.name)));
    symbols.truncate(top);
    Ok(SizeReport {
        flash_bytes: sections.iter().map(|s| s.flash_bytes).sum(),
        static_ram_bytes: sections.iter().map(|s| s.ram_bytes).sum(),
        sections,
        biggest_symbols: symbols,
    })
}

/// Every function symbol with a size, sorted by address.
pub fn functions(elf: &Path) -> Result<Vec<Function>> {
    let data = read(elf)?;
    let file = object::File::parse(&*data).with_context(|| format!("parsing {}", elf.display()))?;
    let mut fns: Vec<Function> = file
        .symbols()
        .filter(|s| s.kind() == SymbolKind::Text && s.size() > 0)
        .map(|s| {
            let start = (s.address() & !1) as u32;
            Function {
                name: demangle(s.name().unwrap_or("?")),
                start,
                end: start + s.size() as u32,
            }
        })
        .collect();
    fns.sort_by_key(|f| f.start);
    fns.dedup_by_key(|f| f.start);
    Ok(fns)
}

/// The function containing `addr`.
pub fn function_at(fns: &[Function], addr: u32) -> Option<&Function> {
    let i = fns.partition_point(|f| f.start <= addr);
    fns[..i].last().filter(|f| addr < f.end)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demangles_without_hash() {
        assert_eq!(
            demangle(
                "_ZN68_$LT$firmware..bench..Dot64$u20$as$u20$firmware..bench..Workload$GT$4tick17hd418c186fd89d8e5E"
            ),
            "<firmware::bench::Dot64 as firmware::bench::Workload>::tick"
        );
        assert_eq!(demangle("expf"), "expf");
    }

    #[test]
    fn finds_the_containing_function() {
        let f = |n: &str, s, e| Function {
            name: n.into(),
            start: s,
            end: e,
        };
        let fns = vec![f("a", 0x10, 0x20), f("b", 0x20, 0x28), f("c", 0x40, 0x50)];
        assert_eq!(function_at(&fns, 0x10).unwrap().name, "a");
        assert_eq!(function_at(&fns, 0x27).unwrap().name, "b");
        assert!(function_at(&fns, 0x30).is_none());
        assert!(function_at(&fns, 0x8).is_none());
        assert!(function_at(&fns, 0x50).is_none());
    }
}
