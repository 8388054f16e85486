"""cffi (API mode) builder for the plant kernel: extension `pmsm_hil.hil._plant_native`."""

from __future__ import annotations

from pathlib import Path

from cffi import FFI

_HERE = Path(__file__).resolve().parent

CDEF = """
typedef struct {
    double rs, ld, lq, psi_f, vdc, j, b, t_dead, t_mpw, max_piece;
    int32_t pole_pairs;
    int32_t inertia_mode;
} pl_params_t;
typedef struct {
    uint64_t t_ns;
    uint64_t trace_k;
    double i_d, i_q, theta_e, omega_m;
    double last_edge_t[3];
    double dead_until[3];
    int32_t gate;
    int32_t dead_level[3];
} pl_state_t;
typedef ge_period_stats_t pl_period_stats_t;
int pl_advance(const pl_params_t *p, pl_state_t *s, const int32_t *states, const int64_t *durations_ns,
               int32_t n, double t_load0, double t_load_slope, const double *load_bp, int32_t n_load_bp,
               double trace_dt, double *trace,
               int32_t trace_cap, pl_period_stats_t *stats);
double pl_torque(const pl_params_t *p, double i_d, double i_q);
void pl_phase_currents(double i_d, double i_q, double theta_e, double *i_a, double *i_b, double *i_c);
"""

#: Second set of functions: the dual three-phase kernel (plant6.c), same extension module.
CDEF6 = """
typedef struct {
    double rs, ld, lq, lls, psi_f, vdc, j, b, t_dead, t_mpw, max_piece;
    int32_t pole_pairs;
    int32_t inertia_mode;
} p6_params_t;
typedef struct {
    uint64_t t_ns;
    uint64_t trace_k;
    double i_d, i_q, i_x, i_y, theta_e, omega_m;
    double last_edge_t[6];
    double dead_until[6];
    int32_t gate;
    int32_t dead_level[6];
} p6_state_t;
typedef ge_period_stats_t p6_period_stats_t;
int p6_advance(const p6_params_t *p, p6_state_t *s, const int32_t *states, const int64_t *durations_ns,
               int32_t n, double t_load0, double t_load_slope, const double *load_bp, int32_t n_load_bp,
               double trace_dt, double *trace,
               int32_t trace_cap, p6_period_stats_t *stats);
double p6_torque(const p6_params_t *p, double i_d, double i_q);
void p6_phase_currents(double i_d, double i_q, double theta_e, double i_x, double i_y, double *i_phase);
void p6_code_voltage(double vdc, int32_t code, double *v4);
"""

#: The machine-kernel tables (machine_kernel.h) of both plants, opaque here: the native loop calls them.
CDEF_KERNELS = """
const mk_kernel_t *pl_kernel(void);
const mk_kernel_t *p6_kernel(void);
"""


def _source(name: str) -> str:
    """Source path, relative to the working directory when possible (setuptools wants that)."""
    path = _HERE / name
    return str(path.relative_to(Path.cwd())) if path.is_relative_to(Path.cwd()) else str(path)


#: stats struct, sample struct and the opaque table type, shared with every kernel (hil/kernel_build.py)
CDEF_COMMON = (_HERE / "machine_kernel.cdef").read_text(encoding="utf-8")

#: the plant kernels and their shared helpers (nothing of the loop: tests/test_layers.py)
PLANT_SOURCES = ("dq_segment.c", "gate_edges.c", "plant.c", "plant6.c")

ffibuilder = FFI()
ffibuilder.cdef(CDEF_COMMON + CDEF + CDEF6 + CDEF_KERNELS)
ffibuilder.set_source(
    "pmsm_hil.hil._plant_native",
    '#include "plant.h"\n#include "plant6.h"',
    sources=[_source(name) for name in PLANT_SOURCES],
    include_dirs=[str(_HERE)],
    # the native loop calls these kernels too: no FMA contraction and no sin/cos fusion, so its records equal the
    # Python loop's bit for bit on every architecture
    extra_compile_args=["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion", "-ffp-contract=off",
                        "-fno-builtin-sin", "-fno-builtin-cos"],
    libraries=["m"],
)

if __name__ == "__main__":
    ffibuilder.compile(verbose=True)
