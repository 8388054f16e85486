/*
 * QEMU TCG plugin (plugin API version 1): exact per-step instruction counts of a firmware of the HIL
 * target core. Every executed instruction adds 1 to a counter (inline op); the first instructions of
 * hil_core_step_begin and hil_core_step_end (addresses from the ELF, plugin arguments begin= and end=)
 * snapshot it. Each begin..end difference -- the instructions from the begin marker up to the end
 * marker, hil_app_step and the markers' call overhead -- is appended to the file out= as a little-endian
 * u32. The firmware calls the pair once at boot with nothing between: the first record is the markers'
 * own cost, which the host subtracts.
 *
 * The counter itself lives in the first 8 bytes of the file live= (mapped shared, native byte order): the host
 * reads the guest's progress there while it waits for a Command (src/pmsm_hil/hil/runner/c/loop_stall.h: a guest that executed
 * its time and did not answer is the firmware's fault, a QEMU the host did not schedule is not). Without live=
 * it is private.
 *
 * Debian ships no qemu-plugin.h: the few API declarations below are written from QEMU's documented
 * plugin API (docs/devel/tcg-plugins), not copied from its header.
 */
#include <fcntl.h>
#include <sys/mman.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef uint64_t qemu_plugin_id_t;
typedef struct qemu_info_t qemu_info_t; /* not read */
struct qemu_plugin_tb;
struct qemu_plugin_insn;
enum qemu_plugin_cb_flags { QEMU_PLUGIN_CB_NO_REGS, QEMU_PLUGIN_CB_R_REGS, QEMU_PLUGIN_CB_RW_REGS };
enum qemu_plugin_op { QEMU_PLUGIN_INLINE_ADD_U64 };
typedef void (*qemu_plugin_vcpu_udata_cb_t)(unsigned int vcpu_index, void *userdata);
typedef void (*qemu_plugin_vcpu_tb_trans_cb_t)(qemu_plugin_id_t id, struct qemu_plugin_tb *tb);
typedef void (*qemu_plugin_udata_cb_t)(qemu_plugin_id_t id, void *userdata);

void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t id, qemu_plugin_vcpu_tb_trans_cb_t cb);
size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *tb, size_t idx);
uint64_t qemu_plugin_insn_vaddr(const struct qemu_plugin_insn *insn);
void qemu_plugin_register_vcpu_insn_exec_inline(struct qemu_plugin_insn *insn, enum qemu_plugin_op op, void *ptr,
                                                uint64_t imm);
void qemu_plugin_register_vcpu_insn_exec_cb(struct qemu_plugin_insn *insn, qemu_plugin_vcpu_udata_cb_t cb,
                                            enum qemu_plugin_cb_flags flags, void *userdata);
void qemu_plugin_register_atexit_cb(qemu_plugin_id_t id, qemu_plugin_udata_cb_t cb, void *userdata);

__attribute__((visibility("default"))) int qemu_plugin_version = 1;

static uint64_t own_counter;
/* instructions executed so far: own_counter, or the first word of the shared file live= */
static uint64_t *executed = &own_counter;
static uint64_t begin_at;
static int began;
static uint64_t addr_begin = UINT64_MAX;
static uint64_t addr_end = UINT64_MAX;
static int out_fd = -1;

static void on_marker(unsigned int vcpu_index, void *userdata)
{
    (void)vcpu_index;
    if (userdata == NULL) {
        begin_at = *executed;
        began = 1;
    } else if (began) {
        const uint64_t n = *executed - begin_at;
        uint8_t le[4];
        le[0] = (uint8_t)(n & 0xFFu);
        le[1] = (uint8_t)((n >> 8) & 0xFFu);
        le[2] = (uint8_t)((n >> 16) & 0xFFu);
        le[3] = (uint8_t)((n >> 24) & 0xFFu);
        began = 0;
        if (out_fd >= 0 && write(out_fd, le, sizeof le) != (ssize_t)sizeof le) {
            close(out_fd);
            out_fd = -1;
        }
    }
}

static void on_tb(qemu_plugin_id_t id, struct qemu_plugin_tb *tb)
{
    const size_t n = qemu_plugin_tb_n_insns(tb);
    size_t i;
    (void)id;
    for (i = 0; i < n; ++i) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        const uint64_t pc = qemu_plugin_insn_vaddr(insn);
        /* the callback before the count: a snapshot excludes the marker instruction itself */
        if (pc == addr_begin) {
            qemu_plugin_register_vcpu_insn_exec_cb(insn, on_marker, QEMU_PLUGIN_CB_NO_REGS, NULL);
        } else if (pc == addr_end) {
            qemu_plugin_register_vcpu_insn_exec_cb(insn, on_marker, QEMU_PLUGIN_CB_NO_REGS, (void *)1);
        }
        qemu_plugin_register_vcpu_insn_exec_inline(insn, QEMU_PLUGIN_INLINE_ADD_U64, executed, 1);
    }
}

static void on_exit_cb(qemu_plugin_id_t id, void *userdata)
{
    (void)id;
    (void)userdata;
    if (out_fd >= 0) {
        close(out_fd);
        out_fd = -1;
    }
}

/* The counter into the first 8 bytes of `path` (created if missing, at least one page long), mapped shared: 0 or -1. */
static int map_live(const char *path)
{
    const long page = sysconf(_SC_PAGESIZE);
    const size_t size = page > 0 ? (size_t)page : 4096u;
    void *map;
    const int fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0600);
    if (fd < 0) {
        return -1;
    }
    if (ftruncate(fd, (off_t)size) != 0) {
        close(fd);
        return -1;
    }
    map = mmap(NULL, size, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    close(fd);
    if (map == MAP_FAILED) {
        return -1;
    }
    executed = (uint64_t *)map;
    *executed = 0;
    return 0;
}

__attribute__((visibility("default"))) int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info,
                                                               int argc, char **argv)
{
    int i;
    (void)info;
    for (i = 0; i < argc; ++i) {
        if (strncmp(argv[i], "begin=", 6) == 0) {
            addr_begin = strtoull(argv[i] + 6, NULL, 0);
        } else if (strncmp(argv[i], "end=", 4) == 0) {
            addr_end = strtoull(argv[i] + 4, NULL, 0);
        } else if (strncmp(argv[i], "out=", 4) == 0) {
            out_fd = open(argv[i] + 4, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
        } else if (strncmp(argv[i], "live=", 5) == 0) {
            if (map_live(argv[i] + 5) != 0) {
                return -1;
            }
        } else {
            return -1;
        }
    }
    if (addr_begin == UINT64_MAX || addr_end == UINT64_MAX || out_fd < 0) {
        return -1;
    }
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_tb);
    qemu_plugin_register_atexit_cb(id, on_exit_cb, NULL);
    return 0;
}
