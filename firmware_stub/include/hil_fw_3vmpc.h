/*
 * Reference firmware: three-vector MPC (3vmpc), the benchmark of 003_7bbad73a6f78337e.txt:
 * eq. (6) prediction, all six adjacent active-vector pairs with eq. (9) dwell times evaluated (one
 * prediction each), the pair leaving the smallest flux error applied with a zero vector as the
 * symmetric sequence zero - longer - shorter - longer - zero. Uses the hv-mpfc machinery with
 * t_thr = 0. See docs/algorithms/hv_mpfc.md.
 */
#ifndef HIL_FW_3VMPC_H
#define HIL_FW_3VMPC_H

#include "hil_fw_types.h"

struct hil_fw_state;

#define HIL_FW_3VMPC_CANDIDATES 6 /* adjacent pairs evaluated per step */

/* Prediction stage of 3vmpc. vector_id = 16 * 1 + sector of the chosen pair; candidates = 6. */
void hil_fw_3vmpc_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd);

#endif
