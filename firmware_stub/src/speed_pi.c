/* Reference firmware: speed PI with output limit and clamping anti-windup. */
#include "hil_fw_speed_pi.h"

static float clampf(float x, float lim)
{
    if (x > lim) {
        return lim;
    }
    if (x < -lim) {
        return -lim;
    }
    return x;
}

void hil_fw_speed_pi_reset(hil_fw_speed_pi_t *pi, float integ0)
{
    pi->integ = clampf(integ0, pi->limit);
    pi->out = pi->integ;
}

float hil_fw_speed_pi_update(hil_fw_speed_pi_t *pi, float error, float dt)
{
    const float p = pi->kp * error;
    const float candidate = clampf(pi->integ + pi->ki * error * dt, pi->limit);
    const float u = p + candidate;
    /* Clamping anti-windup: while this error pushes the output into its limit, the integrator
     * only advances up to the value that puts the output exactly on the limit. */
    if (u > pi->limit && error > 0.0f) {
        const float room = pi->limit - p;
        if (room > pi->integ) {
            pi->integ = room;
        }
    } else if (u < -pi->limit && error < 0.0f) {
        const float room = -pi->limit - p;
        if (room < pi->integ) {
            pi->integ = room;
        }
    } else {
        pi->integ = candidate;
    }
    pi->out = clampf(p + pi->integ, pi->limit);
    return pi->out;
}
