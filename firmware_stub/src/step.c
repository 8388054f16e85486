/* Reference firmware: the three stages of one control step (Table 4 split). */
#include <math.h>
#include <stddef.h>

#include "hil_fw_controllers.h"
#include "hil_fw_inverter.h"
#include "hil_fw_six.h"
#include "hil_fw_step.h"
#include "hil_fw_transforms.h"
#include "hil_fw_vseq.h"

static float clampf(float x, float lim)
{
    return x > lim ? lim : (x < -lim ? -lim : x);
}

/* 1 when the speed loop is due at t_ns; keeps its own schedule from the passed-in time. */
static int speed_due(hil_fw_state_t *s, uint64_t t_ns, uint64_t period_ns)
{
    if (!s->speed_primed || t_ns + period_ns / 2u >= s->speed_next_ns ||
        s->speed_next_ns > t_ns + 2u * period_ns) {
        s->speed_primed = 1u;
        s->speed_next_ns = t_ns + period_ns;
        return 1;
    }
    return 0;
}

/* The frame carries the phase count of the selected controller's table entry (0: either 3 or 6). */
static int phases_match(uint8_t controller_id, uint8_t n_phases)
{
    const hil_fw_controller_t *c = hil_fw_controller_get(controller_id);
    if (c == NULL || c->phases == 0u) {
        return n_phases == 3u || n_phases == 6u;
    }
    return n_phases == c->phases;
}

static uint8_t check_frame(const hil_fw_meas_t *m, uint8_t controller_id)
{
    if (!phases_match(controller_id, m->n_phases)) {
        return HIL_FW_STATUS_INVALID_CONFIG;
    }
    if (!isfinite(m->i_abc[0]) || !isfinite(m->i_abc[1]) || !isfinite(m->i_abc[2]) ||
        !isfinite(m->theta_e) || !isfinite(m->omega_m) || !isfinite(m->vdc)) {
        return HIL_FW_STATUS_BAD_FRAME;
    }
    if (m->n_phases == 6u && (!isfinite(m->i_abc[3]) || !isfinite(m->i_abc[4]) || !isfinite(m->i_abc[5]))) {
        return HIL_FW_STATUS_BAD_FRAME;
    }
    return HIL_FW_STATUS_OK;
}

/* Torque [N*m] -> (id, iq) [A] under the current-magnitude limit. */
static void torque_to_currents(hil_fw_state_t *s, float torque)
{
    const float *v = s->params.value;
    const float imax = v[HIL_FW_P_CURRENT_LIMIT];
    const float id = clampf(v[HIL_FW_P_ID_REF], imax);
    const float tk = s->params.model.torque_k * (s->meas.n_phases == 6u ? 2.0f : 1.0f); /* six: 3 p */
    const float den = tk * (v[HIL_FW_P_PSI_F] + (v[HIL_FW_P_LD] - v[HIL_FW_P_LQ]) * id);
    const float iq_max = sqrtf(imax * imax - id * id);
    s->ref.torque = torque;
    s->ref.i_d = id;
    s->ref.i_q = fabsf(den) > 1.0e-9f ? clampf(torque / den, iq_max) : 0.0f;
}

void hil_fw_stage_measure(hil_fw_state_t *s, const hil_fw_meas_t *m, uint64_t t_ns)
{
    hil_fw_measured_t *me = &s->meas;
    float torque = 0.0f;
    me->t_ns = t_ns;
    me->seq = m->seq;
    me->n_phases = m->n_phases;
    me->plant_status = m->status;
    me->fault = check_frame(m, s->controller_id);
    if (me->fault == HIL_FW_STATUS_OK) {
        me->theta_e = m->theta_e;
        me->cos_th = cosf(m->theta_e);
        me->sin_th = sinf(m->theta_e);
        if (m->n_phases == 6u) {
            hil_fw_vsd(m->i_abc, &me->i_alpha, &me->i_beta, &me->i_x, &me->i_y);
        } else {
            hil_fw_clarke(m->i_abc[0], m->i_abc[1], m->i_abc[2], &me->i_alpha, &me->i_beta);
            me->i_x = 0.0f;
            me->i_y = 0.0f;
        }
        hil_fw_park(me->i_alpha, me->i_beta, me->cos_th, me->sin_th, &me->i_d, &me->i_q);
        me->omega_m = m->omega_m;
        me->omega_e = s->params.value[HIL_FW_P_POLE_PAIRS] * m->omega_m;
        me->vdc = m->vdc > 0.0f ? m->vdc : s->params.value[HIL_FW_P_VDC];
    }
    if (s->enable && me->fault == HIL_FW_STATUS_OK) {
        if (s->mode == HIL_FW_MODE_SPEED) {
            const uint64_t period_ns = (uint64_t)s->params.model.ts_ns * HIL_FW_SPEED_DIV;
            if (speed_due(s, t_ns, period_ns)) {
                const float dt = s->params.model.ts * (float)HIL_FW_SPEED_DIV;
                hil_fw_speed_pi_update(&s->speed_pi, s->reference - me->omega_m, dt);
            }
            torque = s->speed_pi.out;
        } else {
            torque = clampf(s->reference, s->params.value[HIL_FW_P_TORQUE_LIMIT]);
        }
        torque_to_currents(s, torque);
    } else {
        s->ref.torque = 0.0f;
        s->ref.i_d = 0.0f;
        s->ref.i_q = 0.0f;
    }
}

void hil_fw_stage_reference(hil_fw_state_t *s)
{
    const hil_fw_controller_t *c = hil_fw_controller_get(s->controller_id);
    if (s->enable && s->meas.fault == HIL_FW_STATUS_OK && c != NULL && c->reference != NULL) {
        c->reference(s);
    }
}

/* Full-period zero vector with the fewest leg transitions from the applied state. */
static void safe_command(const hil_fw_state_t *s, hil_fw_cmd_t *cmd, uint8_t status)
{
    const uint8_t n = s->applied.n_states;
    const uint8_t last = s->applied.states[n > 0u ? n - 1u : 0u];
    cmd->n_states = 1u;
    cmd->states[0] = s->meas.n_phases == 6u ? hil_fw_six_zero_for(last) : hil_fw_zero_state_for(last);
    cmd->states[1] = 0u;
    cmd->states[2] = 0u;
    cmd->durations_ns[0] = s->params.model.ts_ns;
    cmd->durations_ns[1] = 0u;
    cmd->durations_ns[2] = 0u;
    cmd->vector_id = s->meas.n_phases == 6u ? 0u : hil_fw_state_vector[cmd->states[0]];
    cmd->candidates = 0u;
    cmd->status = status;
    cmd->mirror = 0u;
}

void hil_fw_stage_predict(hil_fw_state_t *s, hil_fw_cmd_t *cmd)
{
    const hil_fw_controller_t *c = hil_fw_controller_get(s->controller_id);
    uint8_t i;
    cmd->seq = s->meas.seq;
    cmd->torque_ref = s->ref.torque;
    cmd->id_ref = s->ref.i_d;
    cmd->iq_ref = s->ref.i_q;
    cmd->mirror = 0u; /* controllers that send a mirrored sequence set it */
    cmd->n_duties = 0u; /* controllers that send duty cycles set it (foc) */
    if (s->meas.fault != HIL_FW_STATUS_OK) {
        safe_command(s, cmd, s->meas.fault);
    } else if (c == NULL || (c->predict == NULL && s->controller_id != HIL_FW_CTRL_OFF)) {
        safe_command(s, cmd, HIL_FW_STATUS_NOT_IMPLEMENTED);
    } else if (!s->enable || c->predict == NULL) {
        safe_command(s, cmd, HIL_FW_STATUS_OK);
    } else {
        c->predict(s, cmd);
    }
    s->applied.vector_id = cmd->vector_id;
    s->applied.n_states = hil_fw_vseq_expand(cmd->states, cmd->durations_ns, cmd->n_states, cmd->mirror,
                                             s->applied.states, s->applied.durations_ns);
    for (i = s->applied.n_states; i < HIL_FW_MAX_APPLIED; ++i) {
        s->applied.states[i] = 0u;
        s->applied.durations_ns[i] = 0u;
    }
}

void hil_fw_step(hil_fw_state_t *s, const hil_fw_meas_t *m, uint64_t t_ns, hil_fw_cmd_t *cmd)
{
    hil_fw_stage_measure(s, m, t_ns);
    hil_fw_stage_reference(s);
    hil_fw_stage_predict(s, cmd);
}
