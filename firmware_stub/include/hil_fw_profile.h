/*
 * Harness (not control law): the step with each stage timed by CLOCK_MONOTONIC.
 */
#ifndef HIL_FW_PROFILE_H
#define HIL_FW_PROFILE_H

#include <stdint.h>

#include "hil_fw_state.h"
#include "hil_fw_types.h"

/* hil_fw_step with split_ns[0..2] = measurement, reference, prediction stage times [ns]. */
void hil_fw_step_profiled(hil_fw_state_t *s, const hil_fw_meas_t *m, uint64_t t_ns, hil_fw_cmd_t *cmd,
                          uint32_t split_ns[3]);

#endif
