/*
 * Reference firmware: field-oriented control, the classic baseline of Fig. 15: PI current loops in
 * dq (current_kp, current_ki) with back-EMF/cross-coupling feed-forward, the voltage rotated to
 * the middle of its application interval, and center-aligned SVPWM. The 7-segment pattern
 * 0-a-b-7-b-a-0 spans two control periods: even periods send (a, b, 7), odd periods (b, a, 0),
 * each with the dwell times of the whole voltage (ta, tb, t0), so every period's mean voltage is
 * the reference and every leg switches once per period. See docs/algorithms/dsvm.md.
 * With pwm_duties = 1 (the default) foc ends as drive firmware does: three duty cycles of a
 * centre-aligned PWM (min-max zero-sequence injection, the duty form of SVPWM), whose carrier the
 * plant compares exactly: all 7 segments 0-x-xy-7-xy-x-0 in every period (docs/firmware_api.md).
 * Reference stage (hil_fw_foc_reference): the torque reference becomes (id, iq) on the MTPA curve of the
 * controller's linear model (ld, lq, psi_f), id_ref (the parameter) added to it, and field weakening by
 * voltage-limit feedback: an integrator lowers id while the last current-PI voltage demand |v_dq| exceeds
 * FOC_FW_MARGIN of the linear reach vdc / sqrt(3), its gain scheduled by 1 / (|omega_e| ld) so that the loop's
 * crossover stays FOC_FW_CROSSOVER; id stays above -psi_f / ld (the characteristic current) and the current
 * limit; iq = T / (1.5 p (psi_f + (ld - lq) id)) under the current limit. See docs/algorithms/field_weakening.md.
 */
#ifndef HIL_FW_FOC_H
#define HIL_FW_FOC_H

#include <stdint.h>

#include "hil_fw_types.h"

struct hil_fw_state;

typedef struct {
    uint8_t parity;     /* 0: up-counting half (a, b, 7), 1: down-counting half (b, a, 0) */
    uint8_t sector;     /* SVPWM sector 1..6 of the last voltage */
    uint64_t next_t_ns; /* expected sample time of the next step [ns] */
    float x_d;          /* integrator states [V] */
    float x_q;
    float v_d;          /* last dq voltage reference after limiting [V] */
    float v_q;
    float v_dem;        /* last |v_dq| demand before limiting [V] (field-weakening feedback) */
    float id_fw;        /* field-weakening d current [A], <= 0 */
} hil_fw_foc_state_t;

/* SVPWM of a stator-frame voltage [V] at DC link vdc [V] over ts_ns: sector (1..6) and the dwell
 * times of the odd vector a (V1/V3/V5), the even vector b (V2/V4/V6) and the zero vectors;
 * over-modulation is scaled back onto the hexagon. ta + tb + t0 = ts_ns. */
uint8_t hil_fw_svpwm(float u_alpha, float u_beta, float vdc, uint32_t ts_ns, uint8_t *a, uint8_t *b,
                     uint32_t times_ns[3]);

/* The 7-segment pattern of a stator-frame voltage [V] over one period: SVPWM at vdc [V] over ts_ns, the even
 * half (a, b, 7) or the odd half (b, a, 0) by *parity (toggled), empty slots dropped; fills the command's
 * states, durations, vector_id (the sector), candidates 0 and status ok; returns the sector 1..6. */
uint8_t hil_fw_foc_modulate(float u_alpha, float u_beta, float vdc, uint32_t ts_ns, uint8_t *parity,
                            hil_fw_cmd_t *cmd);
/* Duty cycles (0..1) of legs a, b, c for a stator-frame voltage [V] at DC link vdc [V]: min-max
 * zero-sequence injection (centre-aligned SVPWM); beyond the hexagon the voltage is scaled onto it.
 * A non-finite input gives 0.5 on every leg (zero voltage), never a NaN. */
void hil_fw_svpwm_duties(float u_alpha, float u_beta, float vdc, float duty[3]);

/* The MTPA d current [A] of a machine with inductances ld, lq [H] and magnet flux psi_f [Wb] at q current
 * i_q [A]: -(lq - ld) i_q^2 / (psi_f / 2 + sqrt(psi_f^2 / 4 + (lq - ld)^2 i_q^2)) (the rationalised root of
 * dT/did = 0 at constant |i|, exact for lq = ld); 0 when lq <= ld. */
float hil_fw_mtpa_id(float ld, float lq, float psi_f, float i_q);

/* Reference stage of foc: MTPA and field weakening (id, iq) from the torque reference. */
void hil_fw_foc_reference(struct hil_fw_state *s);

/* Prediction stage of foc (PI + SVPWM). */
void hil_fw_foc_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd);

#endif
