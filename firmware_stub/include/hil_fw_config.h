/*
 * Reference firmware: configuration parameters (ids HIL_FW_P_* with units in the generated hil_ids.h,
 * SI units) and the discrete model coefficients derived from them.
 */
#ifndef HIL_FW_CONFIG_H
#define HIL_FW_CONFIG_H

#include <stdint.h>

#include "hil_ids.h"

/* Forward-Euler dq model coefficients, recomputed whenever a parameter changes. */
typedef struct {
    uint32_t ts_ns;  /* control period [ns] */
    float ts;        /* control period [s] */
    float ad;        /* 1 - Rs*Ts/Ld */
    float aq;        /* 1 - Rs*Ts/Lq */
    float kd;        /* Ts/Ld [A/V] */
    float kq;        /* Ts/Lq [A/V] */
    float lq_ld;     /* Lq/Ld */
    float ld_lq;     /* Ld/Lq */
    float psi_lq;    /* psi_f/Lq [A*s/rad] */
    float torque_k;  /* 1.5 * pole pairs */
} hil_fw_model_t;

typedef struct {
    float value[HIL_FW_P_COUNT]; /* indexed by HIL_FW_P_* */
    hil_fw_model_t model;
} hil_fw_params_t;

/* Load defaults (Table 3 machine, Ts = 100 us, Vdc = 300 V, kp 0.8, ki 0.35). */
void hil_fw_params_defaults(hil_fw_params_t *p);

/* Check a value against the physical range of param_id: 0 ok, HIL_FW_E_PARAM_ID/VALUE. */
int hil_fw_param_check(uint8_t param_id, float value);

/* Recompute the model coefficients from the values. */
void hil_fw_params_derive(hil_fw_params_t *p);

#endif
