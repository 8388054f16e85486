/* Shared fixtures for the firmware tests: a configured state and a measurement builder. */
#ifndef FW_FIXTURE_H
#define FW_FIXTURE_H

#include <math.h>

#include "hil_fw.h"

/* Defaults + MPCC selected + enabled in torque mode with the given torque [N*m]. */
static inline void fw_fixture_torque(hil_fw_state_t *s, float torque)
{
    hil_fw_init(s);
    (void)hil_fw_select_controller(s, HIL_FW_CTRL_MPCC);
    (void)hil_fw_set_setpoint(s, 1u, HIL_FW_MODE_TORQUE, torque);
}

/* Three-phase measurement from rotor-frame currents [A] at angle theta_e [rad]. */
static inline hil_fw_meas_t fw_meas_dq(uint16_t seq, float id, float iq, float theta_e, float omega_m, float vdc)
{
    hil_fw_meas_t m;
    float al, be;
    int i;
    m.seq = seq;
    m.n_phases = 3u;
    m.status = 0u;
    for (i = 0; i < HIL_FW_MAX_PHASES; ++i) {
        m.i_abc[i] = 0.0f;
    }
    hil_fw_park_inv(id, iq, cosf(theta_e), sinf(theta_e), &al, &be);
    hil_fw_clarke_inv(al, be, &m.i_abc[0], &m.i_abc[1], &m.i_abc[2]);
    m.theta_e = theta_e;
    m.omega_m = omega_m;
    m.vdc = vdc;
    return m;
}

/* Make the previously commanded vector (applied during [k, k+1)) the switching code `code`. */
static inline void fw_set_applied(hil_fw_state_t *s, uint8_t code)
{
    s->applied.n_states = 1u;
    s->applied.states[0] = code;
    s->applied.durations_ns[0] = s->params.model.ts_ns;
    s->applied.vector_id = hil_fw_state_vector[code];
}

#endif
