/* Reference firmware: DBCC-based MPC, reference voltage of eq. (6) and its lattice triangle. */
#include <math.h>

#include "hil_fw_dbcc_mpc.h"
#include "hil_fw_dsvm.h"
#include "hil_fw_state.h"

#define SIN60 0.86602540378f

uint8_t hil_fw_dbcc_triangle(float m, float n, uint8_t out[3])
{
    const float h = 0.5f * (fabsf(m) + fabsf(n) + fabsf(m + n)); /* hexagon norm, 2 on the edge */
    float m0;
    float n0;
    int im;
    int in;
    if (!isfinite(h)) {
        m = 0.0f; /* no usable reference: the zero vector's triangle */
        n = 0.0f;
    } else if (h >= 1.9999f) {
        const float k = 1.9998f / h; /* strictly inside: indices stay in 0..4 */
        m *= k;
        n *= k;
    }
    m0 = floorf(m);
    n0 = floorf(n);
    im = (int)m0 + 2;
    in = (int)n0 + 2;
    if ((m - m0) + (n - n0) < 1.0f) {
        out[0] = hil_fw_dsvm_lattice_index[im][in];
        out[1] = hil_fw_dsvm_lattice_index[im + 1][in];
        out[2] = hil_fw_dsvm_lattice_index[im][in + 1];
    } else {
        out[0] = hil_fw_dsvm_lattice_index[im + 1][in + 1];
        out[1] = hil_fw_dsvm_lattice_index[im + 1][in];
        out[2] = hil_fw_dsvm_lattice_index[im][in + 1];
    }
    return HIL_FW_DBCC_CANDIDATES;
}

void hil_fw_dbcc_reference(struct hil_fw_state *s)
{
    hil_fw_dsvm_state_t *st = &s->ctrl.dsvm;
    const float *p = s->params.value;
    const float we = s->meas.omega_e;
    const float ts = s->params.model.ts;
    const float e = s->meas.vdc * (1.0f / 3.0f);
    float vd;
    float vq;
    float va;
    float vb;
    uint8_t i;
    hil_fw_dsvm_prepare(s);
    /* eq. (6) with e_d = -we Lq iq, e_q = we (Ld id + psi_f) */
    vd = p[HIL_FW_P_RS] * st->id1 + p[HIL_FW_P_LD] / ts * (s->ref.i_d - st->id1) - we * p[HIL_FW_P_LQ] * st->iq1;
    vq = p[HIL_FW_P_RS] * st->iq1 + p[HIL_FW_P_LQ] / ts * (s->ref.i_q - st->iq1) +
         we * (p[HIL_FW_P_LD] * st->id1 + p[HIL_FW_P_PSI_F]);
    va = vd * st->c2 - vq * st->s2;
    vb = vd * st->s2 + vq * st->c2;
    st->v_ref_n = vb / (e * SIN60);
    st->v_ref_m = va / e - 0.5f * st->v_ref_n;
    st->n_cand = hil_fw_dbcc_triangle(st->v_ref_m, st->v_ref_n, st->cand);
    for (i = 0u; i < st->n_cand; ++i) {
        if (st->cand[i] >= HIL_FW_DSVM_VECTORS) {
            st->cand[i] = 0u; /* cannot happen after clamping; keep the list valid */
        }
    }
    st->ref_vector = st->cand[0];
}
