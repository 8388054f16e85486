/*
 * The Python glue of the reference firmware's cffi extension (pmsm_hil.sim_target._firmware): included once, by
 * the extension's preamble (src/pmsm_hil/sim_target/_build_firmware.py), which takes the cffi declarations of what is here from
 * this header. One call with scalar arguments fills the measurement record and runs the profiled step (cheaper
 * than setting struct fields one by one from Python).
 */
#ifndef HIL_SIM_TARGET_FIRMWARE_PY_H
#define HIL_SIM_TARGET_FIRMWARE_PY_H

#include <stdint.h>

#include "hil_fw.h"
#include "hil_fw_dsvm.h"

/* A step's command and its stage split: measurement, reference, prediction [ns]. */
typedef struct {
    hil_fw_cmd_t cmd;
    uint32_t split_ns[3];
} hil_fw_py_out_t;

/* *m filled (status 0) from the arguments (currents [A], theta_e [rad], omega_m [rad/s], vdc [V]), then
 * hil_fw_step_profiled into *out, then the untimed diagnostics (restricted set vs the full DSVM set). */
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

#endif
