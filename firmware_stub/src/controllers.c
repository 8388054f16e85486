/* Reference firmware: controller dispatch table (ids from docs/architecture.md). */
#include <stddef.h>

#include "hil_fw_controllers.h"
#include "hil_fw_mpcc.h"

/* Controllers not implemented yet keep predict = NULL; each new one adds its own .c file. */
static const hil_fw_controller_t table[HIL_FW_CTRL_COUNT] = {
    [HIL_FW_CTRL_OFF] = {"off", NULL, NULL},
    [HIL_FW_CTRL_MPCC] = {"mpcc", NULL, hil_fw_mpcc_predict},
    [HIL_FW_CTRL_FCS_MPC_1] = {"fcs-mpc-1", NULL, NULL},
    [HIL_FW_CTRL_FCS_MPC_2] = {"fcs-mpc-2", NULL, NULL},
    [HIL_FW_CTRL_DSVM_20] = {"dsvm-20", NULL, NULL},
    [HIL_FW_CTRL_DBCC_MPC] = {"dbcc-mpc", NULL, NULL},
    [HIL_FW_CTRL_FOC] = {"foc", NULL, NULL},
    [HIL_FW_CTRL_MPTC1] = {"mptc1", NULL, NULL},
    [HIL_FW_CTRL_MPTC2] = {"mptc2", NULL, NULL},
    [HIL_FW_CTRL_MPTC3] = {"mptc3", NULL, NULL},
    [HIL_FW_CTRL_3VMPC] = {"3vmpc", NULL, NULL},
    [HIL_FW_CTRL_HV_MPFC] = {"hv-mpfc", NULL, NULL},
};

const hil_fw_controller_t *hil_fw_controller_get(uint8_t controller_id)
{
    return controller_id < HIL_FW_CTRL_COUNT ? &table[controller_id] : NULL;
}

int hil_fw_controller_implemented(uint8_t controller_id)
{
    if (controller_id == HIL_FW_CTRL_OFF) {
        return 1;
    }
    return controller_id < HIL_FW_CTRL_COUNT && table[controller_id].predict != NULL;
}

const char *hil_fw_controller_name(uint8_t controller_id)
{
    return controller_id < HIL_FW_CTRL_COUNT ? table[controller_id].name : "?";
}
