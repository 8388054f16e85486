/*
 * Reference firmware: conventional MPCC (benchmark of the paper), see docs/algorithms/mpcc.md.
 *
 * Model: forward-Euler dq model, eq. (1) plus the back-EMF term -omega*psi_f/Lq*Ts in i_q.
 * Delay compensation (two-step): i(k+1) from the measured i(k) and the command applied during
 * [k, k+1); each candidate is evaluated over [k+1, k+2). The stator-frame vector rotates in dq,
 * so its dq voltage is taken at the rotor angle in the middle of its application interval.
 */
#include <math.h>

#include "hil_fw_inverter.h"
#include "hil_fw_mpcc.h"
#include "hil_fw_state.h"
#include "hil_fw_transforms.h"

/* Active vectors V1..V6 in alpha/beta per unit of 2/3 Vdc: angle (j - 1) * 60 degrees. */
static const float unit_alpha[6] = {1.0f, 0.5f, -0.5f, -1.0f, -0.5f, 0.5f};
static const float unit_beta[6] = {0.0f, 0.86602540378f, 0.86602540378f, 0.0f, -0.86602540378f,
                                   -0.86602540378f};

void hil_fw_mpcc_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd)
{
    const hil_fw_model_t *m = &s->params.model;
    const hil_fw_measured_t *me = &s->meas;
    hil_fw_mpcc_state_t *st = &s->ctrl.mpcc;
    const float wts = me->omega_e * m->ts; /* electrical angle advanced per period [rad] */
    /* cos/sin at the middle of [k, k+1): theta + wts/2, and of [k+1, k+2): theta + 3 wts/2 */
    float c1;
    float s1;
    float c2;
    float s2;
    float ua;
    float ub;
    float vd;
    float vq;
    float id1;
    float iq1;
    float base_d;
    float base_q;
    float err_d;
    float err_q;
    float best_cost;
    float best_d;
    float best_q;
    float vmag;
    int best = 0; /* 0: zero vector, 1..6: V1..V6 */
    int j;

    hil_fw_mid_angles(me->cos_th, me->sin_th, wts, &c1, &s1, &c2, &s2);
    /* Step 1: i(k+1) under the command applied during [k, k+1). */
    hil_fw_cmd_mean_voltage_ab(s->applied.states, s->applied.durations_ns, s->applied.n_states, me->vdc,
                               &ua, &ub);
    hil_fw_park(ua, ub, c1, s1, &vd, &vq);
    id1 = m->ad * me->i_d + m->lq_ld * wts * me->i_q + m->kd * vd;
    iq1 = m->aq * me->i_q - m->ld_lq * wts * me->i_d - m->psi_lq * wts + m->kq * vq;

    /* Step 2: i(k+2) = base + K v_j for each candidate over [k+1, k+2). */
    base_d = m->ad * id1 + m->lq_ld * wts * iq1;
    base_q = m->aq * iq1 - m->ld_lq * wts * id1 - m->psi_lq * wts;
    err_d = s->ref.i_d - base_d; /* error left by the zero vector */
    err_q = s->ref.i_q - base_q;
    best_cost = fabsf(err_d) + fabsf(err_q);
    best_d = base_d;
    best_q = base_q;
    vmag = (2.0f / 3.0f) * me->vdc;
    for (j = 0; j < 6; ++j) {
        const float va = vmag * unit_alpha[j];
        const float vb = vmag * unit_beta[j];
        const float dd = m->kd * (va * c2 + vb * s2);
        const float dq = m->kq * (-va * s2 + vb * c2);
        const float g = fabsf(err_d - dd) + fabsf(err_q - dq); /* eq. (4) */
        if (g < best_cost) {
            best_cost = g;
            best = j + 1;
            best_d = base_d + dd;
            best_q = base_q + dq;
        }
    }

    st->i_d1 = id1;
    st->i_q1 = iq1;
    st->i_d2 = best_d;
    st->i_q2 = best_q;
    st->cost = best_cost;

    cmd->n_states = 1u;
    if (best == 0) {
        const uint8_t prev = s->applied.states[s->applied.n_states > 0u ? s->applied.n_states - 1u : 0u];
        cmd->states[0] = hil_fw_zero_state_for(prev);
    } else {
        cmd->states[0] = hil_fw_vector_state[best];
    }
    cmd->vector_id = hil_fw_state_vector[cmd->states[0]];
    cmd->durations_ns[0] = m->ts_ns;
    cmd->states[1] = 0u;
    cmd->states[2] = 0u;
    cmd->durations_ns[1] = 0u;
    cmd->durations_ns[2] = 0u;
    cmd->candidates = HIL_FW_MPCC_CANDIDATES;
    cmd->status = HIL_FW_STATUS_OK;
}
