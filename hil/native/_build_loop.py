"""cffi (API mode) builder of the native period loop: extension `pmsm_hil.hil._loop_native`.

Two sets of flags: the firmware side (reference firmware, HIL target core, generated codec) is compiled with
the firmware's strict flags (`-fsingle-precision-constant`, as every other build of it) into objects linked
in; the loop and the plant (double precision) with the plant's flags plus `-Werror`, no FMA contraction and
no sin/cos fusion, so every value equals the Python loop's bit for bit.
"""

from __future__ import annotations

import importlib.util
import tempfile
from pathlib import Path
from typing import Any

from cffi import FFI

_HERE = Path(__file__).resolve().parent
_ROOT = _HERE.parent.parent
_FW = _ROOT / "firmware_stub"
_FW_INCLUDES = [_FW / "include", _FW / "generated", _FW / "target"]

#: the firmware's strict flags (firmware_stub/target/hil_target.cmake HIL_STRICT_FLAGS)
FIRMWARE_FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion", "-fsingle-precision-constant",
                  "-O2", "-fPIC", "-DHIL_APP_REFERENCE_PROFILED"]
LOOP_FLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion", "-ffp-contract=off",
              "-fno-builtin-sin", "-fno-builtin-cos", "-pthread"]
LOOP_SOURCES = ("loop.c", "loop_frames.c", "loop_rt.c", "nl_link.c", "loop_udp.c", "loop_serial.c", "loop_socketcan.c",
                "target_serve.c", "link_floor.c", "loop_board.c", "loop_fmu.c", "pwm_duty.c")


def _load_extractor() -> Any:
    """hil/cdef_extract.py by path (this script runs at build time, before the package is importable)."""
    spec = importlib.util.spec_from_file_location("_cdef_extract", _HERE.parent / "cdef_extract.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_X = _load_extractor()
#: loop.h and machine_kernel.h as cffi reads them: their integer constants, the finding, configuration and result
#: structs and the handle's functions - taken from the headers, never restated
LOOP_H_CDEF = (_X.cffi_constants(_HERE / "loop_fmu.h", "NL_FMU_")
               + _X.declarations(_HERE / "loop_fmu.h", ["nl_fmu_t", "nl_fmu_open", "nl_fmu_enter_init", "nl_fmu_set",
                                                        "nl_fmu_exit_init", "nl_fmu_period", "nl_fmu_close"])
               + _X.cffi_constants(_HERE / "loop.h", "NL_")
               + _X.cffi_constants(_HERE / "kernels" / "machine_kernel.h", "MK_")
               + "typedef struct mk_kernel mk_kernel_t;\n"
               + _X.declarations(_HERE / "loop.h", ["nl_finding_t", "nl_sil_debug_t", "nl_config_t"]) + """
typedef struct {
    double *trace;
    int64_t trace_rows_cap;
    int32_t n_periods, n_frames, n_findings;
    int64_t n_trace_rows;
    ...;
} nl_slot_t;
""" + _X.declarations(_HERE / "loop.h", ["nl_result_t", "nl_handle_t", "nl_handle_size", "nl_init", "nl_destroy",
                                             "nl_config", "nl_slot", "nl_result", "nl_run", "nl_wait_full",
                                             "nl_release", "nl_stop"]))

CDEF = LOOP_H_CDEF + _X.declarations(_HERE / "pwm_duty.h", ["pwm_duty_sequence"]) + """
size_t nl_sizeof_period(void);
size_t nl_sizeof_frame(void);
void *nl_slot_periods(nl_handle_t *h, int32_t i);
void *nl_slot_frames(nl_handle_t *h, int32_t i);
int64_t *nl_slot_lateness(nl_handle_t *h, int32_t i);
nl_finding_t *nl_slot_findings(nl_handle_t *h, int32_t i);
double *nl_slot_noise(nl_handle_t *h, int32_t i);

typedef struct {
    uint32_t id;
    uint8_t len;
    uint8_t fd;
    uint8_t data[64];
} hil_core_frame_t;
int nl_encode_meas(const nl_config_t *c, uint16_t seq, const double *currents, double theta_e, double omega_m,
                   hil_core_frame_t *out, int *n, int32_t *bad_field, double *bad_value);
void hil_core_init(void);

typedef struct nl_link {
    ...;
} nl_link_t;
typedef struct {
    int64_t frames_tx, frames_rx, crc_errors, framing_errors, dropped, duplicate, out_of_order, send_errors,
        ignored, foreign_dropped, session_dropped, auth_failed, auth_replayed;
    int64_t blocked;
} nl_link_stats_t;
typedef struct {
    int32_t on;
    uint64_t tx_fresh;
    uint64_t rx_fresh;
    uint8_t tx_dir;
    uint8_t rx_dir;
    uint8_t ctx_n;
    uint8_t ctx[8];
    ...;
} hil_auth_t;
int hil_auth_init(hil_auth_t *a, const uint8_t *key, size_t key_n, int target_role);
void hil_auth_set_context(hil_auth_t *a, const uint8_t *ctx, size_t n);
void hil_auth_seal(hil_auth_t *a, uint8_t *body, size_t n);
int hil_auth_open(hil_auth_t *a, const uint8_t *body, size_t n);
void hil_hmac_sha256(const uint8_t *key, size_t key_n, const uint8_t *data, size_t n, uint8_t out[32]);
typedef struct {
    int64_t spin_ns;
    int64_t window_wall_ns, window_cpu_ns, window_blocked_ns;
    int32_t window_n, window_spun_out, block_left, contended, spinning, doublings, rx_backed_off, check_n;
    int64_t rx_start_ns, rx_last_ns, window_wait_ns, spin_wait_ns, check_wait_ns, backoffs, early_ends;
} nl_spin_t;
#define NL_SPIN_CHECK ...
#define NL_SPIN_WINDOW ...
#define NL_SPIN_BACKOFF ...
#define NL_SPIN_BACKOFF_DOUBLINGS ...
#define NL_SPIN_NEAR_MISS_NS ...
typedef struct {
    int64_t reads, gaps, gaps_10us, max_gap_ns, lost_ns;
    int64_t hist[1024];  /* NL_LATE_BINS: cffi checks the layout against loop_rt.h when it compiles */
} nl_gap_probe_t;
int32_t nl_gap_probe(int64_t duration_ns, int64_t gap_ns, int32_t cpu, int32_t rt_priority, nl_gap_probe_t *out);
typedef struct {
    int64_t round_trips, mean_ns, max_ns;
} nl_udp_floor_t;
int32_t nl_udp_floor(int64_t n, int64_t spin_ns, nl_udp_floor_t *out);
int nl_wait_readable(int32_t fd, int64_t deadline_ns, nl_spin_t *sp, int64_t *spin_end, nl_link_stats_t *st);
typedef struct {
    int32_t fd;
    uint32_t session;
    uint32_t peer_addr;
    uint16_t peer_port;
    uint8_t tx_seq;
    int32_t target_role;
    int32_t rx_last;
    nl_spin_t spin;
    nl_link_stats_t stats;
    uint32_t nonce;
    hil_auth_t auth;
} nl_udp_t;
void nl_udp_link(nl_link_t *l, nl_udp_t *u);
typedef struct {
    uint8_t tx_seq;
    ...;
} hil_serial_t;
typedef struct {
    int32_t fd;
    int32_t fd_frames;
    hil_serial_t framer;
    int32_t rx_last;
    nl_spin_t spin;
    int64_t write_timeout_ns;
    nl_link_stats_t stats;
    uint8_t pkt[...];
    int32_t pkt_n;
    int32_t discarding;
    uint8_t rx[...];
    int32_t rx_at, rx_n;
    hil_auth_t auth;
} nl_serial_t;
void nl_serial_link(nl_link_t *l, nl_serial_t *s);
int nl_serial_send(nl_serial_t *s, const hil_core_frame_t *f);
int nl_serial_recv(nl_serial_t *s, hil_core_frame_t *f, int64_t deadline_ns);
typedef struct {
    int32_t fd;
    int32_t fd_frames;
    nl_spin_t spin;
    nl_link_stats_t stats;
    uint32_t kernel_dropped;
} nl_socketcan_t;
void nl_socketcan_link(nl_link_t *l, nl_socketcan_t *s);

/* the callback link: any Python link (python-can adapters, links to in-process, SIL and QEMU targets, the
   fault-injecting wrapper) carries the C loop's frames through these two Python functions */
extern "Python" int nl_py_send(void *ctx, const hil_core_frame_t *f);
extern "Python" int nl_py_recv(void *ctx, hil_core_frame_t *f, int64_t deadline_ns);
extern "Python" int nl_py_diag(void *ctx, uint32_t *split_ns, double *torque_ref, uint8_t *full_miss);
extern "Python" void nl_py_period(void *ctx, double t_s);
void nl_py_link(nl_link_t *l, void *ctx, int with_diag, int with_period);
int nl_socketcan_send(nl_socketcan_t *s, const hil_core_frame_t *f);
int nl_socketcan_recv(nl_socketcan_t *s, hil_core_frame_t *f, int64_t deadline_ns);
#define NT_END_SIGNAL ...
#define NT_END_PARENT ...
#define NT_END_IDLE ...
#define NT_END_CLOSED ...
int32_t nt_serve(const nl_link_t *l, int64_t idle_ns, int32_t parent_pid);
typedef void (*nt_core_rx_fn)(uint32_t id, const uint8_t *data, uint8_t len, uint8_t fd);
typedef int (*nt_core_tx_fn)(hil_core_frame_t *out);
int32_t nt_serve_core(const nl_link_t *l, int64_t idle_ns, int32_t parent_pid, nt_core_rx_fn rx, nt_core_tx_fn tx);
int32_t nt_serve_core_debug(const nl_link_t *l, int64_t idle_ns, int32_t parent_pid, nt_core_rx_fn rx,
                            nt_core_tx_fn tx, const uint32_t *steps, const float *torque_ref, nl_sil_debug_t *debug);
typedef struct {
    uint32_t frames_rx, measurements, commands, config_writes, config_rejected, faults, unknown_id, bad_length,
        tx_overflow, steps;
} hil_core_counters_t;
const hil_core_counters_t *hil_core_counters(void);
void hil_core_rx(uint32_t id, const uint8_t *data, uint8_t len, uint8_t fd);
int hil_core_tx(hil_core_frame_t *out);
"""

PREAMBLE = """
#include <stddef.h>
#include "loop.h"
#include "loop_fmu.h"
#include "pwm_duty.h"
#include "machine_kernel.h"
#include "loop_frames.h"
#include "loop_rt.h"
#include "hil_target_core.h"
#include "loop_udp.h"
#include "loop_serial.h"
#include "loop_socketcan.h"
#include "target_serve.h"
#include "link_floor.h"

static size_t nl_sizeof_period(void) { return sizeof(nl_period_t); }
static size_t nl_sizeof_frame(void) { return sizeof(nl_frame_rec_t); }
static void *nl_slot_periods(nl_handle_t *h, int32_t i) { return nl_slot(h, i)->periods; }
static void *nl_slot_frames(nl_handle_t *h, int32_t i) { return nl_slot(h, i)->frames; }
static int64_t *nl_slot_lateness(nl_handle_t *h, int32_t i) { return nl_slot(h, i)->lateness_ns; }
static nl_finding_t *nl_slot_findings(nl_handle_t *h, int32_t i) { return nl_slot(h, i)->findings; }
static double *nl_slot_noise(nl_handle_t *h, int32_t i) { return nl_slot(h, i)->noise; }

/* The callback link (hil/runner/native_pylink.py defines the two functions) */
static int nl_py_send(void *ctx, const hil_core_frame_t *f);
static int nl_py_recv(void *ctx, hil_core_frame_t *f, int64_t deadline_ns);
static int nl_py_diag(void *ctx, uint32_t *split_ns, double *torque_ref, uint8_t *full_miss);
static void nl_py_period(void *ctx, double t_s);
static void nl_py_link(nl_link_t *l, void *ctx, int with_diag, int with_period)
{
    l->send = nl_py_send;
    l->recv = nl_py_recv;
    l->ctx = ctx;
    l->diag = with_diag ? nl_py_diag : NULL;
    l->period = with_period ? nl_py_period : NULL;
}
"""


def _rel(path: Path) -> str:
    """Path relative to the working directory when possible (setuptools wants that)."""
    return str(path.relative_to(Path.cwd())) if path.is_relative_to(Path.cwd()) else str(path)


def _firmware_objects() -> list[str]:
    """Compile the firmware side with its own flags; the object files to link."""
    from setuptools._distutils.ccompiler import new_compiler
    from setuptools._distutils.sysconfig import customize_compiler

    cc = new_compiler()
    customize_compiler(cc)
    sources = [*sorted((_FW / "src").glob("*.c")), _FW / "target" / "hil_target_core.c",
               _FW / "target" / "hil_app_reference.c", _FW / "target" / "hil_serial.c", _FW / "target" / "hil_auth.c",
               _FW / "generated" / "hil_protocol.c"]
    out = tempfile.mkdtemp(prefix="hil-loop-fw-")
    objects: list[str] = cc.compile([str(s) for s in sources], output_dir=out,
                                    include_dirs=[str(p) for p in _FW_INCLUDES], extra_postargs=FIRMWARE_FLAGS)
    return objects


ffibuilder = FFI()
ffibuilder.cdef(CDEF)
ffibuilder.set_source(
    "pmsm_hil.hil._loop_native",
    PREAMBLE,
    sources=[_rel(_HERE / name) for name in LOOP_SOURCES],
    include_dirs=[_rel(_HERE), _rel(_HERE / "kernels"), *(_rel(p) for p in _FW_INCLUDES)],
    extra_compile_args=LOOP_FLAGS,
    extra_objects=_firmware_objects(),
    libraries=["m", "pthread", "dl"],
)

if __name__ == "__main__":
    ffibuilder.compile(verbose=True)
