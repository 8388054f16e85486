/* Shared fixtures for the firmware tests: a configured state and a measurement builder. */
#ifndef FW_FIXTURE_H
#define FW_FIXTURE_H

#include <math.h>
#include <stddef.h>

#include "hil_fw.h"

/* One parameter of a test machine: its id (HIL_FW_P_*) and value in SI units. */
typedef struct {
    uint8_t id;
    float value;
} fw_param_t;

#define FW_COUNT(array) (sizeof(array) / sizeof((array)[0]))

/* hil_fw_init, the n parameters of `machine` in order, `controller` selected and enabled in torque mode at `torque`
 * [N*m]: 0 when the firmware took all of it, else the first refusal (a parameter's id; -1 the controller, -2 the
 * setpoint). */
static inline int fw_fixture_machine(hil_fw_state_t *s, const fw_param_t *machine, size_t n, uint8_t controller,
                                     float torque)
{
    size_t k;
    hil_fw_init(s);
    for (k = 0; k < n; ++k) {
        if (hil_fw_set_param(s, machine[k].id, machine[k].value) != 0) {
            return machine[k].id;
        }
    }
    if (hil_fw_select_controller(s, controller) != 0) {
        return -1;
    }
    return hil_fw_set_setpoint(s, 1u, HIL_FW_MODE_TORQUE, torque) != 0 ? -2 : 0;
}

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
