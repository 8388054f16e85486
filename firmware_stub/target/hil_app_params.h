/*
 * Firmware parameters (docs/firmware_api.md "Firmware parameters"): a firmware declares its own named
 * parameters -- filter constants, bandwidths, gains of its own design -- in one exported table, and the host
 * accepts them as `hil run --param NAME=VALUE`, in sweeps (`param.NAME`) and in the pytest plugin
 * (`params={...}`). The host reads the table from the firmware file itself (ELF symbol `hil_app_params`, in the
 * SIL library and in the MCU ELF alike) and writes the values with ConfigParam frames before enabling, like
 * every other parameter: they arrive in hil_app_config(id, value). The core rejects a value outside
 * [min, max] before the firmware sees it (ConfigAck invalid_config).
 *
 *   HIL_APP_PARAMS(
 *       {"bandwidth", "rad/s", 128u, {0, 0, 0}, 1500.0f, 100.0f, 10000.0f},
 *       {"speed_filter", "s", 129u, {0, 0, 0}, 0.0f, 0.0f, 0.1f});
 *
 * Ids are 128..254 (HIL_APP_PARAM_ID_FIRST..LAST: the protocol keeps 0..127 for its own parameters); names
 * are lower case [a-z0-9_], unique, and must not be one of the protocol's parameter names (rs, ts, ...).
 * The host sends a declared parameter only when the user sets it: the firmware starts from `def` itself.
 */
#ifndef HIL_APP_PARAMS_H
#define HIL_APP_PARAMS_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define HIL_APP_PARAM_ID_FIRST 128u
#define HIL_APP_PARAM_ID_LAST 254u
#define HIL_APP_PARAM_NAME_LEN 24
#define HIL_APP_PARAM_UNIT_LEN 12

/* One entry (52 bytes, no pointers: the host reads it straight from the firmware file). */
typedef struct {
    char name[HIL_APP_PARAM_NAME_LEN]; /* NUL-terminated */
    char unit[HIL_APP_PARAM_UNIT_LEN]; /* SI unit, NUL-terminated ("" for a ratio) */
    uint8_t id;                        /* ConfigParam id, 128..254 */
    uint8_t reserved[3];               /* 0 */
    float def;                         /* the value the firmware uses unless told otherwise */
    float min;                         /* accepted range, inclusive */
    float max;
} hil_app_param_t;

/* Defined by HIL_APP_PARAMS; weak in the core (a firmware without parameters declares none). */
extern const hil_app_param_t hil_app_params[];
extern const uint32_t hil_app_params_count;

#define HIL_APP_PARAMS(...)                                                                       \
    const hil_app_param_t hil_app_params[] __attribute__((used)) = {__VA_ARGS__};                 \
    const uint32_t hil_app_params_count __attribute__((used)) =                                   \
        (uint32_t)(sizeof(hil_app_params) / sizeof(hil_app_params[0]))

#ifdef __cplusplus
}
#endif

#endif
