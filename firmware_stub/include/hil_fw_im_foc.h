/*
 * Reference firmware: im-foc, rotor-flux-oriented control of a squirrel-cage induction machine (inverse-Gamma
 * model: Rs, RR, L_sigma, L_M, as the plant kind "im", docs/plant.md).
 *
 * - Current-model flux estimator from the measured speed: the rotor flux psi_R in stator coordinates,
 *   d psi_R / dt = RR i_s - (RR / L_M - j omega_e) psi_R, discretized exactly for a current held at the mean
 *   of two samples (omega_e = pole_pairs * omega_m of the Measurement frame; the frame's theta_e, the rotor
 *   angle, is not needed).
 * - References (reference stage): the flux current from a model-based flux loop,
 *   i_d = |psi_R| / L_M + (psi_r_ref - |psi_R|) / (RR tau_psi), tau_psi = 20 ms, so that the estimated flux
 *   follows the flux reference with the time constant tau_psi (in steady state i_d = psi_ref / L_M), limited
 *   to 0.8 of the current limit; i_q = T / (1.5 p |psi_R|) under the current limit
 *   (|psi_R| bounded below by a tenth of the reference while the flux builds up).
 * - Field weakening: the flux reference psi_ref is psi_r_ref, or less where the voltage demands it:
 *   min(psi_r_ref, 0.95 vdc / sqrt(3) / (|omega_e| (1 + L_sigma / L_M))) (the no-load 1/omega feed-forward) plus
 *   a voltage-limit feedback correction (an integrator of 0.95 vdc / sqrt(3) - |u| with a 15 rad/s crossover,
 *   <= 0), never below a quarter of psi_r_ref (docs/algorithms/field_weakening.md).
 * - Current PI in the estimated rotor-flux frame (current_kp, current_ki) with the decoupling feed-forward
 *   u_d = -omega_s L_sigma i_q - (RR / L_M) |psi_R|, u_q = omega_s L_sigma i_d + omega_e |psi_R|
 *   (omega_s = omega_e + RR i_q / |psi_R|, the estimated flux speed), so both axes see L_sigma s + Rs + RR;
 *   conditional integration at the SVPWM voltage limit vdc / sqrt(3).
 * - The voltage rotated to the middle of its application period and the 7-segment SVPWM pattern of foc.
 * The speed PI is the shared step's. All state is zero at reset (zero flux estimate).
 */
#ifndef HIL_FW_IM_FOC_H
#define HIL_FW_IM_FOC_H

#include <stdint.h>

#include "hil_fw_types.h"

struct hil_fw_state;

typedef struct {
    uint8_t parity;     /* 7-segment half (hil_fw_foc_modulate) */
    uint8_t sector;     /* SVPWM sector 1..6 of the last voltage */
    uint64_t next_t_ns; /* expected sample time of the next step [ns] */
    float psi_a;        /* estimated rotor flux, stator frame [Wb] */
    float psi_b;
    float i_a_prev;     /* stator-frame current of the previous sample [A] */
    float i_b_prev;
    float psi;          /* |psi_R| estimate [Wb] */
    float cos_f;        /* cos, sin of the estimated rotor-flux angle */
    float sin_f;
    float x_d;          /* current-PI integrators [V] */
    float x_q;
    float v_d;          /* last flux-frame voltage reference after limiting [V] */
    float v_q;
    float v_dem;        /* last |u| demand before limiting [V] (field-weakening feedback) */
    float dpsi_fw;      /* field-weakening flux-reference correction [Wb], <= 0 */
    float psi_ref;      /* rotor-flux reference in use [Wb] (psi_r_ref, or less when field weakening) */
} hil_fw_im_foc_state_t;

/* Reference stage: flux estimate and the flux-frame current references. */
void hil_fw_im_foc_reference(struct hil_fw_state *s);

/* Prediction stage: current PI in the rotor-flux frame + SVPWM. */
void hil_fw_im_foc_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd);

#endif
