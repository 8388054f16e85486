/*
 * Firmware folders that a build must report well (tests/firmware_board/test_fw_build_ux.py): FW_NO_STEP leaves
 * out hil_app_step (the build fails naming it, on both boards), FW_WARNS compiles with a warning (shown, the
 * build succeeds), FW_SYNTAX has a syntax error (the first error with its caret context), FW_BAD_PARAMS declares
 * a parameter with an id outside 128..254, FW_BAD_PARAMS=2 a name without its NUL, FW_BAD_PARAMS=3 an infinite
 * range (the build refuses the table, naming the entry).
 */
#include <stdint.h>

#include "hil_app.h"
#include "hil_app_params.h"
#include "../accept_all.h"

#if defined(FW_BAD_PARAMS) && FW_BAD_PARAMS == 2 /* a name of 24 characters: no room for its NUL */
HIL_APP_PARAMS({"gain_of_the_speed_filter", "", 128u, {0u, 0u, 0u}, 1.0f, 0.0f, 2.0f});
#elif defined(FW_BAD_PARAMS) && FW_BAD_PARAMS == 3 /* an infinite range */
HIL_APP_PARAMS({"gain", "", 128u, {0u, 0u, 0u}, 1.0f, 0.0f, 2.0f},
               {"offset", "A", 129u, {0u, 0u, 0u}, 0.0f, -1.0f / 0.0f, 1.0f / 0.0f});
#elif defined(FW_BAD_PARAMS)
HIL_APP_PARAMS({"gain", "", 128u, {0u, 0u, 0u}, 1.0f, 0.0f, 2.0f}, {"offset", "A", 12u, {0u, 0u, 0u}, 0.0f, -1.0f, 1.0f});
#endif

void hil_app_init(void)
{
}

int hil_app_config(uint8_t param_id, float value)
{
    (void)param_id;
    (void)value;
    return HIL_APP_OK;
}

#if !defined(FW_NO_STEP)
void hil_app_step(const hil_app_meas_t *m, hil_app_cmd_t *cmd)
{
#if defined(FW_WARNS)
    int unused_in_step;
#endif
#if defined(FW_SYNTAX)
    cmd->n_states = 1u
#endif
    (void)m;
    cmd->n_states = 1u;
    cmd->states[0] = 0u;
    cmd->durations_ns[0] = 100000u;
}
#endif
