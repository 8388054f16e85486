/*
 * Reference firmware: configuration parameters (ids from docs/architecture.md, SI units)
 * and the discrete model coefficients derived from them.
 */
#ifndef HIL_FW_CONFIG_H
#define HIL_FW_CONFIG_H

#include <stdint.h>

#define HIL_FW_P_RS 1                     /* stator resistance [Ohm] */
#define HIL_FW_P_LD 2                     /* d-axis inductance [H] */
#define HIL_FW_P_LQ 3                     /* q-axis inductance [H] */
#define HIL_FW_P_PSI_F 4                  /* magnet flux linkage [Wb] */
#define HIL_FW_P_POLE_PAIRS 5             /* pole pairs (integer) */
#define HIL_FW_P_TS 6                     /* control period [s] */
#define HIL_FW_P_VDC 7                    /* nominal DC-link voltage [V] */
#define HIL_FW_P_SPEED_KP 8               /* speed PI proportional gain [N*m/(rad/s)] */
#define HIL_FW_P_SPEED_KI 9               /* speed PI integral gain [N*m/rad] */
#define HIL_FW_P_TORQUE_LIMIT 10          /* torque reference limit [N*m] */
#define HIL_FW_P_TORQUE_INTEGRATOR_INIT 11 /* speed PI integrator preset at enable [N*m] */
#define HIL_FW_P_ID_REF 12                /* d-axis current reference [A] */
#define HIL_FW_P_LAMBDA 13                /* cost weighting factor [-] */
#define HIL_FW_P_T_THR 14                 /* threshold time [s] */
#define HIL_FW_P_T_DEAD 15                /* inverter dead time [s] */
#define HIL_FW_P_T_MPW 16                 /* minimum pulse width [s] */
#define HIL_FW_P_FLUX_REF 17              /* stator flux reference [Wb] */
#define HIL_FW_P_CURRENT_KP 18            /* current PI proportional gain [V/A] */
#define HIL_FW_P_CURRENT_KI 19            /* current PI integral gain [V/(A*s)] */
#define HIL_FW_P_LLS 20                   /* leakage inductance [H] */
#define HIL_FW_P_TORQUE_BAND 21           /* torque hysteresis band [N*m] */
#define HIL_FW_P_CURRENT_LIMIT 22         /* current magnitude limit [A] */
#define HIL_FW_P_ZERO_SELECT 23           /* zero-vector rule of 3vmpc/hv-mpfc: 0 paper, 1 min_transitions */
#define HIL_FW_P_DT_COMP 24               /* pulse-based dead-time compensation in 3vmpc/hv-mpfc: 0 off, 1 on */
#define HIL_FW_P_FCS_READING 25           /* fcs-mpc-1/2 reading of Tables 1/2, bit flags (hil_fw_fcs_mpc.h) */
#define HIL_FW_P_V3_SYMMETRIC 26          /* mptc2/mptc3 V3 as G1/2-G2-G1/2 (mirrored command): 0 off, 1 on */
#define HIL_FW_P_COUNT 27                 /* array size (index 0 unused) */

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
