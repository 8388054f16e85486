/*
 * A user firmware that misbehaves at control step MISBEHAVE_AT (tests of the SIL target's own process,
 * tests/firmware_board/test_sil_isolation.py). Until then it is a valid DUT: it acknowledges every parameter,
 * takes any controller and answers each Measurement with the zero vector over Ts. At step MISBEHAVE_AT it
 * writes through a null pointer (MISBEHAVE_CRASH: SIGSEGV on the host; on the Cortex-M4F an undefined
 * instruction, a fault), calls abort() (MISBEHAVE_ABORT: SIGABRT), recurses without end (MISBEHAVE_OVERFLOW: a
 * stack overflow, SIGSEGV) or never returns (MISBEHAVE_HANG). MISBEHAVE_CONFIG crashes on the ConfigParam Ts.
 * MISBEHAVE_PRINT misbehaves not at all but prints 1 kB per step on its stdout (8 lines of 128 bytes).
 * MISBEHAVE_INIT_HANG never returns from hil_app_init, MISBEHAVE_CONFIG_HANG from hil_app_config (on Ts).
 * MISBEHAVE_BOTH_FORMS sets both Command forms from step MISBEHAVE_AT on: its zero vector and three duties 0.5.
 */
#include <stdint.h>
#include <stdlib.h>
#if defined(MISBEHAVE_PRINT) && !defined(__arm__)
#include <stdio.h>
#endif

#include "hil_app.h"
#include "hil_ids.h"
#include "../accept_all.h"

#define MISBEHAVE_AT 500u

static uint32_t g_ts_ns = 100000u;
static uint32_t g_steps;
#if !defined(__arm__)
static int *volatile g_nowhere; /* NULL, and the compiler cannot prove it */
#endif
static volatile uint32_t g_spins;

void hil_app_init(void)
{
#if defined(MISBEHAVE_INIT_HANG)
    for (;;) {
        g_spins++;
    }
#endif
    g_ts_ns = 100000u;
    g_steps = 0u;
}

int hil_app_config(uint8_t param_id, float value)
{
#if defined(MISBEHAVE_CONFIG) && !defined(__arm__)
    if (param_id == HIL_FW_P_TS) {
        *g_nowhere = 1; /* crashes while being configured */
    }
#endif
#if defined(MISBEHAVE_CONFIG_HANG)
    if (param_id == HIL_FW_P_TS) {
        for (;;) {
            g_spins++;
        }
    }
#endif
    if (param_id == HIL_FW_P_TS) {
        g_ts_ns = (uint32_t)(value * 1e9f + 0.5f);
    }
    return HIL_APP_OK;
}

#if defined(MISBEHAVE_OVERFLOW)
static volatile uint32_t g_depth_limit; /* 0: none (the compiler cannot prove the recursion endless) */

/* endless recursion with a frame the compiler keeps: a stack overflow */
static uint32_t deeper(uint32_t depth)
{
    volatile uint8_t frame[256];
    frame[depth % 256u] = (uint8_t)depth;
    if (g_depth_limit != 0u && depth >= g_depth_limit) {
        return frame[0];
    }
    return deeper(depth + 1u) + frame[(depth + 1u) % 256u];
}
#endif

void hil_app_step(const hil_app_meas_t *m, hil_app_cmd_t *cmd)
{
    (void)m;
#if defined(MISBEHAVE_PRINT) && !defined(__arm__)
    {
        int line;
        for (line = 0; line < 8; ++line) { /* 127 characters and the newline */
            printf("step %06u line %d: %0107u\n", (unsigned)g_steps, line, 0u);
        }
    }
#endif
    if (g_steps++ == MISBEHAVE_AT) {
#if defined(MISBEHAVE_CRASH) && defined(__arm__)
        __builtin_trap(); /* an undefined instruction: UsageFault, escalated to HardFault */
#elif defined(MISBEHAVE_CRASH)
        *g_nowhere = 1;
#elif defined(MISBEHAVE_ABORT)
        abort();
#elif defined(MISBEHAVE_OVERFLOW)
        (void)deeper(0u);
#elif defined(MISBEHAVE_HANG)
        for (;;) {
            g_spins++;
        }
#endif
    }
    cmd->n_states = 1u;
    cmd->states[0] = 0u;
    cmd->durations_ns[0] = g_ts_ns;
#if defined(MISBEHAVE_BOTH_FORMS)
    if (g_steps > MISBEHAVE_AT) {
        cmd->n_duties = 3u;
        cmd->duty[0] = 0.5f;
        cmd->duty[1] = 0.5f;
        cmd->duty[2] = 0.5f;
    }
#endif
}
