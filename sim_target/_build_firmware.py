"""cffi (API mode) builder of the C reference firmware: extension `pmsm_hil.sim_target._firmware`.

The cdef below is written by hand to match firmware_stub/include/*.h; cffi checks the layout of the
fully declared structs against the real headers at build time. Build with
`.venv/bin/pip install --no-build-isolation -e .` (setup.py lists this builder in cffi_modules).
"""
from __future__ import annotations

import os
from pathlib import Path

from cffi import FFI

ROOT = Path(__file__).resolve().parent.parent
FIRMWARE = ROOT / "firmware_stub"

# The firmware's strict flags also hold for the cffi-generated wrapper (checked with gcc 12).
STRICT_FLAGS = [
    "-std=c99",
    "-Wall",
    "-Wextra",
    "-Werror",
    "-Wdouble-promotion",
    "-fsingle-precision-constant",
    "-O2",
]

CDEF = """
#define HIL_FW_OK ...
#define HIL_FW_E_PARAM_ID ...
#define HIL_FW_E_PARAM_VALUE ...
#define HIL_FW_E_CONTROLLER_ID ...
#define HIL_FW_E_NOT_IMPLEMENTED ...
#define HIL_FW_E_MODE ...
#define HIL_FW_E_REFERENCE ...
#define HIL_FW_E_NULL ...
#define HIL_FW_CTRL_COUNT ...
#define HIL_FW_P_COUNT ...
#define HIL_FW_MAX_PHASES ...
#define HIL_FW_MAX_SUBSTATES ...

typedef struct {
    uint16_t seq;
    uint8_t n_phases;
    uint8_t status;
    float i_abc[6];
    float theta_e;
    float omega_m;
    float vdc;
} hil_fw_meas_t;

typedef struct {
    uint16_t seq;
    uint8_t n_states;
    uint8_t vector_id;
    uint8_t candidates;
    uint8_t status;
    uint8_t states[3];
    uint8_t full_miss;
    uint8_t mirror;
    uint32_t durations_ns[3];
    float torque_ref;
    float id_ref;
    float iq_ref;
    float duty[6];
    uint8_t n_duties;
} hil_fw_cmd_t;

typedef struct {
    uint8_t controller_id;
    uint8_t enable;
    uint8_t mode;
    float reference;
    ...;
} hil_fw_state_t;

typedef struct {
    hil_fw_cmd_t cmd;
    uint32_t split_ns[3];
} hil_fw_py_out_t;

typedef struct {
    const char *name;
    uint8_t id;
    uint8_t phases;
    uint64_t params;
    ...;
} hil_fw_controller_t;

void hil_fw_init(hil_fw_state_t *s);
int hil_fw_set_param(hil_fw_state_t *s, uint8_t param_id, float value);
int hil_fw_get_param(const hil_fw_state_t *s, uint8_t param_id, float *value);
int hil_fw_select_controller(hil_fw_state_t *s, uint8_t controller_id);
int hil_fw_set_setpoint(hil_fw_state_t *s, uint8_t enable, uint8_t mode, float reference);
int hil_fw_controller_implemented(uint8_t controller_id);
const char *hil_fw_controller_name(uint8_t controller_id);
const hil_fw_controller_t *hil_fw_controller_get(uint8_t controller_id);

void hil_fw_stage_measure(hil_fw_state_t *s, const hil_fw_meas_t *m, uint64_t t_ns);
void hil_fw_stage_reference(hil_fw_state_t *s);
void hil_fw_stage_predict(hil_fw_state_t *s, hil_fw_cmd_t *cmd);
void hil_fw_step(hil_fw_state_t *s, const hil_fw_meas_t *m, uint64_t t_ns, hil_fw_cmd_t *cmd);
void hil_fw_step_profiled(hil_fw_state_t *s, const hil_fw_meas_t *m, uint64_t t_ns, hil_fw_cmd_t *cmd,
                          uint32_t split_ns[3]);

void hil_fw_py_step(hil_fw_state_t *s, hil_fw_meas_t *m, hil_fw_py_out_t *out, uint16_t seq,
                    uint8_t n_phases, float i0, float i1, float i2, float i3, float i4, float i5,
                    float theta_e, float omega_m, float vdc, uint64_t t_ns);
"""

# Glue for the Python wrapper: one call with scalar arguments fills the measurement record and
# runs the profiled step (cheaper than setting struct fields one by one from Python).
PREAMBLE = """
#include "hil_fw.h"
#include "hil_fw_dsvm.h"

typedef struct {
    hil_fw_cmd_t cmd;
    uint32_t split_ns[3];
} hil_fw_py_out_t;

static void hil_fw_py_step(hil_fw_state_t *s, hil_fw_meas_t *m, hil_fw_py_out_t *out, uint16_t seq,
                           uint8_t n_phases, float i0, float i1, float i2, float i3, float i4, float i5,
                           float theta_e, float omega_m, float vdc, uint64_t t_ns)
{
    m->seq = seq;
    m->n_phases = n_phases;
    m->status = 0u;
    m->i_abc[0] = i0;
    m->i_abc[1] = i1;
    m->i_abc[2] = i2;
    m->i_abc[3] = i3;
    m->i_abc[4] = i4;
    m->i_abc[5] = i5;
    m->theta_e = theta_e;
    m->omega_m = omega_m;
    m->vdc = vdc;
    hil_fw_step_profiled(s, m, t_ns, &out->cmd, out->split_ns);
    /* diagnostics outside the timed stages: restricted set vs the full DSVM set */
    out->cmd.full_miss = hil_fw_dsvm_full_miss(s);
}
"""


def _rel(path: Path) -> str:
    """Path relative to the working directory when possible (setuptools prefers relative sources)."""
    try:
        return os.path.relpath(path)
    except ValueError:
        return str(path)


ffibuilder = FFI()
ffibuilder.cdef(CDEF)
ffibuilder.set_source(
    "pmsm_hil.sim_target._firmware",
    PREAMBLE,
    sources=[_rel(p) for p in sorted((FIRMWARE / "src").glob("*.c"))],
    include_dirs=[_rel(FIRMWARE / "include"), _rel(FIRMWARE / "generated")],
    extra_compile_args=STRICT_FLAGS,
    libraries=["m"],
)

if __name__ == "__main__":
    ffibuilder.compile(verbose=True)
