/*
 * Reference firmware: speed PI outer loop (parallel form, clamped integrator, output limit).
 * Input: speed error [rad/s mechanical]; output: torque reference [N*m].
 */
#ifndef HIL_FW_SPEED_PI_H
#define HIL_FW_SPEED_PI_H

typedef struct {
    float kp;     /* proportional gain [N*m/(rad/s)] */
    float ki;     /* integral gain [N*m/rad] */
    float limit;  /* output and integrator limit [N*m], > 0 */
    float integ;  /* integrator state [N*m] */
    float out;    /* last output [N*m] */
} hil_fw_speed_pi_t;

/* Set the integrator to integ0 [N*m] (clamped to +-limit) and the output to it. */
void hil_fw_speed_pi_reset(hil_fw_speed_pi_t *pi, float integ0);

/* One update over dt [s]: integ += ki*e*dt, out = kp*e + integ, both limited to +-limit. While the
 * error pushes the output into its limit the integrator stops where the output just reaches the
 * limit (clamping anti-windup). Returns the torque reference [N*m]. */
float hil_fw_speed_pi_update(hil_fw_speed_pi_t *pi, float error, float dt);

#endif
