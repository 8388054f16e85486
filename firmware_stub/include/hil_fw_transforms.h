/*
 * Reference firmware: amplitude-invariant Clarke and Park transforms (float32).
 */
#ifndef HIL_FW_TRANSFORMS_H
#define HIL_FW_TRANSFORMS_H

#define HIL_FW_PI_F 3.14159265358979f
#define HIL_FW_SQRT3_F 1.73205080756888f

/* abc [A or V] -> alpha/beta, amplitude-invariant (no zero-sequence assumption). */
void hil_fw_clarke(float a, float b, float c, float *alpha, float *beta);

/* alpha/beta -> a, b, c (inverse amplitude-invariant Clarke). */
void hil_fw_clarke_inv(float alpha, float beta, float *a, float *b, float *c);

/* alpha/beta -> d/q with cos/sin of the rotor electrical angle. */
void hil_fw_park(float alpha, float beta, float cos_th, float sin_th, float *d, float *q);

/* d/q -> alpha/beta with cos/sin of the rotor electrical angle. */
void hil_fw_park_inv(float d, float q, float cos_th, float sin_th, float *alpha, float *beta);

/* cos/sin of the rotor electrical angle at the middle of the next two periods, [k, k+1) (theta + wts/2: c1, s1) and
 * [k+1, k+2) (theta + 3 wts/2: c2, s2), from cos/sin of theta at k and the angle advanced per period wts [rad]. */
void hil_fw_mid_angles(float cos_th, float sin_th, float wts, float *c1, float *s1, float *c2, float *s2);

#endif
