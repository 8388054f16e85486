/*
 * Reference firmware: discrete space vector modulation with the period split into two equal
 * halves (N = 2), eqs. (7)-(9) of the paper, and the prediction/evaluation core shared by
 * dsvm-20, fcs-mpc-1, fcs-mpc-2 and dbcc-mpc. See docs/algorithms/dsvm.md and
 * docs/algorithms/fcs_mpc_regions.md.
 *
 * DSVM vector index (19 distinct voltages; eq. (9) counts 20 because u0 and u7 both give zero):
 *   0        zero (both halves a zero vector)
 *   1..6     u_j  = u_j in both halves
 *   7..12    u_{j,j+1} = u_j in one half, u_{j+1} in the other (u12, u23, u34, u45, u56, u61)
 *   13..18   u_jZ = u_j in one half, a zero vector in the other
 * Lattice coordinates (m, n): voltage = Vdc/3 * (m e1 + n e2), e1 at 0 deg, e2 at 60 deg.
 */
#ifndef HIL_FW_DSVM_H
#define HIL_FW_DSVM_H

#include <stdint.h>

#include "hil_fw_types.h"

struct hil_fw_state;

#define HIL_FW_DSVM_VECTORS 19     /* distinct synthesized voltages */
#define HIL_FW_DSVM_MAX_CAND 19    /* largest candidate list */
#define HIL_FW_DSVM_NO_DIAG 255u   /* full_miss: not a restricted-set controller */
#define HIL_FW_DSVM_NO_STEP UINT64_MAX /* next_t_ns after reset: the next step (re)starts the flux observer */

/* One DSVM vector: lattice coordinates and the real vectors (0 = zero, 1..6) of its two halves. */
typedef struct {
    int8_t m;
    int8_t n;
    uint8_t half_a;
    uint8_t half_b;
} hil_fw_dsvm_vector_t;

extern const hil_fw_dsvm_vector_t hil_fw_dsvm_vectors[HIL_FW_DSVM_VECTORS];

/* Triangular regions of Fig. 6 (r = 0..5: sector between u_{r+1} and u_{r+2}), 6 vectors each. */
extern const uint8_t hil_fw_dsvm_triangle[6][6];
/* Rhombic (kite) regions of Fig. 8 (r = 0..5: centred on u_{r+1}), 5 vectors each. */
extern const uint8_t hil_fw_dsvm_kite[6][5];
/* DSVM index of lattice point (m, n), m, n in -2..2, at [m + 2][n + 2]; 255 outside the hexagon. */
extern const uint8_t hil_fw_dsvm_lattice_index[5][5];

/* State of the DSVM family (flux observer, hysteresis, candidate list, last evaluation). */
typedef struct {
    uint8_t h_psi;         /* flux comparator output (Table 1/2 row) */
    uint8_t h_te;          /* torque comparator output */
    uint8_t sector;        /* flux sector S, 1..6 */
    uint8_t ref_vector;    /* reference vector (DSVM index) of the reference stage */
    uint8_t n_cand;        /* candidates in cand[] */
    uint8_t best;          /* chosen DSVM index */
    uint8_t prepared;      /* 1: prediction terms below are valid for this step */
    uint8_t cand[HIL_FW_DSVM_MAX_CAND];
    uint64_t next_t_ns;    /* expected sample time of the next step [ns]; HIL_FW_DSVM_NO_STEP after reset */
    float psi_a;           /* stator flux estimate at k, eq. (10) [Wb] */
    float psi_b;
    float i_a_prev;        /* stator current at k-1 [A] */
    float i_b_prev;
    float u_a_prev;        /* mean voltage applied over [k-1, k) [V] */
    float u_b_prev;
    float psi_ref;         /* flux reference [Wb] */
    float psi_mag1;        /* |psi| at k+1 [Wb] */
    float te1;             /* torque estimate at k+1, eq. (11) [N*m] */
    float id1;             /* delay-compensated current at k+1 [A] */
    float iq1;
    float c2;              /* cos/sin of the angle in the middle of [k+1, k+2) */
    float s2;
    float err_d;           /* i_ref - i(k+2) under the zero vector [A] */
    float err_q;
    float d1d;             /* i(k+2) change per lattice step e1 / e2 [A] */
    float d1q;
    float d2d;
    float d2q;
    float v_ref_m;         /* dbcc-mpc: reference voltage in lattice coordinates */
    float v_ref_n;
    float best_cost;       /* g1 of the chosen vector [A] */
} hil_fw_dsvm_state_t;

/* Reset of the family's controllers (table entry): no previous step, so fcs-mpc-1/2 start the flux
 * observer from the current model at their first step. */
void hil_fw_dsvm_reset(struct hil_fw_state *s);

/* Delay compensation and the per-candidate terms for this step (idempotent within a step). */
void hil_fw_dsvm_prepare(struct hil_fw_state *s);

/* Cost g1, eq. (4), of DSVM vector `idx` with the prepared terms [A]. */
float hil_fw_dsvm_cost(const hil_fw_dsvm_state_t *st, uint8_t idx);

/* Evaluate st->cand, pick the least g1 (first wins ties) and write the two-half command. */
void hil_fw_dsvm_choose(struct hil_fw_state *s, hil_fw_cmd_t *cmd);

/* Switching sequence of DSVM vector idx after the state prev_code: two Ts/2 halves ordered (and
 * the zero vector picked) for the fewest leg transitions. */
void hil_fw_dsvm_sequence(uint8_t idx, uint8_t prev_code, uint32_t ts_ns, hil_fw_cmd_t *cmd);

/* Prediction stage of dsvm-20: all 19 distinct vectors. */
void hil_fw_dsvm20_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd);

/* Prediction stage of fcs-mpc-1/2 and dbcc-mpc: the reference stage's candidate list. */
void hil_fw_dsvm_restricted_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd);

/* Diagnostics (not part of the control law, not timed): 1 if the full 19-vector optimum has a
 * lower g1 than the restricted set's choice this step, 0 if not, HIL_FW_DSVM_NO_DIAG for
 * controllers without a restricted set or when no evaluation ran. */
uint8_t hil_fw_dsvm_full_miss(const struct hil_fw_state *s);

#endif
