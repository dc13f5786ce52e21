#!/usr/bin/env python3
"""Static size of an interrupt handler's path in a Cortex-M ELF.

Usage: isr_path.py ELF [SYMBOL]   (SYMBOL defaults to ADC1_2)

Disassembles the ELF with llvm-objdump, takes the function symbols from llvm-nm,
and walks every function reachable from SYMBOL through direct calls and branches
(bl, b, b.w, cbz/cbnz, b<cond>) that land at another function's start; the linker's
long-branch thunks (`__Thumbv7ABSLongThunk_*`, movw/movt/bx r12) are followed to
their target. Prints one row per reachable function: where it runs (CCM SRAM at
0x1000_0000, zero wait states, or flash at 0x0800_0000, 4 wait states at 170 MHz),
its bytes, instructions, calls (bl/blx), conditional branches, and whether it
is a panic path (a name with `panic`); then the totals. An indirect branch (blx/bx
through a register other than lr, or a load into pc outside a thunk) is reported,
since the walk cannot follow it. Static counts, not executed ones.
"""

import re
import subprocess
import sys

INSN = re.compile(r"^\s*([0-9a-f]+):\s+(\S+)\s*(.*)$")
TARGET = re.compile(r"0x([0-9a-f]+)")
COND = re.compile(r"^b(eq|ne|cs|hs|cc|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le)(\.w|\.n)?$")


def functions(elf):
    """{start: (size, name)} of the function symbols (llvm-nm -S, type t/T)."""
    out = subprocess.run(
        ["llvm-nm", "-S", "-C", "--defined-only", elf],
        check=True, capture_output=True, text=True,
    ).stdout
    funcs = {}
    for line in out.splitlines():
        parts = line.split(None, 3)
        if len(parts) == 4 and parts[2] in ("t", "T"):
            start, size = int(parts[0], 16) & ~1, int(parts[1], 16)
            if size > 0:
                funcs[start] = (size, parts[3])
    return funcs


def instructions(elf):
    """[(address, mnemonic, operands)] of every disassembled instruction."""
    out = subprocess.run(
        ["llvm-objdump", "-d", "--no-show-raw-insn", elf],
        check=True, capture_output=True, text=True,
    ).stdout
    rows = []
    for line in out.splitlines():
        m = INSN.match(line)
        if m:
            rows.append((int(m.group(1), 16), m.group(2), m.group(3)))
    return rows


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    elf = sys.argv[1]
    root_name = sys.argv[2] if len(sys.argv) > 2 else "ADC1_2"
    funcs = functions(elf)
    insns = instructions(elf)
    body = {start: [] for start in funcs}
    starts = sorted(funcs)
    for addr, mnem, ops in insns:
        for start in starts:
            if start <= addr < start + funcs[start][0]:
                body[start].append((addr, mnem, ops))
                break
    roots = [s for s, (_, n) in funcs.items() if n == root_name]
    if not roots:
        sys.exit(f"{elf}: no function symbol {root_name}")
    seen, todo, rows = set(), [roots[0]], []
    indirect = []
    while todo:
        f = todo.pop()
        if f in seen:
            continue
        seen.add(f)
        size, name = funcs[f]
        code = [i for i in body[f] if not i[1].startswith(".")]
        thunk = name.startswith("__Thumbv7ABSLongThunk_")
        calls = cond = 0
        targets = []
        if thunk:
            lo = hi = None
            for _, mnem, ops in code:
                imm = re.search(r"#(\d+)", ops)
                if mnem == "movw" and imm:
                    lo = int(imm.group(1))
                if mnem == "movt" and imm:
                    hi = int(imm.group(1))
            if lo is not None and hi is not None:
                targets.append(((hi << 16) | lo) & ~1)
        for addr, mnem, ops in code:
            base = mnem.split(".")[0]
            if base in ("bl", "blx"):
                calls += 1
            if COND.match(mnem) or base in ("cbz", "cbnz"):
                cond += 1
            if base in ("bl", "b", "cbz", "cbnz") or COND.match(mnem):
                t = TARGET.search(ops)
                if t:
                    dest = int(t.group(1), 16)
                    if dest in funcs and dest != f:
                        targets.append(dest)
            through_register = base in ("blx", "bx") and "lr" not in ops and not thunk
            load_into_pc = base in ("ldr", "mov") and ops.replace(" ", "").startswith("pc,")
            if through_register or load_into_pc:
                indirect.append(f"{addr:08x} {mnem} {ops} in {name}")
        todo.extend(t for t in targets if t in funcs)
        region = "CCM SRAM" if 0x1000_0000 <= f < 0x1001_0000 else (
            "flash" if 0x0800_0000 <= f < 0x0810_0000 else "other")
        rows.append((region, size, len(code), calls, cond, "panic" in name, thunk, name))
    rows.sort(key=lambda r: (r[6], r[0] != "CCM SRAM", -r[1]))
    print(f"{elf}: functions reachable from {root_name}")
    print("| where | bytes | instructions | calls | cond. branches | function |")
    print("|---|---:|---:|---:|---:|---|")
    for region, size, n, calls, cond, panic, thunk, name in rows:
        tag = " (panic)" if panic else (" (thunk)" if thunk else "")
        print(f"| {region} | {size} | {n} | {calls} | {cond} | {name[:110]}{tag} |")
    real = [r for r in rows if not r[6]]
    for region in ("CCM SRAM", "flash"):
        part = [r for r in real if r[0] == region]
        print(f"total {region}: {len(part)} functions, {sum(r[1] for r in part)} bytes, "
              f"{sum(r[2] for r in part)} instructions, {sum(r[3] for r in part)} calls, "
              f"{sum(r[4] for r in part)} conditional branches")
    print(f"thunks (CCM SRAM -> flash): {sum(1 for r in rows if r[6])}")
    print(f"panic functions reachable: {sum(1 for r in rows if r[5])}")
    print(f"indirect branches on the path: {len(indirect)}")
    for line in indirect:
        print(f"  {line}")


if __name__ == "__main__":
    main()
