/*
 * Reference firmware: two-level inverter voltage vectors, eq. (3) of the paper:
 * u_j = 2/3 Vdc (Sa + a Sb + a^2 Sc), a = exp(j 2 pi / 3).
 *
 * Vector index (vector_id) vs switching code 4*Sa + 2*Sb + Sc:
 *   V0 = 000 (0), V1 = 100 (4), V2 = 110 (6), V3 = 010 (2), V4 = 011 (3), V5 = 001 (1),
 *   V6 = 101 (5), V7 = 111 (7); Vj (j = 1..6) points at (j - 1) * 60 degrees.
 */
#ifndef HIL_FW_INVERTER_H
#define HIL_FW_INVERTER_H

#include <stdint.h>

#include "hil_fw_types.h"

extern const uint8_t hil_fw_vector_state[8]; /* vector index -> switching code */
extern const uint8_t hil_fw_state_vector[8]; /* switching code -> vector index */

/* alpha/beta voltage [V] of switching code (0..7) at DC-link voltage vdc [V]. */
void hil_fw_state_voltage_ab(uint8_t code, float vdc, float *u_alpha, float *u_beta);

/* Duration-weighted mean alpha/beta voltage [V] of a command's sub-intervals. */
void hil_fw_cmd_mean_voltage_ab(const uint8_t *states, const uint32_t *durations_ns, uint8_t n_states,
                                float vdc, float *u_alpha, float *u_beta);

/* Number of inverter legs that change between switching codes a and b (0..3). */
uint8_t hil_fw_leg_transitions(uint8_t a, uint8_t b);

/* Zero-vector code (0 or 7) reachable from prev_code with the fewest leg transitions. */
uint8_t hil_fw_zero_state_for(uint8_t prev_code);

#endif
