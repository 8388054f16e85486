/*
 * Duty cycles of a centre-aligned PWM -> the switching sequence of one control period (docs/firmware_api.md,
 * "Duty-cycle commands"). Integer arithmetic only, so the Python twin (src/pmsm_hil/hil/pwm.py) gives the same ns.
 *
 * Carrier: a triangle counter c(t) from the valley (c = 0, every leg low) to the peak (c = 1) and back; a leg is
 * high (upper switch on) while c(t) > 1 - d. Single update: the carrier period is the control period Ts, valley
 * at the period start, peak at Ts/2: the leg is high over [t_on, Ts - t_on), t_on = (1 - d) Ts / 2, the 7
 * segments 0-x-xy-7-xy-x-0. Double update (control at twice the PWM rate): the carrier period is 2 Ts; an even
 * control period k holds the rising half (high over [(1 - d) Ts, Ts)), an odd one the falling half (high over
 * [0, Ts - (1 - d) Ts)). Instants are rounded to the nearest ns (half up), the plant's time grid.
 */
#ifndef HIL_PWM_DUTY_H
#define HIL_PWM_DUTY_H

#include <stdint.h>

#define PWM_DUTY_FULL 65520u      /* raw duty of d = 1 (wire scale 1/65520) */
#define PWM_DUTY_OUT_OF_RANGE 65534u /* raw code: the firmware's duty was below 0 or above 1 */
#define PWM_DUTY_NAN 65535u       /* raw code: the firmware's duty was not a number */
#define PWM_MAX_LEGS 6
#define PWM_MAX_SEGMENTS (2 * PWM_MAX_LEGS + 1)

#define PWM_SINGLE 0              /* single update: the whole carrier in one control period */
#define PWM_RISING 1              /* double update, even period: valley -> peak */
#define PWM_FALLING 2             /* double update, odd period: peak -> valley */

/* The sequence of `legs` raw duties (0..PWM_DUTY_FULL; leg 0 is the MSB of a state code) over ts_ns [ns]:
 * states and durations [ns] (PWM_MAX_SEGMENTS capacity, no zero durations, sum ts_ns); returns the count,
 * or -1 - j for the first raw duty j above PWM_DUTY_FULL. */
int pwm_duty_sequence(int legs, const uint16_t *raw, int64_t ts_ns, int half, int32_t *states, int64_t *durations);

#endif
