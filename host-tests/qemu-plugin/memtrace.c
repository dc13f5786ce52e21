/* QEMU TCG plugin (plugin API version 1, QEMU 7.2): records every executed
 * instruction's address and every data access's address, size and direction for
 * the instructions inside the address ranges of a ranges file, as little-endian
 * pairs of 32-bit words:
 *   instruction: (0, pc)
 *   load:        (1 | size_shift << 8, address)
 *   store:       (2 | size_shift << 8, address)
 * Arguments: out=PATH (the record file), ranges=PATH (lines "START END", hex,
 * END exclusive). host-tests (src/trace.rs) builds it with the host C compiler
 * and reads the records; the prototypes below are the ones of QEMU's
 * qemu-plugin.h that this plugin uses (Debian ships no header). */
#include <inttypes.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef uint64_t qemu_plugin_id_t;
typedef uint32_t qemu_plugin_meminfo_t;
struct qemu_plugin_tb;
struct qemu_plugin_insn;
typedef struct qemu_info_t qemu_info_t;
enum qemu_plugin_cb_flags { QEMU_PLUGIN_CB_NO_REGS, QEMU_PLUGIN_CB_R_REGS, QEMU_PLUGIN_CB_RW_REGS };
enum qemu_plugin_mem_rw { QEMU_PLUGIN_MEM_R = 1, QEMU_PLUGIN_MEM_W, QEMU_PLUGIN_MEM_RW };
typedef void (*qemu_plugin_vcpu_tb_trans_cb_t)(qemu_plugin_id_t id, struct qemu_plugin_tb *tb);
typedef void (*qemu_plugin_vcpu_udata_cb_t)(unsigned int vcpu_index, void *userdata);
typedef void (*qemu_plugin_vcpu_mem_cb_t)(unsigned int vcpu_index, qemu_plugin_meminfo_t info,
                                          uint64_t vaddr, void *userdata);
void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t id, qemu_plugin_vcpu_tb_trans_cb_t cb);
size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *tb, size_t idx);
uint64_t qemu_plugin_insn_vaddr(const struct qemu_plugin_insn *insn);
void qemu_plugin_register_vcpu_insn_exec_cb(struct qemu_plugin_insn *insn,
                                            qemu_plugin_vcpu_udata_cb_t cb,
                                            enum qemu_plugin_cb_flags flags, void *userdata);
void qemu_plugin_register_vcpu_mem_cb(struct qemu_plugin_insn *insn, qemu_plugin_vcpu_mem_cb_t cb,
                                      enum qemu_plugin_cb_flags flags, enum qemu_plugin_mem_rw rw,
                                      void *userdata);
unsigned int qemu_plugin_mem_size_shift(qemu_plugin_meminfo_t info);
bool qemu_plugin_mem_is_store(qemu_plugin_meminfo_t info);

__attribute__((visibility("default"))) int qemu_plugin_version = 1;

#define MAX_RANGES 4096
static uint32_t range_lo[MAX_RANGES], range_hi[MAX_RANGES];
static size_t n_ranges;
static FILE *out;

static bool traced(uint64_t pc)
{
    for (size_t i = 0; i < n_ranges; i++) {
        if (pc >= range_lo[i] && pc < range_hi[i]) {
            return true;
        }
    }
    return false;
}

static void put(uint32_t kind, uint32_t addr)
{
    uint32_t rec[2] = {kind, addr};
    fwrite(rec, sizeof rec, 1, out);
}

static void on_insn(unsigned int vcpu, void *pc)
{
    (void)vcpu;
    put(0, (uint32_t)(uintptr_t)pc);
}

static void on_mem(unsigned int vcpu, qemu_plugin_meminfo_t info, uint64_t vaddr, void *udata)
{
    (void)vcpu;
    (void)udata;
    uint32_t kind = (qemu_plugin_mem_is_store(info) ? 2u : 1u) | qemu_plugin_mem_size_shift(info) << 8;
    put(kind, (uint32_t)vaddr);
}

static void on_translate(qemu_plugin_id_t id, struct qemu_plugin_tb *tb)
{
    (void)id;
    size_t n = qemu_plugin_tb_n_insns(tb);
    for (size_t i = 0; i < n; i++) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        uint64_t pc = qemu_plugin_insn_vaddr(insn);
        if (!traced(pc)) {
            continue;
        }
        qemu_plugin_register_vcpu_insn_exec_cb(insn, on_insn, QEMU_PLUGIN_CB_NO_REGS,
                                               (void *)(uintptr_t)pc);
        qemu_plugin_register_vcpu_mem_cb(insn, on_mem, QEMU_PLUGIN_CB_NO_REGS, QEMU_PLUGIN_MEM_RW,
                                         NULL);
    }
}

static void finish(void)
{
    if (out != NULL) {
        fclose(out);
        out = NULL;
    }
}

__attribute__((visibility("default"))) int qemu_plugin_install(qemu_plugin_id_t id,
                                                               const qemu_info_t *info, int argc,
                                                               char **argv)
{
    (void)info;
    const char *out_path = NULL;
    const char *ranges_path = NULL;
    for (int i = 0; i < argc; i++) {
        if (strncmp(argv[i], "out=", 4) == 0) {
            out_path = argv[i] + 4;
        } else if (strncmp(argv[i], "ranges=", 7) == 0) {
            ranges_path = argv[i] + 7;
        } else {
            fprintf(stderr, "memtrace: unknown argument %s\n", argv[i]);
            return -1;
        }
    }
    if (out_path == NULL || ranges_path == NULL) {
        fprintf(stderr, "memtrace: needs out=PATH and ranges=PATH\n");
        return -1;
    }
    FILE *r = fopen(ranges_path, "r");
    if (r == NULL) {
        fprintf(stderr, "memtrace: cannot open %s\n", ranges_path);
        return -1;
    }
    unsigned lo, hi;
    while (n_ranges < MAX_RANGES && fscanf(r, "%x %x", &lo, &hi) == 2) {
        range_lo[n_ranges] = lo;
        range_hi[n_ranges] = hi;
        n_ranges++;
    }
    fclose(r);
    out = fopen(out_path, "wb");
    if (out == NULL) {
        fprintf(stderr, "memtrace: cannot create %s\n", out_path);
        return -1;
    }
    setvbuf(out, NULL, _IOFBF, 1 << 20);
    atexit(finish);
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_translate);
    return 0;
}
