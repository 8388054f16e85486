/*
 * Reference firmware: model predictive torque control of a dual three-phase PMSM (Zhang et al. 2021):
 * mptc1 (12 G1 vectors + zero, weighted cost eq. (10)), mptc2 (12 virtual vectors V3 + zero, full
 * dual-vector model eq. (13), weighted cost) and mptc3 (6 V3 chosen by the system state of Table 1,
 * simplified model eqs. (15)-(16), cost J1 or J2 of Table 2). Param v3_symmetric sends each V3 of
 * mptc2/mptc3 as the symmetric G1/2 - G2 - G1/2 sequence (mirrored command). See docs/algorithms/mptc.md.
 */
#ifndef HIL_FW_MPTC_H
#define HIL_FW_MPTC_H

#include <stdint.h>

#include "hil_fw_types.h"

struct hil_fw_state;

#define HIL_FW_MPTC_FULL_CANDIDATES 13 /* 12 vectors + zero */
#define HIL_FW_MPTC3_CANDIDATES 6

/* mptc3 system states (Table 1). */
#define HIL_FW_MPTC_DYN_TO_STEADY 1
#define HIL_FW_MPTC_DYNAMIC 2
#define HIL_FW_MPTC_STEADY 3
#define HIL_FW_MPTC_STEADY_TO_DYN 4

typedef struct {
    float te1;      /* delay-compensated torque at k+1 [N*m] */
    float psi1;     /* delay-compensated stator flux magnitude at k+1 [Wb] */
    float i_d1;     /* delay-compensated currents at k+1 [A] */
    float i_q1;
    float te2;      /* predicted torque at k+2 of the chosen vector [N*m] */
    float psi2;     /* predicted flux magnitude at k+2 of the chosen vector [Wb] */
    float psi_ref;  /* flux reference used [Wb] */
    float cost;     /* cost of the chosen vector */
    uint8_t best;   /* 0: zero vector, j = 1..12: VV_j / G1_j */
    uint8_t sys_case;  /* mptc3: HIL_FW_MPTC_* of this step (0 for mptc1/2) */
    uint8_t flux_sector; /* mptc3: sector 1..12 of the flux at k+1 */
    uint8_t use_j1;      /* mptc3: 1 cost J1 (flux), 0 cost J2 (torque) */
} hil_fw_mptc_state_t;

/* Shared stage of the three controllers: delay compensation to k+1 and the references. */
typedef struct {
    float id1, iq1;   /* currents at k+1 [A] */
    float c2, s2;     /* cos/sin of the rotor angle at k+1 [-] */
    float wts;        /* electrical angle advanced per period [rad] */
    float te_ref;     /* torque reference [N*m] */
    float psi_ref;    /* flux magnitude reference [Wb] */
    float lambda;     /* weighting factor of eq. (10) [N*m/Wb] */
} hil_fw_mptc_ctx_t;

/* Field weakening (docs/algorithms/field_weakening.md, "mptc1..3"): the stator flux reference (the automatic one;
 * a user's flux_ref param is taken as given) is held to
 * what the voltage allows at the speed, psi_ref <= HIL_FW_MPTC_FW_MARGIN * (vdc / sqrt(3)) / |omega_e|: the
 * steady-state stator voltage of a machine whose resistive drop is negligible is |omega_e| * |psi_s|, and
 * vdc / sqrt(3) is the circle inside the V3 12-gon (0.598 vdc * cos 15 deg) the controllers can hold on average.
 * The margin leaves the predictive choice voltage to move the torque within a period. */
#define HIL_FW_MPTC_FW_MARGIN 0.9f

/* The flux reference psi_ref [Wb] capped by the voltage limit at DC link vdc [V] and electrical speed omega_e
 * [rad/s]; psi_ref itself (the same float) wherever the cap is not reached. */
float hil_fw_mptc_flux_cap(float psi_ref, float vdc, float omega_e);

void hil_fw_mptc_begin(struct hil_fw_state *s, hil_fw_mptc_ctx_t *c);

/* 1 if the measurement is six-phase; else writes a zero command with HIL_FW_STATUS_INVALID_CONFIG. */
int hil_fw_mptc_six_phase_ok(struct hil_fw_state *s, hil_fw_cmd_t *cmd);

/* Torque 3 p (psi_d i_q - psi_q i_d) [N*m] and flux (psi_d, psi_q) [Wb] of dq currents [A]. */
float hil_fw_mptc_torque(const struct hil_fw_state *s, float i_d, float i_q);

/* One forward-Euler step of length h [s] with rotor-frame voltage (vd, vq) [V] (eq. (8)). */
void hil_fw_mptc_euler(const struct hil_fw_state *s, float h, float vd, float vq, float *i_d, float *i_q);

/* 1 if param v3_symmetric is set: mptc2/mptc3 send a V3 as G1 for eta_G1 Ts/2, G2 for eta_G2 Ts with the
 * mirror flag (applied G1/2 - G2 - G1/2), else 0 (G1 for eta_G1 Ts, then G2). */
int hil_fw_mptc_v3_symmetric(const struct hil_fw_state *s);

/* Write the command: best 0 = zero vector, else vector index 1..12; v3 selects the G1+G2 pair (mirrored
 * when hil_fw_mptc_v3_symmetric). */
void hil_fw_mptc_emit(struct hil_fw_state *s, hil_fw_cmd_t *cmd, int best, int v3, uint8_t candidates);

/* Unit direction (cos, sin) of vector index j = 0..11 (angle 15 + 30 j degrees). */
extern const float hil_fw_mptc_dir_c[12];
extern const float hil_fw_mptc_dir_s[12];

/* mptc3 candidate offsets from the flux sector: J1 (parallel) and J2 (perpendicular) sets. */
extern const int8_t hil_fw_mptc3_set_j1[HIL_FW_MPTC3_CANDIDATES];
extern const int8_t hil_fw_mptc3_set_j2[HIL_FW_MPTC3_CANDIDATES];

/* mptc3 system state of Table 1 from the torque errors at the paper's k-1 and k and the band. */
uint8_t hil_fw_mptc3_case(float err_prev, float err_now, float band);

void hil_fw_mptc1_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd);
void hil_fw_mptc2_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd);
void hil_fw_mptc3_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd);

#endif
