/* Host board (SIL): the target core in a shared library. The host loads it with ctypes
 * (src/pmsm_hil/sim_target/sil.py) and calls hil_core_init / hil_core_rx / hil_core_tx; the board clock is
 * CLOCK_MONOTONIC, so exec_time_ns is the host's wall time of hil_app_step. */
#define _POSIX_C_SOURCE 199309L

#include <time.h>

#include "hil_target_core.h"

uint32_t hil_board_clock(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint32_t)((uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec);
}

uint32_t hil_board_exec_ns(uint32_t t0, uint32_t t1)
{
    return t1 - t0;
}

/* ABI check for the loader: bump when hil_core_frame_t / hil_core_counters_t / hil_app_cmd_t change. */
int hil_sil_abi_version(void)
{
    return 1;
}
