/*
 * Reference firmware: the controller table. One entry per controller id (hil_ids.h, from the DBC):
 * its name, id, phase count, a reset run when it is selected and on every rising enable edge, and
 * the two stages of its step. Each controller lives in its own .c file; adding one is that file plus
 * one table line in controllers.c (docs/recipes.md, "A new controller").
 */
#ifndef HIL_FW_CONTROLLERS_H
#define HIL_FW_CONTROLLERS_H

#include <stdint.h>

#include "hil_fw_types.h"

struct hil_fw_state;

/* Initialise the controller's part of s->ctrl (already zeroed by the caller) for a new run. */
typedef void (*hil_fw_reset_fn)(struct hil_fw_state *s);
typedef void (*hil_fw_reference_fn)(struct hil_fw_state *s);
typedef void (*hil_fw_predict_fn)(struct hil_fw_state *s, hil_fw_cmd_t *cmd);

/* Bit of parameter id p (HIL_FW_P_*) in a parameter mask. */
#define HIL_FW_PARAM_BIT(p) ((uint64_t)1u << (p))

/* Parameters the shared step reads for every controller: the motor model, Ts, Vdc, the speed PI, the torque
 * limit and integrator preset, and the torque -> current reference (id_ref, current_limit). */
#define HIL_FW_PARAMS_COMMON                                                                                  \
    (HIL_FW_PARAM_BIT(HIL_FW_P_RS) | HIL_FW_PARAM_BIT(HIL_FW_P_LD) | HIL_FW_PARAM_BIT(HIL_FW_P_LQ) |           \
     HIL_FW_PARAM_BIT(HIL_FW_P_PSI_F) | HIL_FW_PARAM_BIT(HIL_FW_P_POLE_PAIRS) | HIL_FW_PARAM_BIT(HIL_FW_P_TS) |  \
     HIL_FW_PARAM_BIT(HIL_FW_P_VDC) | HIL_FW_PARAM_BIT(HIL_FW_P_SPEED_KP) | HIL_FW_PARAM_BIT(HIL_FW_P_SPEED_KI) | \
     HIL_FW_PARAM_BIT(HIL_FW_P_TORQUE_LIMIT) | HIL_FW_PARAM_BIT(HIL_FW_P_TORQUE_INTEGRATOR_INIT) |                \
     HIL_FW_PARAM_BIT(HIL_FW_P_ID_REF) | HIL_FW_PARAM_BIT(HIL_FW_P_CURRENT_LIMIT))

typedef struct {
    const char *name;              /* DBC name (HIL_FW_CTRL_*_NAME) */
    uint8_t id;                    /* HIL_FW_CTRL_* */
    uint8_t phases;                /* measured phase currents it drives: 3 or 6 (0: either, off only) */
    hil_fw_reset_fn reset;         /* NULL: the zeroed state is its initial state */
    hil_fw_reference_fn reference; /* NULL: no reference-vector stage */
    hil_fw_predict_fn predict;     /* NULL: not implemented */
    uint64_t params;               /* parameters it reads: HIL_FW_PARAMS_COMMON | its own (HIL_FW_PARAM_BIT);
                                    * `hil run` refuses a --param outside it (off: none) */
} hil_fw_controller_t;

/* Table entry for controller_id, or NULL for ids without an entry (unknown to this firmware). */
const hil_fw_controller_t *hil_fw_controller_get(uint8_t controller_id);

/* 1 if controller_id has an entry and is implemented (off included), else 0. */
int hil_fw_controller_implemented(uint8_t controller_id);

/* Name of controller_id ("?" for ids without an entry). */
const char *hil_fw_controller_name(uint8_t controller_id);

/* Start the selected controller afresh: zero s->ctrl, then run its reset. Called by
 * hil_fw_select_controller on a change of controller and by hil_fw_set_setpoint on a rising enable. */
void hil_fw_controller_reset(struct hil_fw_state *s);

#endif
