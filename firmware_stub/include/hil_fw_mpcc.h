/*
 * Reference firmware: conventional model predictive current control (MPCC), the benchmark of
 * the paper: 7 distinct vectors, cost g1 of eq. (4), forward-Euler dq model eq. (1) with the
 * back-EMF term, two-step delay compensation. See docs/algorithms/mpcc.md.
 */
#ifndef HIL_FW_MPCC_H
#define HIL_FW_MPCC_H

#include "hil_fw_types.h"

struct hil_fw_state;

#define HIL_FW_MPCC_CANDIDATES 7

/* Per-step diagnostics kept in the state (read by tests and loggers). */
typedef struct {
    float i_d1;  /* predicted d current at k+1 (delay compensation) [A] */
    float i_q1;  /* predicted q current at k+1 [A] */
    float i_d2;  /* predicted d current at k+2 for the chosen vector [A] */
    float i_q2;  /* predicted q current at k+2 for the chosen vector [A] */
    float cost;  /* g1 of the chosen vector [A] */
} hil_fw_mpcc_state_t;

/* Prediction and evaluation stage: fills states/durations/vector_id/candidates of cmd. */
void hil_fw_mpcc_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd);

#endif
