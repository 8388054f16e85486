/* Reference firmware: reference-vector stage of FCS-MPC I and II (Tables 1 and 2). */
#include <math.h>

#include "hil_fw_dsvm.h"
#include "hil_fw_fcs_mpc.h"
#include "hil_fw_inverter.h"
#include "hil_fw_state.h"
#include "hil_fw_transforms.h"

/* DSVM indices: u12..u61 = 7..12, u1..u6 = 1..6. Rows as printed in the paper. */
const uint8_t hil_fw_fcs_table1[4][6] = {
    {7u, 8u, 9u, 10u, 11u, 12u},  /* h_psi 1, h_te 1: u12 u23 u34 u45 u56 u61 */
    {11u, 12u, 7u, 8u, 9u, 10u},  /* h_psi 1, h_te 0: u56 u61 u12 u23 u34 u45 */
    {8u, 9u, 10u, 11u, 12u, 7u},  /* h_psi 0, h_te 1: u23 u34 u45 u56 u61 u12 */
    {10u, 11u, 12u, 7u, 8u, 9u},  /* h_psi 0, h_te 0: u45 u56 u61 u12 u23 u34 */
};
const uint8_t hil_fw_fcs_table2[4][6] = {
    {2u, 3u, 4u, 5u, 6u, 1u}, /* h_psi 1, h_te 1 */
    {6u, 1u, 2u, 3u, 4u, 5u}, /* h_psi 1, h_te 0 */
    {3u, 4u, 5u, 6u, 1u, 2u}, /* h_psi 0, h_te 1 */
    {5u, 6u, 1u, 2u, 3u, 4u}, /* h_psi 0, h_te 0 */
};

uint8_t hil_fw_fcs_sector_rot(float alpha, float beta, uint8_t rot)
{
    /* shift by +30 deg - rot * 30 deg so that sector boundaries fall on multiples of 60 deg */
    const float ang = atan2f(beta, alpha) + (HIL_FW_PI_F / 6.0f) * (1.0f - (float)(rot % 12u));
    int k;
    if (!isfinite(ang)) {
        return 1u; /* a NaN/inf flux estimate has no sector: sector 1, never a NaN cast (undefined in C) */
    }
    k = (int)floorf(ang * (3.0f / HIL_FW_PI_F)); /* -9..3 */
    k %= 6;
    if (k < 0) {
        k += 6;
    }
    return (uint8_t)(k + 1);
}

uint8_t hil_fw_fcs_sector(float alpha, float beta)
{
    return hil_fw_fcs_sector_rot(alpha, beta, 0u);
}

uint8_t hil_fw_fcs_lookup(int table, uint8_t h_psi, uint8_t h_te, uint8_t sector)
{
    const int row = (h_psi ? 0 : 2) + (h_te ? 0 : 1);
    if (sector < 1u || sector > 6u) {
        return 255u;
    }
    if (table == HIL_FW_FCS_TABLE_VIRTUAL) {
        return hil_fw_fcs_table1[row][sector - 1u];
    }
    if (table == HIL_FW_FCS_TABLE_REAL) {
        return hil_fw_fcs_table2[row][sector - 1u];
    }
    return 255u;
}

unsigned hil_fw_fcs_reading(const struct hil_fw_state *s)
{
    const unsigned set = (unsigned)s->params.value[HIL_FW_P_FCS_READING];
    if (set != HIL_FW_FCS_READING_CONTROLLER_DEFAULT) {
        return set;
    }
    return s->controller_id == HIL_FW_CTRL_FCS_MPC_1 ? HIL_FW_FCS_READING_DEFAULT_1 : HIL_FW_FCS_READING_DEFAULT_2;
}

/* Comparator with band (0: plain two-level): 1 above +band, 0 below -band, else unchanged. */
static uint8_t compare(float delta, float band, uint8_t prev)
{
    if (delta > band) {
        return 1u;
    }
    if (delta < -band) {
        return 0u;
    }
    return prev;
}

/* Flux observer eq. (10) (trapezoidal in the current), estimates at k+1 (or k), comparators, sector;
 * the reading bits of fcs_reading (hil_fw_fcs_mpc.h). */
static void dtc_state(struct hil_fw_state *s)
{
    hil_fw_dsvm_state_t *st = &s->ctrl.dsvm;
    const hil_fw_measured_t *me = &s->meas;
    const float *p = s->params.value;
    const float ts = s->params.model.ts;
    const float rs = p[HIL_FW_P_RS];
    const float wts = me->omega_e * ts;
    const float cw = cosf(wts);
    const float sw = sinf(wts);
    const unsigned reading = hil_fw_fcs_reading(s);
    float ua;
    float ub;
    float ia1;
    float ib1;
    float pa1;
    float pb1;
    float dpsi;
    float dte;
    if (st->next_t_ns != me->t_ns) {
        /* (re)start after reset (next_t_ns = HIL_FW_DSVM_NO_STEP) or a gap in time: flux from the current
         * model at k, eq. (2) */
        hil_fw_park_inv(p[HIL_FW_P_LD] * me->i_d + p[HIL_FW_P_PSI_F], p[HIL_FW_P_LQ] * me->i_q, me->cos_th,
                        me->sin_th, &st->psi_a, &st->psi_b);
        st->h_psi = 1u;
        st->h_te = 1u;
    } else {
        st->psi_a += ts * (st->u_a_prev - rs * 0.5f * (st->i_a_prev + me->i_alpha));
        st->psi_b += ts * (st->u_b_prev - rs * 0.5f * (st->i_b_prev + me->i_beta));
    }
    st->next_t_ns = me->t_ns + s->params.model.ts_ns;
    hil_fw_dsvm_prepare(s);
    hil_fw_cmd_mean_voltage_ab(s->applied.states, s->applied.durations_ns, s->applied.n_states, me->vdc, &ua,
                               &ub);
    st->u_a_prev = ua;
    st->u_b_prev = ub;
    st->i_a_prev = me->i_alpha;
    st->i_b_prev = me->i_beta;
    if ((reading & HIL_FW_FCS_AT_K) != 0u) {
        /* estimates at k: psi(k) and the measured i(k) */
        pa1 = st->psi_a;
        pb1 = st->psi_b;
        ia1 = me->i_alpha;
        ib1 = me->i_beta;
    } else {
        /* i(k+1) in the stator frame at the angle theta + wts */
        hil_fw_park_inv(st->id1, st->iq1, me->cos_th * cw - me->sin_th * sw, me->sin_th * cw + me->cos_th * sw,
                        &ia1, &ib1);
        pa1 = st->psi_a + ts * (ua - rs * 0.5f * (me->i_alpha + ia1));
        pb1 = st->psi_b + ts * (ub - rs * 0.5f * (me->i_beta + ib1));
    }
    st->psi_mag1 = sqrtf(pa1 * pa1 + pb1 * pb1);
    st->te1 = s->params.model.torque_k * (pa1 * ib1 - pb1 * ia1); /* eq. (11) */
    if ((reading & HIL_FW_FCS_FLUX_PSI_F) != 0u) {
        st->psi_ref = p[HIL_FW_P_FLUX_REF] > 0.0f ? p[HIL_FW_P_FLUX_REF] : p[HIL_FW_P_PSI_F];
    } else {
        const float fd = p[HIL_FW_P_LD] * s->ref.i_d + p[HIL_FW_P_PSI_F];
        const float fq = p[HIL_FW_P_LQ] * s->ref.i_q;
        st->psi_ref = sqrtf(fd * fd + fq * fq); /* flux of the current references */
    }
    dpsi = st->psi_ref - st->psi_mag1;
    dte = s->ref.torque - st->te1;
    if ((reading & HIL_FW_FCS_TORQUE_INVERT) != 0u) {
        dte = -dte;
    }
    st->h_psi = compare(dpsi, 0.0f, st->h_psi);
    st->h_te = compare(dte, (reading & HIL_FW_FCS_TORQUE_BAND) != 0u ? p[HIL_FW_P_TORQUE_BAND] : 0.0f, st->h_te);
    st->sector = hil_fw_fcs_sector_rot(pa1, pb1, (uint8_t)(reading & HIL_FW_FCS_ROT_MASK));
}

/* The candidates of the next period: the n vectors of a row of a DSVM neighbourhood table. */
static void set_candidates(hil_fw_dsvm_state_t *st, const uint8_t *row, uint8_t n)
{
    uint8_t i;
    for (i = 0u; i < n; ++i) {
        st->cand[i] = row[i];
    }
    st->n_cand = n;
}

void hil_fw_fcs_mpc1_reference(struct hil_fw_state *s)
{
    hil_fw_dsvm_state_t *st = &s->ctrl.dsvm;
    dtc_state(s);
    st->ref_vector = hil_fw_fcs_lookup(HIL_FW_FCS_TABLE_VIRTUAL, st->h_psi, st->h_te, st->sector);
    set_candidates(st, hil_fw_dsvm_triangle[st->ref_vector - 7u], 6u);
}

void hil_fw_fcs_mpc2_reference(struct hil_fw_state *s)
{
    hil_fw_dsvm_state_t *st = &s->ctrl.dsvm;
    dtc_state(s);
    st->ref_vector = hil_fw_fcs_lookup(HIL_FW_FCS_TABLE_REAL, st->h_psi, st->h_te, st->sector);
    set_candidates(st, hil_fw_dsvm_kite[st->ref_vector - 1u], 5u);
}
