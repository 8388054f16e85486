/* Reference firmware: FOC with dq PI current loops and center-aligned SVPWM in three slots. */
#include <math.h>

#include "hil_fw_foc.h"
#include "hil_fw_inverter.h"
#include "hil_fw_state.h"
#include "hil_fw_transforms.h"

/* Field weakening (docs/algorithms/field_weakening.md): the share of the linear SVPWM reach vdc / sqrt(3) the
 * voltage demand is held to (the rest is the current loop's room for transients), the crossover of the
 * voltage-feedback loop [rad/s] (a tenth of the default current loop's 2 pi 1 kHz: the two loops stay apart) and
 * the electrical speed below which its gain is not raised further [rad/s]. */
#define FOC_FW_MARGIN 0.95f
#define FOC_FW_CROSSOVER 600.0f
#define FOC_FW_OMEGA_FLOOR 50.0f
/* MTPA: fixed-point iterations of iq = T / (tk (psi_f + (ld - lq) id)), id = mtpa(iq) (the reluctance share of
 * the torque is small: each iteration gains more than a decade at the bundled machines' ratings). */
#define FOC_MTPA_ITERATIONS 3

static float clampf(float x, float lim)
{
    return x > lim ? lim : (x < -lim ? -lim : x);
}

uint8_t hil_fw_svpwm(float u_alpha, float u_beta, float vdc, uint32_t ts_ns, uint8_t *a, uint8_t *b,
                     uint32_t times_ns[3])
{
    /* dwell fractions of Vj (angle (j-1)*60 deg) and V(j+1) in sector j */
    const float ang = atan2f(u_beta, u_alpha);
    const float mag = sqrtf(u_alpha * u_alpha + u_beta * u_beta);
    float pos = isfinite(ang) ? (ang < 0.0f ? ang + 2.0f * HIL_FW_PI_F : ang) : 0.0f; /* NaN: never cast */
    int k = (int)(pos * (3.0f / HIL_FW_PI_F));
    float phi;
    float f1;
    float f2;
    float sum;
    uint32_t t1;
    uint32_t t2;
    if (k > 5) {
        k = 5;
    }
    if (k < 0) {
        k = 0;
    }
    phi = pos - (float)k * (HIL_FW_PI_F / 3.0f);
    f1 = HIL_FW_SQRT3_F * mag / vdc * sinf(HIL_FW_PI_F / 3.0f - phi);
    f2 = HIL_FW_SQRT3_F * mag / vdc * sinf(phi);
    f1 = f1 > 0.0f ? f1 : 0.0f;
    f2 = f2 > 0.0f ? f2 : 0.0f;
    sum = f1 + f2;
    if (!(sum <= 1.0e30f)) { /* an infinite or NaN reference: no duty, never a NaN cast */
        f1 = 0.0f;
        f2 = 0.0f;
    } else if (sum > 1.0f) {
        f1 /= sum;
        f2 /= sum;
    }
    t1 = (uint32_t)(f1 * (float)ts_ns + 0.5f);
    t2 = (uint32_t)(f2 * (float)ts_ns + 0.5f);
    if (t1 + t2 > ts_ns) {
        t2 = ts_ns - t1;
    }
    /* sector k+1 lies between V(k+1) and V(k+2); the odd-index vector has one upper switch on */
    if ((k & 1) == 0) {
        *a = hil_fw_vector_state[k + 1];
        *b = hil_fw_vector_state[k + 2];
        times_ns[0] = t1;
        times_ns[1] = t2;
    } else {
        *a = hil_fw_vector_state[k + 2 > 6 ? 1 : k + 2];
        *b = hil_fw_vector_state[k + 1];
        times_ns[0] = t2;
        times_ns[1] = t1;
    }
    times_ns[2] = ts_ns - times_ns[0] - times_ns[1];
    return (uint8_t)(k + 1);
}

void hil_fw_svpwm_duties(float u_alpha, float u_beta, float vdc, float duty[3])
{
    const float va = u_alpha;
    const float vb = -0.5f * u_alpha + 0.5f * HIL_FW_SQRT3_F * u_beta;
    const float vc = -0.5f * u_alpha - 0.5f * HIL_FW_SQRT3_F * u_beta;
    const float hi = fmaxf(va, fmaxf(vb, vc));
    const float lo = fminf(va, fminf(vb, vc));
    const float mid = 0.5f * (hi + lo);
    float span = (hi - lo) / vdc; /* line-to-line peak over vdc: > 1 outside the hexagon */
    float k = 1.0f;
    uint8_t j;
    if (!(span <= 1.0e30f) || !(vdc > 0.0f)) { /* NaN or infinite voltage, no DC link: zero voltage */
        duty[0] = duty[1] = duty[2] = 0.5f;
        return;
    }
    if (span > 1.0f) {
        k = 1.0f / span;
    }
    duty[0] = 0.5f + k * (va - mid) / vdc;
    duty[1] = 0.5f + k * (vb - mid) / vdc;
    duty[2] = 0.5f + k * (vc - mid) / vdc;
    for (j = 0u; j < 3u; ++j) { /* float rounding at the hexagon's edge */
        duty[j] = duty[j] < 0.0f ? 0.0f : (duty[j] > 1.0f ? 1.0f : duty[j]);
    }
}

float hil_fw_mtpa_id(float ld, float lq, float psi_f, float i_q)
{
    const float dl = lq - ld;
    if (!(dl > 0.0f)) {
        return 0.0f;
    }
    return -dl * i_q * i_q / (0.5f * psi_f + sqrtf(0.25f * psi_f * psi_f + dl * dl * i_q * i_q));
}

void hil_fw_foc_reference(struct hil_fw_state *s)
{
    hil_fw_foc_state_t *st = &s->ctrl.foc;
    const hil_fw_measured_t *me = &s->meas;
    const float *p = s->params.value;
    const float ld = p[HIL_FW_P_LD];
    const float lq = p[HIL_FW_P_LQ];
    const float psi_f = p[HIL_FW_P_PSI_F];
    const float imax = p[HIL_FW_P_CURRENT_LIMIT];
    const float tk = s->params.model.torque_k;
    const float torque = s->ref.torque;
    const float w_abs = fabsf(me->omega_e);
    const float gain = FOC_FW_CROSSOVER / ((w_abs > FOC_FW_OMEGA_FLOOR ? w_abs : FOC_FW_OMEGA_FLOOR) * ld);
    /* the lowest d current: the current limit, and -psi_f / ld, where the d flux changes sign and more negative
     * id no longer lowers the voltage */
    const float id_low = -(ld > 0.0f && psi_f / ld < imax ? psi_f / ld : imax);
    float id = 0.0f;
    float den;
    int k;
    if (st->next_t_ns != me->t_ns) { /* a gap in time: no field weakening carried over */
        st->id_fw = 0.0f;
        st->v_dem = 0.0f;
    }
    for (k = 0; k < FOC_MTPA_ITERATIONS; ++k) {
        den = tk * (psi_f + (ld - lq) * id);
        id = hil_fw_mtpa_id(ld, lq, psi_f, fabsf(den) > 1.0e-9f ? torque / den : 0.0f);
    }
    id += p[HIL_FW_P_ID_REF];
    /* voltage-limit feedback: d(id_fw)/dt = gain (FOC_FW_MARGIN vdc / sqrt(3) - |v_dq|), id_fw in [id_low - id, 0] */
    st->id_fw += gain * s->params.model.ts * (FOC_FW_MARGIN * me->vdc / HIL_FW_SQRT3_F - st->v_dem);
    if (st->id_fw > 0.0f) {
        st->id_fw = 0.0f;
    }
    if (st->id_fw < id_low - id) {
        st->id_fw = id_low - id < 0.0f ? id_low - id : 0.0f;
    }
    id = clampf(id + st->id_fw, imax);
    den = tk * (psi_f + (ld - lq) * id);
    s->ref.i_d = id;
    s->ref.i_q = fabsf(den) > 1.0e-9f ? clampf(torque / den, sqrtf(imax * imax - id * id)) : 0.0f;
}

void hil_fw_foc_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd)
{
    hil_fw_foc_state_t *st = &s->ctrl.foc;
    const hil_fw_measured_t *me = &s->meas;
    const float *p = s->params.value;
    const float ts = s->params.model.ts;
    const float kp = p[HIL_FW_P_CURRENT_KP];
    const float ki = p[HIL_FW_P_CURRENT_KI];
    const float we = me->omega_e;
    const float vmax = me->vdc / HIL_FW_SQRT3_F; /* linear range of SVPWM */
    const float ed = s->ref.i_d - me->i_d;
    const float eq = s->ref.i_q - me->i_q;
    const float ff_d = -we * p[HIL_FW_P_LQ] * me->i_q;
    const float ff_q = we * (p[HIL_FW_P_LD] * me->i_d + p[HIL_FW_P_PSI_F]);
    const float th = 1.5f * we * ts; /* middle of [k+1, k+2) */
    const float c = cosf(th);
    const float sn = sinf(th);
    float vd;
    float vq;
    float mag;
    float ua;
    float ub;
    if (st->next_t_ns != me->t_ns) {
        /* a gap in time: restart the pattern and the integrators (all zero after reset already) */
        st->parity = 0u;
        st->x_d = 0.0f;
        st->x_q = 0.0f;
    }
    st->next_t_ns = me->t_ns + s->params.model.ts_ns;
    vd = kp * ed + st->x_d + ff_d;
    vq = kp * eq + st->x_q + ff_q;
    mag = sqrtf(vd * vd + vq * vq);
    /* the field-weakening feedback: the whole demand (in saturation the integrators stop, only the proportional part
     * still says how far beyond the limit the currents' errors ask to go) */
    st->v_dem = mag;
    if (mag > vmax) {
        const float k = vmax / mag;
        vd *= k;
        vq *= k;
    } else {
        st->x_d += ki * ts * ed; /* conditional integration: no wind-up in saturation */
        st->x_q += ki * ts * eq;
    }
    st->v_d = vd;
    st->v_q = vq;
    hil_fw_park_inv(vd, vq, me->cos_th * c - me->sin_th * sn, me->sin_th * c + me->cos_th * sn, &ua, &ub);
    if (p[HIL_FW_P_PWM_DUTIES] >= 0.5f) { /* three duty cycles of a centre-aligned PWM (the default) */
        uint8_t a;
        uint8_t b;
        uint32_t t[3];
        uint8_t i;
        st->sector = hil_fw_svpwm(ua, ub, me->vdc, s->params.model.ts_ns, &a, &b, t);
        hil_fw_svpwm_duties(ua, ub, me->vdc, cmd->duty);
        cmd->n_duties = 3u;
        cmd->n_states = 0u;
        for (i = 0u; i < 3u; ++i) {
            cmd->states[i] = 0u;
            cmd->durations_ns[i] = 0u;
        }
        cmd->vector_id = st->sector;
        cmd->candidates = 0u;
        cmd->status = HIL_FW_STATUS_OK;
        return;
    }
    st->sector = hil_fw_foc_modulate(ua, ub, me->vdc, s->params.model.ts_ns, &st->parity, cmd);
}

uint8_t hil_fw_foc_modulate(float u_alpha, float u_beta, float vdc, uint32_t ts_ns, uint8_t *parity,
                            hil_fw_cmd_t *cmd)
{
    uint8_t a;
    uint8_t b;
    uint32_t t[3];
    uint8_t states[3];
    uint32_t durs[3];
    uint8_t i;
    uint8_t n = 0u;
    const uint8_t sector = hil_fw_svpwm(u_alpha, u_beta, vdc, ts_ns, &a, &b, t);
    const uint8_t odd = (*parity != 0u) ? 1u : 0u; /* the even half a, b, 7; the odd half its mirror b, a, 0 */
    states[0] = odd ? b : a;
    states[1] = odd ? a : b;
    states[2] = odd ? 0u : 7u;
    durs[0] = t[odd];
    durs[1] = t[1u - odd];
    durs[2] = t[2];
    *parity ^= 1u;
    for (i = 0u; i < 3u; ++i) { /* drop empty slots */
        if (durs[i] > 0u) {
            cmd->states[n] = states[i];
            cmd->durations_ns[n] = durs[i];
            ++n;
        }
    }
    for (i = n; i < 3u; ++i) {
        cmd->states[i] = 0u;
        cmd->durations_ns[i] = 0u;
    }
    cmd->n_states = n;
    cmd->vector_id = sector;
    cmd->candidates = 0u;
    cmd->status = HIL_FW_STATUS_OK;
    return sector;
}
