/* QEMU TCG plugin: per-address guest instruction histogram, counted only
 * between a start and an end marker address (bench-m4's profile_start /
 * profile_end, called around each typical tick), written to `out` at exit
 * as "windows N" then "0xADDR COUNT" lines.  Declares only the subset of
 * qemu-plugin.h it uses (plugin API version 1, QEMU 7.2; set
 * -DPLUGIN_API=N for newer QEMUs).  Used by bench-m4/profile.sh.
 * Build: gcc -O2 -shared -fPIC -o libpchist.so qemu-pc-histogram.c
 * Run:   -plugin ./libpchist.so,start=0xADDR,end=0xADDR,out=FILE -d plugin
 * GPL-2.0-or-later, like the QEMU plugin API it uses. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <stddef.h>
typedef uint64_t qemu_plugin_id_t;
struct qemu_plugin_tb; struct qemu_plugin_insn; typedef struct qemu_info_t qemu_info_t;
enum qemu_plugin_cb_flags { QEMU_PLUGIN_CB_NO_REGS, QEMU_PLUGIN_CB_R_REGS, QEMU_PLUGIN_CB_RW_REGS };
typedef void (*qemu_plugin_vcpu_tb_trans_cb_t)(qemu_plugin_id_t, struct qemu_plugin_tb *);
typedef void (*qemu_plugin_vcpu_udata_cb_t)(unsigned int, void *);
typedef void (*qemu_plugin_udata_cb_t)(qemu_plugin_id_t, void *);
extern void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t, qemu_plugin_vcpu_tb_trans_cb_t);
extern void qemu_plugin_register_vcpu_insn_exec_cb(struct qemu_plugin_insn *, qemu_plugin_vcpu_udata_cb_t, enum qemu_plugin_cb_flags, void *);
extern size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *);
extern struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *, size_t);
extern uint64_t qemu_plugin_insn_vaddr(const struct qemu_plugin_insn *);
extern void qemu_plugin_register_atexit_cb(qemu_plugin_id_t, qemu_plugin_udata_cb_t, void *);
#ifndef PLUGIN_API
#define PLUGIN_API 1
#endif
__attribute__((visibility("default"))) int qemu_plugin_version = PLUGIN_API;
/* Code at 0x0-0x3fffff (mps2-an386 code RAM): one counter per halfword. */
#define N (1u<<21)
static uint64_t *cnt; static int active; static uint64_t start_pc, end_pc, windows; static const char *out = "prof.txt";
static void on_insn(unsigned int v, void *ud) { (void)v; if (active) cnt[(uintptr_t)ud]++; }
static void on_start(unsigned int v, void *ud) { (void)v; (void)ud; active = 1; windows++; }
static void on_end(unsigned int v, void *ud) { (void)v; (void)ud; active = 0; }
static void tb_trans(qemu_plugin_id_t id, struct qemu_plugin_tb *tb) {
  (void)id; size_t n = qemu_plugin_tb_n_insns(tb);
  for (size_t i = 0; i < n; i++) {
    struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
    uint64_t pc = qemu_plugin_insn_vaddr(insn) & ~1ull;
    qemu_plugin_vcpu_udata_cb_t cb = pc == start_pc ? on_start : pc == end_pc ? on_end : on_insn;
    qemu_plugin_register_vcpu_insn_exec_cb(insn, cb, QEMU_PLUGIN_CB_NO_REGS, (void *)(uintptr_t)((pc >> 1) & (N - 1)));
  }
}
static void at_exit(qemu_plugin_id_t id, void *ud) {
  (void)id; (void)ud; FILE *f = fopen(out, "w");
  fprintf(f, "windows %llu\n", (unsigned long long)windows);
  for (uint64_t i = 0; i < N; i++) if (cnt[i]) fprintf(f, "0x%llx %llu\n", (unsigned long long)(i << 1), (unsigned long long)cnt[i]);
  fclose(f);
}
__attribute__((visibility("default")))
int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info, int argc, char **argv) {
  (void)info; cnt = calloc(N, 8);
  for (int i = 0; i < argc; i++) {
    if (!strncmp(argv[i], "start=", 6)) start_pc = strtoull(argv[i] + 6, NULL, 0) & ~1ull;
    else if (!strncmp(argv[i], "end=", 4)) end_pc = strtoull(argv[i] + 4, NULL, 0) & ~1ull;
    else if (!strncmp(argv[i], "out=", 4)) out = argv[i] + 4;
  }
  qemu_plugin_register_vcpu_tb_trans_cb(id, tb_trans);
  qemu_plugin_register_atexit_cb(id, at_exit, NULL);
  return 0;
}
