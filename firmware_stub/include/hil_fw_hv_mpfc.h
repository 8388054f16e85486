/*
 * Reference firmware: hybrid-vector model predictive flux control (hv-mpfc) of
 * 003_7bbad73a6f78337e.txt and the flux-deadbeat machinery it shares with 3vmpc:
 * flux prediction eq. (6) with two-step delay compensation, the sector of the stator flux error
 * vector and its vector pair (Table 1), dwell times eq. (9), the five modes of Section 3.2 against
 * t_thr with eqs. (10)/(11), the symmetric sequence and optional pulse-based dead-time compensation.
 * See docs/algorithms/hv_mpfc.md.
 */
#ifndef HIL_FW_HV_MPFC_H
#define HIL_FW_HV_MPFC_H

#include <stdint.h>

#include "hil_fw_types.h"
#include "hil_fw_vseq.h"

struct hil_fw_state;

/* Modes of Section 3.2 (1: three vectors, 2: u_opt1 + zero, 3: u_opt1 + u_opt2, 4: u_opt1 alone,
 * 5: zero alone). */
#define HIL_FW_HV_MODE_THREE 1u
#define HIL_FW_HV_MODE_ACTIVE_ZERO 2u
#define HIL_FW_HV_MODE_TWO_ACTIVE 3u
#define HIL_FW_HV_MODE_ACTIVE 4u
#define HIL_FW_HV_MODE_ZERO 5u

/* Deadbeat problem of one period [k+1, k+2), built by hil_fw_hv_prepare. */
typedef struct {
    float v_alpha;   /* required mean voltage (dPsi - M0) / Ts, stator frame [V] */
    float v_beta;
    float v_q;       /* its q component at the mid angle [V] */
    float err_alpha; /* stator flux error vector dPsi = Psi* - Psi(k+1), stator frame [Wb] */
    float err_beta;
    float cos_m;     /* cos/sin of the rotor angle in the middle of [k+1, k+2) */
    float sin_m;
    float vdc;       /* DC link [V] */
    float psi_d1;    /* predicted stator flux at k+1, eq. (6) [Wb] */
    float psi_q1;
    float i_abc[3];  /* predicted phase currents in the middle of [k+1, k+2) [A] */
} hil_fw_hv_problem_t;

/* Duty cycles of one vector pair from eq. (9). */
typedef struct {
    uint8_t v1;  /* first vector of Table 1 (switching code of u1/u3/u5) */
    uint8_t v2;  /* second vector (u2/u4/u6) */
    float d1;    /* duty cycles in [0, 1], d1 + d2 <= 1 after clamping */
    float d2;
    float err2;  /* squared flux error left after clamping [Wb^2] (0 if feasible) */
} hil_fw_hv_pair_t;

/* Diagnostics of the last step, kept in the state (read by tests and loggers). */
typedef struct {
    float psi_d1;      /* predicted flux at k+1 [Wb] */
    float psi_q1;
    float err_alpha;   /* flux error vector [Wb] */
    float err_beta;
    float t_opt1;      /* eq. (9) dwell times before the mode logic [s] */
    float t_opt2;
    float t_zero;
    uint8_t sector;    /* 1..6 (Table 1 row, or the pair chosen by the 3vmpc search) */
    uint8_t mode;      /* HIL_FW_HV_MODE_* actually applied */
    uint8_t requested; /* mode from the eq. (9) times before the narrow re-check */
    uint8_t dt_moved;  /* edges moved by the dead-time compensation */
    hil_fw_vseq_t seq; /* full symmetric sequence of the period (before packing) */
} hil_fw_hv_state_t;

/* Sector 1..6 of a stator-frame vector: sector s spans [(s-1)*60, s*60) degrees. */
uint8_t hil_fw_hv_sector(float x_alpha, float x_beta);

/* Table 1: the two active vectors (switching codes) for a sector 1..6. */
void hil_fw_hv_table1(uint8_t sector, uint8_t *v1, uint8_t *v2);

/* Eq. (6) prediction to k+1 and the deadbeat problem for [k+1, k+2) from the state's measurement,
 * references and applied command. */
void hil_fw_hv_prepare(const struct hil_fw_state *s, hil_fw_hv_problem_t *p);

/* Eq. (9) for the pair of `sector`: d1 u1 + d2 u2 = v; negative duties clamped to 0, d1 + d2 > 1
 * scaled back to 1 (over-modulation); err2 = |Ts (v - d1 u1 - d2 u2)|^2. */
void hil_fw_hv_pair_duties(const hil_fw_hv_problem_t *p, uint8_t sector, float ts, hil_fw_hv_pair_t *out);

/* Section 3.2: from eq. (9) duties, the mode against t_thr [s] and the dwell times [ns] summing to
 * ts_ns. Eq. (10) / (11) keep psi_sq deadbeat in modes 2 / 3; a vector those equations shorten
 * below t_thr is dropped too (mode 4 or 5). Returns the mode applied; *requested: the mode the
 * eq. (9) times alone select. */
uint8_t hil_fw_hv_modes(const hil_fw_hv_problem_t *p, const hil_fw_hv_pair_t *pair, float t_thr, uint32_t ts_ns,
                        hil_fw_dwell_t *dwell, uint8_t *requested);

/* Sequence, packing into the command (its distinct states with the mirror flag: the whole symmetric
 * sequence in one period), symmetric dead-time compensation; fills cmd states/durations/n_states/
 * mirror and st->seq / st->dt_moved. */
void hil_fw_hv_emit(struct hil_fw_state *s, const hil_fw_hv_problem_t *p, const hil_fw_dwell_t *dwell,
                    hil_fw_cmd_t *cmd);

/* Diagnostics into the state and vector_id = 16 * mode + sector, status ok. */
void hil_fw_hv_finish(struct hil_fw_state *s, const hil_fw_hv_problem_t *p, const hil_fw_hv_pair_t *pair,
                      uint8_t sector, uint8_t mode, uint8_t requested, hil_fw_cmd_t *cmd);

/* Prediction stage of hv-mpfc. vector_id = 16 * mode + sector; candidates = 1 (one prediction). */
void hil_fw_hv_mpfc_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd);

#endif
