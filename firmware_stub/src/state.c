/* Reference firmware: state initialisation and configuration calls. */
#include <math.h>
#include <stddef.h>

#include "hil_fw_controllers.h"
#include "hil_fw_state.h"

static void sync_pi_params(hil_fw_state_t *s)
{
    s->speed_pi.kp = s->params.value[HIL_FW_P_SPEED_KP];
    s->speed_pi.ki = s->params.value[HIL_FW_P_SPEED_KI];
    s->speed_pi.limit = s->params.value[HIL_FW_P_TORQUE_LIMIT];
}

void hil_fw_init(hil_fw_state_t *s)
{
    hil_fw_measured_t zero_meas = {0};
    uint8_t i;
    hil_fw_params_defaults(&s->params);
    sync_pi_params(s);
    hil_fw_speed_pi_reset(&s->speed_pi, s->params.value[HIL_FW_P_TORQUE_INTEGRATOR_INIT]);
    s->controller_id = HIL_FW_CTRL_OFF;
    s->enable = 0u;
    s->mode = HIL_FW_MODE_SPEED;
    s->speed_primed = 0u;
    s->reference = 0.0f;
    s->speed_next_ns = 0u;
    s->meas = zero_meas;
    s->meas.cos_th = 1.0f;
    s->meas.vdc = s->params.value[HIL_FW_P_VDC];
    s->ref.torque = 0.0f;
    s->ref.i_d = 0.0f;
    s->ref.i_q = 0.0f;
    s->applied.n_states = 1u;
    s->applied.vector_id = 0u;
    for (i = 0u; i < HIL_FW_MAX_APPLIED; ++i) {
        s->applied.states[i] = 0u;
        s->applied.durations_ns[i] = 0u;
    }
    s->applied.durations_ns[0] = s->params.model.ts_ns;
    hil_fw_controller_reset(s);
}

int hil_fw_set_param(hil_fw_state_t *s, uint8_t param_id, float value)
{
    int rc;
    if (s == NULL) {
        return HIL_FW_E_NULL;
    }
    rc = hil_fw_param_check(param_id, value);
    if (rc != HIL_FW_OK) {
        return rc;
    }
    s->params.value[param_id] = value;
    hil_fw_params_derive(&s->params);
    sync_pi_params(s);
    if (param_id == HIL_FW_P_TORQUE_LIMIT) {
        hil_fw_speed_pi_reset(&s->speed_pi, s->speed_pi.integ); /* re-clamp */
    }
    return HIL_FW_OK;
}

int hil_fw_get_param(const hil_fw_state_t *s, uint8_t param_id, float *value)
{
    if (s == NULL || value == NULL) {
        return HIL_FW_E_NULL;
    }
    if (param_id == 0u || param_id >= HIL_FW_P_COUNT) {
        return HIL_FW_E_PARAM_ID;
    }
    *value = s->params.value[param_id];
    return HIL_FW_OK;
}

int hil_fw_select_controller(hil_fw_state_t *s, uint8_t controller_id)
{
    if (s == NULL) {
        return HIL_FW_E_NULL;
    }
    if (hil_fw_controller_get(controller_id) == NULL) {
        return HIL_FW_E_CONTROLLER_ID;
    }
    if (!hil_fw_controller_implemented(controller_id)) {
        return HIL_FW_E_NOT_IMPLEMENTED;
    }
    if (controller_id != s->controller_id) {
        s->controller_id = controller_id;
        hil_fw_controller_reset(s);
    }
    return HIL_FW_OK;
}

int hil_fw_set_setpoint(hil_fw_state_t *s, uint8_t enable, uint8_t mode, float reference)
{
    const uint8_t on = enable ? 1u : 0u;
    if (s == NULL) {
        return HIL_FW_E_NULL;
    }
    if (mode != HIL_FW_MODE_SPEED && mode != HIL_FW_MODE_TORQUE) {
        return HIL_FW_E_MODE;
    }
    if (!isfinite(reference)) {
        return HIL_FW_E_REFERENCE;
    }
    if (on && !s->enable) {
        hil_fw_controller_reset(s);
    }
    if (on && mode == HIL_FW_MODE_SPEED && (!s->enable || s->mode != HIL_FW_MODE_SPEED)) {
        hil_fw_speed_pi_reset(&s->speed_pi, s->params.value[HIL_FW_P_TORQUE_INTEGRATOR_INIT]);
        s->speed_primed = 0u;
    }
    s->enable = on;
    s->mode = mode;
    s->reference = reference;
    return HIL_FW_OK;
}
