/*
 * Reference firmware: dual three-phase (six-phase) helpers. Vector space decomposition of the
 * paper's eq. (1) (amplitude invariant, factor 1/3; phases A B C at 0/120/240 deg, U V W at
 * 30/150/270 deg) and the 6-bit switching code [S_A S_B S_C S_U S_V S_W], S_A the MSB.
 */
#ifndef HIL_FW_SIX_H
#define HIL_FW_SIX_H

#include <stdint.h>

#define HIL_FW_SIX_SECTORS 12

/* Phase currents (A B C U V W) [A] -> alpha, beta, x, y [A] (VSD, zero sequence dropped). */
void hil_fw_vsd(const float *i6, float *alpha, float *beta, float *x, float *y);

/* Stator-frame voltage [V] (alpha, beta, x, y) of a 6-bit code at DC-link voltage vdc [V]. */
void hil_fw_six_code_voltage(uint8_t code, float vdc, float *v4);

/* Duration-weighted mean alpha/beta voltage [V] of a six-phase sequence. */
void hil_fw_six_mean_voltage_ab(const uint8_t *states, const uint32_t *durations_ns, uint8_t n_states,
                                float vdc, float *u_alpha, float *u_beta);

/* Zero code (0 or 63) with the fewest leg transitions from prev_code. */
uint8_t hil_fw_six_zero_for(uint8_t prev_code);

/* G1 (largest, 0.644 Vdc) and G2 (0.471 Vdc) codes in the direction 15 + 30*j degrees, j = 0..11;
 * index j is the paper's VV(j+1) and sector S(j+1) = [30 j, 30 (j+1)) degrees. */
extern const uint8_t hil_fw_six_g1[HIL_FW_SIX_SECTORS];
extern const uint8_t hil_fw_six_g2[HIL_FW_SIX_SECTORS];

/* V3 duty weights: eta_G1 * |xy(G1)| = eta_G2 * |xy(G2)| -> eta_G1 = sqrt(3) - 1, eta_G2 = 2 - sqrt(3). */
#define HIL_FW_SIX_ETA_G1 0.7320508075688772f
#define HIL_FW_SIX_ETA_G2 0.2679491924311228f
#define HIL_FW_SIX_G1_AMP 0.6439505508593788f /* |G1| / Vdc */
#define HIL_FW_SIX_G2_AMP 0.4714045207910317f /* |G2| / Vdc */

#endif
