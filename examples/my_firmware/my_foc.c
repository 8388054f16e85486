/*
 * A user's firmware (template): field-oriented control of a three-phase PMSM written against the HIL
 * firmware API only (hil_app.h) -- its own speed PI, its own d/q current PI loops with decoupling, and
 * space-vector modulation ending, as drive firmware does, in three duty cycles of a centre-aligned PWM
 * (cmd->n_duties = 3, cmd->duty[0..2]): the plant applies the exact 7 segments 0-x-xy-7-xy-x-0.
 *
 * Runs as controller 255 `external` (`hil run --controller external --target sil:... | qemu:...`);
 * any other controller id is answered with HIL_APP_E_NOT_IMPLEMENTED (FaultTarget not_implemented).
 */
#include <math.h>
#include <stdint.h>

#include "hil_app.h"

#define P_RS 1
#define P_LD 2
#define P_LQ 3
#define P_PSI_F 4
#define P_POLE_PAIRS 5
#define P_TS 6
#define P_VDC 7
#define P_SPEED_KP 8
#define P_SPEED_KI 9
#define P_TORQUE_LIMIT 10
#define P_TORQUE_INIT 11
#define P_CURRENT_KP 18
#define P_CURRENT_KI 19
#define P_CURRENT_LIMIT 22
#define N_PARAMS 27

#define CONTROLLER_EXTERNAL 255u
#define SQRT3 1.7320508f
#define TWO_PI 6.2831853f
#define BANDWIDTH_RAD_S 1500.0f /* current-loop bandwidth when current_kp/ki are not given */

typedef struct {
    float integ;
    float out;
} pi_t;

static struct {
    float p[N_PARAMS];
    uint8_t controller;
    uint8_t enable;
    uint8_t mode;
    float reference;
    pi_t speed;
    pi_t id_loop;
    pi_t iq_loop;
} fw;

static float clampf(float x, float lim)
{
    return x > lim ? lim : (x < -lim ? -lim : x);
}

/* Parallel PI, forward rectangle, clamping anti-windup: out = kp*e + integ, |out| <= lim. */
static float pi_step(pi_t *c, float e, float kp, float ki, float dt, float lim)
{
    const float next = c->integ + ki * e * dt;
    const float out = kp * e + next;
    if (out > lim || out < -lim) {
        c->out = clampf(out, lim);
        /* integrate only while it does not push further into the limit */
        if ((out > lim && e < 0.0f) || (out < -lim && e > 0.0f)) {
            c->integ = next;
        }
    } else {
        c->integ = next;
        c->out = out;
    }
    return c->out;
}

void hil_app_init(void)
{
    int i;
    for (i = 0; i < N_PARAMS; ++i) {
        fw.p[i] = 0.0f;
    }
    fw.p[P_RS] = 1.0f;
    fw.p[P_LD] = 0.01f;
    fw.p[P_LQ] = 0.01f;
    fw.p[P_PSI_F] = 0.1f;
    fw.p[P_POLE_PAIRS] = 1.0f;
    fw.p[P_TS] = 1.0e-4f;
    fw.p[P_VDC] = 300.0f;
    fw.p[P_TORQUE_LIMIT] = 10.0f;
    fw.p[P_CURRENT_LIMIT] = 10.0f;
    fw.controller = 0u;
    fw.enable = 0u;
    fw.mode = 0u;
    fw.reference = 0.0f;
}

int hil_app_config(uint8_t param_id, float value)
{
    if (!isfinite(value)) {
        return HIL_APP_E_PARAM;
    }
    if (param_id >= N_PARAMS) {
        return HIL_APP_OK; /* not used by this firmware: acknowledged */
    }
    if ((param_id == P_LD || param_id == P_LQ || param_id == P_PSI_F || param_id == P_POLE_PAIRS ||
         param_id == P_TS || param_id == P_VDC) && value <= 0.0f) {
        return HIL_APP_E_PARAM;
    }
    fw.p[param_id] = value;
    return HIL_APP_OK;
}

int hil_app_select(uint8_t controller_id)
{
    if (controller_id != CONTROLLER_EXTERNAL && controller_id != 0u) {
        return HIL_APP_E_NOT_IMPLEMENTED;
    }
    fw.controller = controller_id;
    return HIL_APP_OK;
}

void hil_app_reset(void)
{
    fw.speed.integ = fw.p[P_TORQUE_INIT];
    fw.speed.out = 0.0f;
    fw.id_loop.integ = 0.0f;
    fw.id_loop.out = 0.0f;
    fw.iq_loop.integ = 0.0f;
    fw.iq_loop.out = 0.0f;
}

int hil_app_setpoint(uint8_t enable, uint8_t mode, float reference)
{
    if (mode > 1u) {
        return HIL_APP_E_SETPOINT;
    }
    if (!isfinite(reference)) {
        return HIL_APP_E_SETPOINT;
    }
    fw.enable = enable;
    fw.mode = mode;
    fw.reference = reference;
    return HIL_APP_OK;
}

static void zero_command(hil_app_cmd_t *cmd, uint32_t ts_ns, uint8_t status)
{
    cmd->n_states = 1u;
    cmd->states[0] = 0u;
    cmd->durations_ns[0] = ts_ns;
    cmd->status = status;
}

/* Space-vector PWM of (v_alpha, v_beta) [V] as three duty cycles of a centre-aligned PWM (what a timer's compare
 * registers take): min-max zero-sequence injection; beyond the linear range (|v| > vdc/sqrt(3)) the voltage is
 * scaled back. The plant compares the duties with its carrier (docs/firmware_api.md, "Duty-cycle commands"). */
static void modulate(float va, float vb, float vdc, hil_app_cmd_t *cmd)
{
    const float mag = sqrtf(va * va + vb * vb);
    const float vmax = vdc / SQRT3; /* linear range */
    const float k = mag > vmax ? vmax / mag : 1.0f;
    const float v[3] = {k * va, k * (-0.5f * va + 0.5f * SQRT3 * vb), k * (-0.5f * va - 0.5f * SQRT3 * vb)};
    const float hi = fmaxf(v[0], fmaxf(v[1], v[2]));
    const float lo = fminf(v[0], fminf(v[1], v[2]));
    int j;
    cmd->n_duties = 3u;
    for (j = 0; j < 3; ++j) {
        const float d = 0.5f + (v[j] - 0.5f * (hi + lo)) / vdc;
        cmd->duty[j] = d < 0.0f ? 0.0f : (d > 1.0f ? 1.0f : d); /* float rounding at the hexagon's edge */
    }
}

void hil_app_step(const hil_app_meas_t *m, hil_app_cmd_t *cmd)
{
    const float *p = fw.p;
    const float ts = p[P_TS];
    const uint32_t ts_ns = (uint32_t)(ts * 1.0e9f + 0.5f);
    const float pp = p[P_POLE_PAIRS];
    const float vdc = m->vdc > 0.0f ? m->vdc : p[P_VDC];
    const float ilim = p[P_CURRENT_LIMIT];
    const float vlim = vdc / SQRT3;
    float torque;
    float i_alpha;
    float i_beta;
    float c;
    float s;
    float id;
    float iq;
    float iq_ref;
    float we;
    float vd;
    float vq;
    float th;
    float kp_d = p[P_CURRENT_KP] > 0.0f ? p[P_CURRENT_KP] : BANDWIDTH_RAD_S * p[P_LD];
    float kp_q = p[P_CURRENT_KP] > 0.0f ? p[P_CURRENT_KP] : BANDWIDTH_RAD_S * p[P_LQ];
    float ki = p[P_CURRENT_KI] > 0.0f ? p[P_CURRENT_KI] : BANDWIDTH_RAD_S * p[P_RS];
    if (m->n_phases != 3u || fw.controller != CONTROLLER_EXTERNAL) {
        zero_command(cmd, ts_ns, m->n_phases != 3u ? 5u : 0u);
        return;
    }
    /* outer loop: torque reference, then i_q (i_d = 0) */
    if (fw.mode == 0u) {
        torque = pi_step(&fw.speed, fw.reference - m->omega_m, p[P_SPEED_KP], p[P_SPEED_KI], ts,
                         p[P_TORQUE_LIMIT]);
    } else {
        torque = clampf(fw.reference, p[P_TORQUE_LIMIT]);
    }
    iq_ref = clampf(torque / (1.5f * pp * p[P_PSI_F]), ilim);
    /* Clarke (amplitude invariant) and Park */
    i_alpha = (2.0f * m->i[0] - m->i[1] - m->i[2]) / 3.0f;
    i_beta = (m->i[1] - m->i[2]) / SQRT3;
    c = cosf(m->theta_e);
    s = sinf(m->theta_e);
    id = i_alpha * c + i_beta * s;
    iq = -i_alpha * s + i_beta * c;
    /* current loops with decoupling feed-forward */
    we = pp * m->omega_m;
    vd = pi_step(&fw.id_loop, 0.0f - id, kp_d, ki, ts, vlim) - we * p[P_LQ] * iq;
    vq = pi_step(&fw.iq_loop, iq_ref - iq, kp_q, ki, ts, vlim) + we * (p[P_LD] * id + p[P_PSI_F]);
    /* the command is applied one period later, for one period: rotate to the middle of that period */
    th = m->theta_e + 1.5f * we * ts;
    c = cosf(th);
    s = sinf(th);
    modulate(vd * c - vq * s, vd * s + vq * c, vdc, cmd);
    cmd->torque_ref = torque;
    cmd->iq_ref = iq_ref;
    cmd->id_ref = 0.0f;
}
