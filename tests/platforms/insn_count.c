/* A QEMU TCG plugin that counts the guest instructions a program executes, for
   count_instructions.sh: each translated block adds its instruction count to a counter every
   time it runs (an inline add, no callback), and the total is printed at exit:
     qemu-aarch64 -plugin ./insn_count.so -d plugin PROGRAM ARGS...   ->  "instructions N"
   Plugin API version 1 (QEMU 7.2, Debian 12). Debian ships no qemu-plugin.h, so the five calls
   it uses are declared here, as that version defines them. */
#include <inttypes.h>
#include <stddef.h>
#include <stdio.h>

typedef uint64_t kdrt_plugin_id;
struct qemu_plugin_tb;
enum { KDRT_PLUGIN_INLINE_ADD_U64 = 0 }; /* QEMU_PLUGIN_INLINE_ADD_U64 */

extern void qemu_plugin_register_vcpu_tb_trans_cb(kdrt_plugin_id id,
                                                  void (*cb)(kdrt_plugin_id, struct qemu_plugin_tb *));
extern void qemu_plugin_register_vcpu_tb_exec_inline(struct qemu_plugin_tb *tb, int op, void *ptr, uint64_t imm);
extern size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
extern void qemu_plugin_register_atexit_cb(kdrt_plugin_id id, void (*cb)(kdrt_plugin_id, void *), void *userdata);
extern void qemu_plugin_outs(const char *string);

__attribute__((visibility("default"))) int qemu_plugin_version = 1;

/* One counter: the programs counted run one thread. */
static uint64_t executed;

static void on_translate(kdrt_plugin_id id, struct qemu_plugin_tb *tb)
{
    (void)id;
    qemu_plugin_register_vcpu_tb_exec_inline(tb, KDRT_PLUGIN_INLINE_ADD_U64, &executed, qemu_plugin_tb_n_insns(tb));
}

static void on_exit_report(kdrt_plugin_id id, void *user)
{
    char line[64];
    (void)id, (void)user;
    snprintf(line, sizeof line, "instructions %" PRIu64 "\n", executed);
    qemu_plugin_outs(line);
}

__attribute__((visibility("default"))) int qemu_plugin_install(kdrt_plugin_id id, const void *info, int argc,
                                                               char **argv)
{
    (void)info, (void)argc, (void)argv;
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_translate);
    qemu_plugin_register_atexit_cb(id, on_exit_report, NULL);
    return 0;
}
