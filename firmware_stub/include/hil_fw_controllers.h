/*
 * Reference firmware: controller dispatch table. Each controller lives in its own .c file and
 * provides an optional reference-vector stage and a prediction/evaluation stage.
 */
#ifndef HIL_FW_CONTROLLERS_H
#define HIL_FW_CONTROLLERS_H

#include <stdint.h>

#include "hil_fw_types.h"

struct hil_fw_state;

typedef void (*hil_fw_reference_fn)(struct hil_fw_state *s);
typedef void (*hil_fw_predict_fn)(struct hil_fw_state *s, hil_fw_cmd_t *cmd);

typedef struct {
    const char *name;              /* name as in docs/architecture.md */
    hil_fw_reference_fn reference; /* NULL: no reference-vector stage */
    hil_fw_predict_fn predict;     /* NULL: not implemented */
} hil_fw_controller_t;

/* Table entry for controller_id, or NULL for unknown ids. */
const hil_fw_controller_t *hil_fw_controller_get(uint8_t controller_id);

/* 1 if controller_id is known and implemented, else 0. */
int hil_fw_controller_implemented(uint8_t controller_id);

/* Name of controller_id ("?" for unknown ids). */
const char *hil_fw_controller_name(uint8_t controller_id);

#endif
