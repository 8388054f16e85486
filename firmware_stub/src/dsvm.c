/* Reference firmware: DSVM (N = 2) tables, prediction core and switching sequences. */
#include <math.h>
#include <stddef.h>

#include "hil_fw_controllers.h"
#include "hil_fw_dsvm.h"
#include "hil_fw_inverter.h"
#include "hil_fw_state.h"
#include "hil_fw_transforms.h"

const hil_fw_dsvm_vector_t hil_fw_dsvm_vectors[HIL_FW_DSVM_VECTORS] = {
    {0, 0, 0u, 0u},                                                              /* zero */
    {2, 0, 1u, 1u},   {0, 2, 2u, 2u},  {-2, 2, 3u, 3u}, {-2, 0, 4u, 4u}, {0, -2, 5u, 5u},
    {2, -2, 6u, 6u},                                                             /* u1..u6 */
    {1, 1, 1u, 2u},   {-1, 2, 2u, 3u}, {-2, 1, 3u, 4u}, {-1, -1, 4u, 5u}, {1, -2, 5u, 6u},
    {2, -1, 6u, 1u},                                                             /* u12..u61 */
    {1, 0, 1u, 0u},   {0, 1, 2u, 0u},  {-1, 1, 3u, 0u}, {-1, 0, 4u, 0u}, {0, -1, 5u, 0u},
    {1, -1, 6u, 0u},                                                             /* u1Z..u6Z */
};

/* Fig. 6: region r is the closed triangle 0, u_{r+1}, u_{r+2}; the reference vector first. */
const uint8_t hil_fw_dsvm_triangle[6][6] = {
    {7u, 1u, 2u, 13u, 14u, 0u},  {8u, 2u, 3u, 14u, 15u, 0u},  {9u, 3u, 4u, 15u, 16u, 0u},
    {10u, 4u, 5u, 16u, 17u, 0u}, {11u, 5u, 6u, 17u, 18u, 0u}, {12u, 6u, 1u, 18u, 13u, 0u},
};

/* Fig. 8: region r is the closed kite 0, u_{r,r+1}, u_{r+1}, u_{r+1,r+2} (angle within 30 deg of
 * u_{r+1}); the reference vector first. */
const uint8_t hil_fw_dsvm_kite[6][5] = {
    {1u, 12u, 7u, 13u, 0u}, {2u, 7u, 8u, 14u, 0u},   {3u, 8u, 9u, 15u, 0u},
    {4u, 9u, 10u, 16u, 0u}, {5u, 10u, 11u, 17u, 0u}, {6u, 11u, 12u, 18u, 0u},
};

const uint8_t hil_fw_dsvm_lattice_index[5][5] = {
    {255u, 255u, 4u, 9u, 3u}, {255u, 10u, 16u, 15u, 8u}, {5u, 17u, 0u, 14u, 2u},
    {11u, 18u, 13u, 7u, 255u}, {6u, 12u, 1u, 255u, 255u},
};

#define SIN60 0.86602540378f

void hil_fw_dsvm_reset(struct hil_fw_state *s)
{
    s->ctrl.dsvm.next_t_ns = HIL_FW_DSVM_NO_STEP;
}

void hil_fw_dsvm_prepare(struct hil_fw_state *s)
{
    const hil_fw_model_t *m = &s->params.model;
    const hil_fw_measured_t *me = &s->meas;
    hil_fw_dsvm_state_t *st = &s->ctrl.dsvm;
    const float wts = me->omega_e * m->ts;
    const float e = me->vdc * (1.0f / 3.0f); /* lattice step [V] */
    float c1; /* cos/sin at the middle of [k, k+1) */
    float s1;
    float c2; /* cos/sin at the middle of [k+1, k+2) */
    float s2;
    float ua;
    float ub;
    float id1;
    float iq1;
    hil_fw_mid_angles(me->cos_th, me->sin_th, wts, &c1, &s1, &c2, &s2);
    hil_fw_cmd_mean_voltage_ab(s->applied.states, s->applied.durations_ns, s->applied.n_states, me->vdc, &ua,
                               &ub);
    id1 = m->ad * me->i_d + m->lq_ld * wts * me->i_q + m->kd * (ua * c1 + ub * s1);
    iq1 = m->aq * me->i_q - m->ld_lq * wts * me->i_d - m->psi_lq * wts + m->kq * (-ua * s1 + ub * c1);
    st->id1 = id1;
    st->iq1 = iq1;
    st->c2 = c2;
    st->s2 = s2;
    st->err_d = s->ref.i_d - (m->ad * id1 + m->lq_ld * wts * iq1);
    st->err_q = s->ref.i_q - (m->aq * iq1 - m->ld_lq * wts * id1 - m->psi_lq * wts);
    /* e1 = e (1, 0), e2 = e (1/2, sin 60) in alpha/beta, rotated into dq at the middle angle. */
    st->d1d = m->kd * e * c2;
    st->d1q = -m->kq * e * s2;
    st->d2d = m->kd * e * (0.5f * c2 + SIN60 * s2);
    st->d2q = m->kq * e * (-0.5f * s2 + SIN60 * c2);
    st->prepared = 1u;
}

float hil_fw_dsvm_cost(const hil_fw_dsvm_state_t *st, uint8_t idx)
{
    const float m = (float)hil_fw_dsvm_vectors[idx].m;
    const float n = (float)hil_fw_dsvm_vectors[idx].n;
    return fabsf(st->err_d - m * st->d1d - n * st->d2d) + fabsf(st->err_q - m * st->d1q - n * st->d2q);
}

static uint8_t real_code(uint8_t j, uint8_t zero_code)
{
    return j == 0u ? zero_code : hil_fw_vector_state[j];
}

void hil_fw_dsvm_sequence(uint8_t idx, uint8_t prev_code, uint32_t ts_ns, hil_fw_cmd_t *cmd)
{
    const hil_fw_dsvm_vector_t *v = &hil_fw_dsvm_vectors[idx];
    uint8_t zero;
    uint8_t a;
    uint8_t b;
    if (v->half_a == 0u) {
        zero = hil_fw_zero_state_for(prev_code);
    } else {
        /* zero next to the active vector: 000 after one upper switch on, 111 after two */
        zero = hil_fw_zero_state_for(hil_fw_vector_state[v->half_a]);
    }
    a = real_code(v->half_a, zero);
    b = real_code(v->half_b, zero);
    if (hil_fw_leg_transitions(prev_code, b) < hil_fw_leg_transitions(prev_code, a)) {
        const uint8_t t = a;
        a = b;
        b = t;
    }
    cmd->n_states = 2u;
    cmd->states[0] = a;
    cmd->states[1] = b;
    cmd->states[2] = 0u;
    cmd->durations_ns[0] = ts_ns / 2u;
    cmd->durations_ns[1] = ts_ns - ts_ns / 2u;
    cmd->durations_ns[2] = 0u;
}

void hil_fw_dsvm_choose(struct hil_fw_state *s, hil_fw_cmd_t *cmd)
{
    hil_fw_dsvm_state_t *st = &s->ctrl.dsvm;
    const uint8_t n = s->applied.n_states;
    const uint8_t prev = s->applied.states[n > 0u ? n - 1u : 0u];
    uint8_t best = st->cand[0];
    float best_cost = hil_fw_dsvm_cost(st, best);
    uint8_t i;
    for (i = 1u; i < st->n_cand; ++i) {
        const float g = hil_fw_dsvm_cost(st, st->cand[i]);
        if (g < best_cost) {
            best_cost = g;
            best = st->cand[i];
        }
    }
    st->best = best;
    st->best_cost = best_cost;
    hil_fw_dsvm_sequence(best, prev, s->params.model.ts_ns, cmd);
    cmd->vector_id = best;
    cmd->candidates = st->n_cand;
    cmd->status = HIL_FW_STATUS_OK;
}

void hil_fw_dsvm20_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd)
{
    hil_fw_dsvm_state_t *st = &s->ctrl.dsvm;
    uint8_t i;
    hil_fw_dsvm_prepare(s);
    for (i = 0u; i < HIL_FW_DSVM_VECTORS; ++i) {
        st->cand[i] = i;
    }
    st->n_cand = HIL_FW_DSVM_VECTORS;
    hil_fw_dsvm_choose(s, cmd);
}

void hil_fw_dsvm_restricted_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd)
{
    hil_fw_dsvm_choose(s, cmd);
}

uint8_t hil_fw_dsvm_full_miss(const struct hil_fw_state *s)
{
    const hil_fw_dsvm_state_t *st = &s->ctrl.dsvm;
    const hil_fw_controller_t *c = hil_fw_controller_get(s->controller_id);
    float full = 0.0f;
    uint8_t i;
    /* restricted-set controllers evaluate the reference stage's list; the state is reset on select */
    if (c == NULL || c->predict != hil_fw_dsvm_restricted_predict || !s->enable ||
        s->meas.fault != HIL_FW_STATUS_OK || !st->prepared) {
        return HIL_FW_DSVM_NO_DIAG;
    }
    for (i = 0u; i < HIL_FW_DSVM_VECTORS; ++i) {
        const float g = hil_fw_dsvm_cost(st, i);
        if (i == 0u || g < full) {
            full = g;
        }
    }
    /* same float expressions for shared candidates, so equal optima compare equal */
    return full < st->best_cost ? 1u : 0u;
}
