/* The board hooks of the HIL target core inside the native loop: the execution time a Command reports is the
 * firmware's own profiled stage split (measurement + reference + prediction [ns]), as the Python in-process
 * target reports it (src/pmsm_hil/sim_target/target.py), not the core's clock around the whole step. */
#define _POSIX_C_SOURCE 199309L

#include <time.h>

#include "hil_target_core.h"

void hil_app_reference_diag(uint32_t split_ns[3], uint8_t *full_miss);

uint32_t hil_board_clock(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint32_t)((uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec);
}

uint32_t hil_board_exec_ns(uint32_t t0, uint32_t t1)
{
    uint32_t split[3];
    uint8_t full_miss;
    uint64_t sum;
    (void)t0;
    (void)t1;
    hil_app_reference_diag(split, &full_miss);
    sum = (uint64_t)split[0] + split[1] + split[2];
    return sum > 0xFFFFFFFFu ? 0xFFFFFFFFu : (uint32_t)sum;
}
