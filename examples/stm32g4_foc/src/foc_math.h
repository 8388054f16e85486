/*
 * Field-oriented control math, portable C99 in float32 (no device header): Clarke and Park transforms, PI with
 * clamping anti-windup, space-vector PWM duties, the encoder speed PLL and the whole current-loop step. Built
 * for the MCU with the firmware and for the host by the unit tests (tests/firmware/test_stm32g4_foc_math.py).
 * Units SI: A, V, rad (electrical unless named mechanical), rad/s, s.
 */
#ifndef FOC_MATH_H
#define FOC_MATH_H

#include <stdint.h>

#define FOC_SQRT3 1.7320508f
#define FOC_TWO_PI 6.2831853f
#define FOC_PI 3.1415927f

typedef struct {
    float kp;    /* proportional gain */
    float ki;    /* integral gain [1/s] x kp units */
    float limit; /* |output| limit */
    float integ; /* integrator state */
} foc_pi_t;

typedef struct {
    float kp;    /* PLL proportional gain [1/s] */
    float ki;    /* PLL integral gain [1/s^2] */
    float theta; /* estimated angle [rad], in [0, 2 pi) */
    float omega; /* estimated speed [rad/s]: the integral path (low-pass of the angle's steps) */
    float integ; /* integral path */
} foc_pll_t;

/* The machine and gains the current loop works with. */
typedef struct {
    float rs, ld, lq, psi_f, pole_pairs;
    float kp_d, kp_q, ki_d, ki_q; /* d/q current PI gains: V/A, V/(A*s) */
    float ts;                     /* control period [s] */
    float delay_periods;          /* sample-to-mid-application delay compensated by the angle advance [Ts] */
} foc_params_t;

typedef struct {
    foc_pi_t id_pi;
    foc_pi_t iq_pi;
    float id, iq;  /* measured d/q currents [A] */
    float vd, vq;  /* commanded d/q voltages [V] */
    uint8_t saturated; /* the last step's voltage vector was limited (integrators held) */
} foc_state_t;

float foc_wrap_2pi(float x);
float foc_wrap_pi(float x);
void foc_clarke(float ia, float ib, float *alpha, float *beta);
void foc_park(float alpha, float beta, float s, float c, float *d, float *q);
void foc_inv_park(float d, float q, float s, float c, float *alpha, float *beta);
float foc_pi_step(foc_pi_t *pi, float error, float ts);
/* Duty cycles 0..1 of the three legs for (v_alpha, v_beta) [V] on vdc [V]: min-max zero-sequence injection;
 * beyond the linear range vdc/sqrt(3) the vector is scaled back. Returns 1 when it was scaled. */
int foc_svpwm(float v_alpha, float v_beta, float vdc, float duty[3]);
void foc_pll_init(foc_pll_t *pll, float bandwidth_rad_s, float theta);
float foc_pll_step(foc_pll_t *pll, float theta_meas, float ts);
/* Gains for a current-loop bandwidth wc [rad/s]: kp = wc*L, ki = wc*Rs (the PI zero cancels the R/L pole). */
void foc_params_set_bandwidth(foc_params_t *p, float wc);
void foc_reset(foc_state_t *st, float vlimit);
/* One current-loop step: phase currents ia, ib [A] (ic = -ia - ib), rotor angle theta_e and speed omega_e
 * (electrical), DC link vdc; references id_ref, iq_ref [A]. The d/q voltage is limited to vdc/sqrt(3), d first,
 * and the integrators hold while it is. Writes the three duties. */
void foc_current_step(foc_state_t *st, const foc_params_t *p, float ia, float ib, float theta_e, float omega_e,
                      float vdc, float id_ref, float iq_ref, float duty[3]);

#endif /* FOC_MATH_H */
