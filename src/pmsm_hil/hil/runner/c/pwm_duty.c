/* Duty cycles -> switching sequence; see pwm_duty.h. */
#include "pwm_duty.h"

/* round(num / den) for num, den >= 0, half up. */
static int64_t div_round(int64_t num, int64_t den)
{
    return (2 * num + den) / (2 * den);
}

int pwm_duty_sequence(int legs, const uint16_t *raw, int64_t ts_ns, int half, int32_t *states, int64_t *durations)
{
    int64_t on[PWM_MAX_LEGS];
    int64_t off[PWM_MAX_LEGS];
    int64_t b[2 * PWM_MAX_LEGS + 2];
    int nb = 0;
    int n = 0;
    for (int leg = 0; leg < legs; leg++) {
        const int64_t low = (int64_t)PWM_DUTY_FULL - (int64_t)raw[leg]; /* (1 - d) * FULL */
        if (raw[leg] > PWM_DUTY_FULL) {
            return -1 - leg;
        }
        if (half == PWM_SINGLE) {
            on[leg] = div_round(low * ts_ns, 2 * (int64_t)PWM_DUTY_FULL);
            off[leg] = ts_ns - on[leg];
        } else if (half == PWM_RISING) {
            on[leg] = div_round(low * ts_ns, (int64_t)PWM_DUTY_FULL);
            off[leg] = ts_ns;
        } else {
            on[leg] = 0;
            off[leg] = ts_ns - div_round(low * ts_ns, (int64_t)PWM_DUTY_FULL);
        }
        b[nb++] = on[leg];
        b[nb++] = off[leg];
    }
    b[nb++] = 0;
    b[nb++] = ts_ns;
    for (int i = 1; i < nb; i++) { /* insertion sort: at most 14 instants */
        int64_t x = b[i];
        int j = i - 1;
        while (j >= 0 && b[j] > x) {
            b[j + 1] = b[j];
            j--;
        }
        b[j + 1] = x;
    }
    for (int i = 0; i + 1 < nb; i++) {
        int32_t st = 0;
        if (b[i + 1] == b[i]) {
            continue;
        }
        for (int leg = 0; leg < legs; leg++) {
            if (on[leg] <= b[i] && b[i] < off[leg]) {
                st |= 1 << (legs - 1 - leg);
            }
        }
        if (n > 0 && states[n - 1] == st) { /* an instant where no leg changes (a duty 0 at the peak) */
            durations[n - 1] += b[i + 1] - b[i];
            continue;
        }
        states[n] = st;
        durations[n] = b[i + 1] - b[i];
        n++;
    }
    return n;
}
