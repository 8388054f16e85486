/*
 * Reference firmware: the control step, split into the three stages of Table 4 of the paper.
 * Time is passed in; the control law never reads a clock.
 */
#ifndef HIL_FW_STEP_H
#define HIL_FW_STEP_H

#include <stdint.h>

#include "hil_fw_state.h"
#include "hil_fw_types.h"

/* Measurement: bookkeeping, Clarke/Park, speed PI when due, torque -> current references. */
void hil_fw_stage_measure(hil_fw_state_t *s, const hil_fw_meas_t *m, uint64_t t_ns);

/* Reference vector determination (empty for MPCC). */
void hil_fw_stage_reference(hil_fw_state_t *s);

/* Prediction and evaluation: fills the command and records it as the next applied one. */
void hil_fw_stage_predict(hil_fw_state_t *s, hil_fw_cmd_t *cmd);

/* The three stages in order. */
void hil_fw_step(hil_fw_state_t *s, const hil_fw_meas_t *m, uint64_t t_ns, hil_fw_cmd_t *cmd);

#endif
