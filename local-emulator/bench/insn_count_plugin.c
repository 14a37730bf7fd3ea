/*
 * Guest instruction counter for qemu-user (TCG plugin API version 1: QEMU 7.x, as Debian 12
 * ships), used by instruction-counts.sh for the aarch64 column.
 *
 *   cc -shared -fPIC -O2 -o insn_count_plugin.so insn_count_plugin.c
 *   qemu-aarch64 -L /usr/aarch64-linux-gnu \
 *       -plugin ./insn_count_plugin.so,out=count.txt[,per_insn=on] ./program args
 *
 * At exit, writes N (executed guest instructions of the whole process) to FILE when out=FILE
 * is given, and "insns N" to QEMU's log (shown with -d plugin). Default: one inline add of the block's instruction count
 * per executed translation block (fast; a block left in the middle by a fault would count in
 * full, which user-mode programs practically never do); per_insn=on adds 1 per executed
 * instruction instead (exact, slower). The counter is not atomic: count single-threaded
 * guests only.
 *
 * No QEMU header is needed: the few API declarations below are written against the plugin API
 * of QEMU 7.2 (qemu_plugin_version 1; the inline ops that take a plain pointer were replaced
 * in QEMU 9, so a newer QEMU refuses or mis-runs this plugin).
 */
#include <inttypes.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define EXPORT __attribute__((visibility("default")))

/* ---- QEMU 7.2 plugin API (subset) ---- */
typedef uint64_t qemu_plugin_id_t;
typedef struct qemu_info_t {
    const char *target_name;
    struct {
        int min;
        int cur;
    } version;
    bool system_emulation;
    union {
        struct {
            int smp_vcpus;
            int max_vcpus;
        } system;
    };
} qemu_info_t;
struct qemu_plugin_tb;
struct qemu_plugin_insn;
enum qemu_plugin_op { QEMU_PLUGIN_INLINE_ADD_U64 };
typedef void (*qemu_plugin_udata_cb_t)(qemu_plugin_id_t id, void *userdata);
typedef void (*qemu_plugin_vcpu_tb_trans_cb_t)(qemu_plugin_id_t id, struct qemu_plugin_tb *tb);
void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t id, qemu_plugin_vcpu_tb_trans_cb_t cb);
void qemu_plugin_register_vcpu_tb_exec_inline(struct qemu_plugin_tb *tb, enum qemu_plugin_op op,
                                              void *ptr, uint64_t imm);
void qemu_plugin_register_vcpu_insn_exec_inline(struct qemu_plugin_insn *insn,
                                                enum qemu_plugin_op op, void *ptr, uint64_t imm);
size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *tb, size_t idx);
void qemu_plugin_register_atexit_cb(qemu_plugin_id_t id, qemu_plugin_udata_cb_t cb,
                                    void *userdata);
void qemu_plugin_outs(const char *string);
/* ---- end of API subset ---- */

EXPORT int qemu_plugin_version = 1;

static uint64_t insn_count;
static bool per_insn;
static char *out_path;

static void on_translate(qemu_plugin_id_t id, struct qemu_plugin_tb *tb)
{
    (void)id;
    size_t n = qemu_plugin_tb_n_insns(tb);
    if (per_insn) {
        for (size_t i = 0; i < n; i++) {
            qemu_plugin_register_vcpu_insn_exec_inline(qemu_plugin_tb_get_insn(tb, i),
                                                       QEMU_PLUGIN_INLINE_ADD_U64, &insn_count, 1);
        }
    } else {
        qemu_plugin_register_vcpu_tb_exec_inline(tb, QEMU_PLUGIN_INLINE_ADD_U64, &insn_count, n);
    }
}

static void report(qemu_plugin_id_t id, void *userdata)
{
    (void)id;
    (void)userdata;
    char line[64];
    snprintf(line, sizeof line, "insns %" PRIu64 "\n", insn_count);
    qemu_plugin_outs(line);
    if (out_path) {
        FILE *f = fopen(out_path, "w");
        if (!f || fprintf(f, "%" PRIu64 "\n", insn_count) < 0 || fclose(f) != 0) {
            fprintf(stderr, "insn_count_plugin: cannot write %s\n", out_path);
        }
    }
}

EXPORT int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info, int argc, char **argv)
{
    if (info->system_emulation) {
        fprintf(stderr, "insn_count_plugin: user-mode emulation only\n");
        return 1;
    }
    for (int i = 0; i < argc; i++) {
        if (strncmp(argv[i], "out=", 4) == 0) {
            out_path = strdup(argv[i] + 4);
        } else if (strcmp(argv[i], "per_insn=on") == 0 || strcmp(argv[i], "per_insn=true") == 0) {
            per_insn = true;
        } else if (strcmp(argv[i], "per_insn=off") == 0 || strcmp(argv[i], "per_insn=false") == 0) {
            per_insn = false;
        } else {
            fprintf(stderr, "insn_count_plugin: unknown argument %s (out=FILE, per_insn=on|off)\n",
                    argv[i]);
            return 1;
        }
    }
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_translate);
    qemu_plugin_register_atexit_cb(id, report, NULL);
    return 0;
}
