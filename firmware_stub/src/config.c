/* Reference firmware: parameter defaults, physical-range checks, derived model coefficients. */
#include <math.h>

#include "hil_fw_config.h"
#include "hil_fw_fcs_mpc.h"
#include "hil_fw_types.h"

typedef struct {
    float lo;        /* lower bound */
    float hi;        /* upper bound (inclusive) */
    uint8_t lo_open; /* 1: value must be > lo, 0: >= lo */
    uint8_t integer; /* 1: value must be integral */
} param_rule_t;

/* Physical ranges; index = param id (0 unused, rejected). */
static const param_rule_t rules[HIL_FW_P_COUNT] = {
    [HIL_FW_P_RS] = {0.0f, 1.0e3f, 0, 0},
    [HIL_FW_P_LD] = {0.0f, 10.0f, 1, 0},
    [HIL_FW_P_LQ] = {0.0f, 10.0f, 1, 0},
    [HIL_FW_P_PSI_F] = {0.0f, 100.0f, 0, 0},
    [HIL_FW_P_POLE_PAIRS] = {1.0f, 64.0f, 0, 1},
    [HIL_FW_P_TS] = {1.0e-6f, 0.1f, 0, 0},
    [HIL_FW_P_VDC] = {0.0f, 1.0e5f, 1, 0},
    [HIL_FW_P_SPEED_KP] = {0.0f, 1.0e6f, 0, 0},
    [HIL_FW_P_SPEED_KI] = {0.0f, 1.0e6f, 0, 0},
    [HIL_FW_P_TORQUE_LIMIT] = {0.0f, 1.0e6f, 1, 0},
    [HIL_FW_P_TORQUE_INTEGRATOR_INIT] = {-1.0e6f, 1.0e6f, 0, 0},
    [HIL_FW_P_ID_REF] = {-1.0e6f, 1.0e6f, 0, 0},
    [HIL_FW_P_LAMBDA] = {0.0f, 1.0e6f, 0, 0},
    [HIL_FW_P_T_THR] = {0.0f, 0.1f, 0, 0},
    [HIL_FW_P_T_DEAD] = {0.0f, 1.0e-3f, 0, 0},
    [HIL_FW_P_T_MPW] = {0.0f, 1.0e-3f, 0, 0},
    [HIL_FW_P_FLUX_REF] = {0.0f, 100.0f, 0, 0},
    [HIL_FW_P_CURRENT_KP] = {0.0f, 1.0e6f, 0, 0},
    [HIL_FW_P_CURRENT_KI] = {0.0f, 1.0e9f, 0, 0},
    [HIL_FW_P_LLS] = {0.0f, 10.0f, 0, 0},
    [HIL_FW_P_TORQUE_BAND] = {0.0f, 1.0e6f, 0, 0},
    [HIL_FW_P_CURRENT_LIMIT] = {0.0f, 1.0e6f, 1, 0},
    [HIL_FW_P_ZERO_SELECT] = {0.0f, 1.0f, 0, 1},
    [HIL_FW_P_DT_COMP] = {0.0f, 1.0f, 0, 1},
    [HIL_FW_P_FCS_READING] = {0.0f, 255.0f, 0, 1},
    [HIL_FW_P_V3_SYMMETRIC] = {0.0f, 1.0f, 0, 1},
    [HIL_FW_P_RR] = {0.0f, 1.0e3f, 1, 0},
    [HIL_FW_P_LSIGMA] = {0.0f, 10.0f, 1, 0},
    [HIL_FW_P_LM] = {0.0f, 10.0f, 1, 0},
    [HIL_FW_P_PSI_R_REF] = {0.0f, 100.0f, 1, 0},
    [HIL_FW_P_PWM_DUTIES] = {0.0f, 1.0f, 0, 1},
};

void hil_fw_params_defaults(hil_fw_params_t *p)
{
    int i;
    for (i = 0; i < HIL_FW_P_COUNT; ++i) {
        p->value[i] = 0.0f;
    }
    /* Table 3 of the paper (1.1 kW, 1500 rpm, 7 N*m). */
    p->value[HIL_FW_P_RS] = 4.5f;
    p->value[HIL_FW_P_LD] = 0.012f;
    p->value[HIL_FW_P_LQ] = 0.014f;
    p->value[HIL_FW_P_PSI_F] = 0.21f;
    p->value[HIL_FW_P_POLE_PAIRS] = 3.0f;
    p->value[HIL_FW_P_TS] = 100.0e-6f; /* 10 kHz sampling */
    p->value[HIL_FW_P_VDC] = 300.0f;   /* not in the paper; covers rated point with margin */
    p->value[HIL_FW_P_SPEED_KP] = 0.8f;
    p->value[HIL_FW_P_SPEED_KI] = 0.35f;
    p->value[HIL_FW_P_TORQUE_LIMIT] = 10.5f;  /* 1.5 x rated torque */
    p->value[HIL_FW_P_TORQUE_INTEGRATOR_INIT] = 0.0f;
    p->value[HIL_FW_P_ID_REF] = 0.0f;
    p->value[HIL_FW_P_LAMBDA] = 0.0f;
    p->value[HIL_FW_P_T_THR] = 0.0f;
    p->value[HIL_FW_P_T_DEAD] = 0.0f;
    p->value[HIL_FW_P_T_MPW] = 0.0f;
    p->value[HIL_FW_P_FLUX_REF] = 0.0f; /* 0: from the id = 0 operating point of the torque reference */
    p->value[HIL_FW_P_CURRENT_KP] = 87.96f;    /* 2*pi*1 kHz * Lq */
    p->value[HIL_FW_P_CURRENT_KI] = 28274.3f;  /* 2*pi*1 kHz * Rs */
    p->value[HIL_FW_P_LLS] = 0.0f;
    p->value[HIL_FW_P_TORQUE_BAND] = 0.2f;
    p->value[HIL_FW_P_CURRENT_LIMIT] = 15.0f;
    /* each fcs controller's own reading, resolved per step (hil_fw_fcs_mpc.h) */
    p->value[HIL_FW_P_FCS_READING] = (float)HIL_FW_FCS_READING_CONTROLLER_DEFAULT;
    /* im-foc's machine: the 2.2-kW induction motor of motulator's examples (preset im-2k2) */
    p->value[HIL_FW_P_RR] = 2.1f;
    p->value[HIL_FW_P_LSIGMA] = 0.021f;
    p->value[HIL_FW_P_LM] = 0.224f;
    p->value[HIL_FW_P_PSI_R_REF] = 0.9f;
    p->value[HIL_FW_P_PWM_DUTIES] = 1.0f; /* foc ends in three duty cycles (0: the 5-segment states) */
    hil_fw_params_derive(p);
}

int hil_fw_param_check(uint8_t param_id, float value)
{
    const param_rule_t *r;
    if (param_id == 0u || param_id >= HIL_FW_P_COUNT) {
        return HIL_FW_E_PARAM_ID;
    }
    r = &rules[param_id];
    if (!isfinite(value) || value > r->hi) {
        return HIL_FW_E_PARAM_VALUE;
    }
    if (r->lo_open ? !(value > r->lo) : !(value >= r->lo)) {
        return HIL_FW_E_PARAM_VALUE;
    }
    if (r->integer && floorf(value) != value) {
        return HIL_FW_E_PARAM_VALUE;
    }
    if (param_id == HIL_FW_P_FCS_READING && ((unsigned)value & 15u) > 11u) {
        return HIL_FW_E_PARAM_VALUE; /* sector rotation field 0..11 */
    }
    return HIL_FW_OK;
}

void hil_fw_params_derive(hil_fw_params_t *p)
{
    hil_fw_model_t *m = &p->model;
    const float rs = p->value[HIL_FW_P_RS];
    const float ld = p->value[HIL_FW_P_LD];
    const float lq = p->value[HIL_FW_P_LQ];
    const float ts = p->value[HIL_FW_P_TS];
    m->ts = ts;
    m->ts_ns = (uint32_t)lroundf(ts * 1.0e9f);
    m->ad = 1.0f - rs * ts / ld;
    m->aq = 1.0f - rs * ts / lq;
    m->kd = ts / ld;
    m->kq = ts / lq;
    m->lq_ld = lq / ld;
    m->ld_lq = ld / lq;
    m->psi_lq = p->value[HIL_FW_P_PSI_F] / lq;
    m->torque_k = 1.5f * p->value[HIL_FW_P_POLE_PAIRS];
}
