/* Harness, not control law: stage timing with CLOCK_MONOTONIC. */
#define _POSIX_C_SOURCE 199309L

#include <time.h>

#include "hil_fw_profile.h"
#include "hil_fw_step.h"

static uint64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

void hil_fw_step_profiled(hil_fw_state_t *s, const hil_fw_meas_t *m, uint64_t t_ns, hil_fw_cmd_t *cmd,
                          uint32_t split_ns[3])
{
    const uint64_t t0 = now_ns();
    uint64_t t1;
    uint64_t t2;
    uint64_t t3;
    hil_fw_stage_measure(s, m, t_ns);
    t1 = now_ns();
    hil_fw_stage_reference(s);
    t2 = now_ns();
    hil_fw_stage_predict(s, cmd);
    t3 = now_ns();
    split_ns[0] = (uint32_t)(t1 - t0);
    split_ns[1] = (uint32_t)(t2 - t1);
    split_ns[2] = (uint32_t)(t3 - t2);
}
