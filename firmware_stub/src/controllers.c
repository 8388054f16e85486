/* Reference firmware: controller dispatch table (ids from docs/architecture.md). */
#include <stddef.h>

#include "hil_fw_3vmpc.h"
#include "hil_fw_controllers.h"
#include "hil_fw_dbcc_mpc.h"
#include "hil_fw_dsvm.h"
#include "hil_fw_fcs_mpc.h"
#include "hil_fw_foc.h"
#include "hil_fw_hv_mpfc.h"
#include "hil_fw_mpcc.h"
#include "hil_fw_mptc.h"

/* Controllers not implemented yet keep predict = NULL; each new one adds its own .c file. */
static const hil_fw_controller_t table[HIL_FW_CTRL_COUNT] = {
    [HIL_FW_CTRL_OFF] = {"off", NULL, NULL},
    [HIL_FW_CTRL_MPCC] = {"mpcc", NULL, hil_fw_mpcc_predict},
    [HIL_FW_CTRL_FCS_MPC_1] = {"fcs-mpc-1", hil_fw_fcs_mpc1_reference, hil_fw_dsvm_restricted_predict},
    [HIL_FW_CTRL_FCS_MPC_2] = {"fcs-mpc-2", hil_fw_fcs_mpc2_reference, hil_fw_dsvm_restricted_predict},
    [HIL_FW_CTRL_DSVM_20] = {"dsvm-20", NULL, hil_fw_dsvm20_predict},
    [HIL_FW_CTRL_DBCC_MPC] = {"dbcc-mpc", hil_fw_dbcc_reference, hil_fw_dsvm_restricted_predict},
    [HIL_FW_CTRL_FOC] = {"foc", NULL, hil_fw_foc_predict},
    [HIL_FW_CTRL_MPTC1] = {"mptc1", NULL, hil_fw_mptc1_predict},
    [HIL_FW_CTRL_MPTC2] = {"mptc2", NULL, hil_fw_mptc2_predict},
    [HIL_FW_CTRL_MPTC3] = {"mptc3", NULL, hil_fw_mptc3_predict},
    [HIL_FW_CTRL_3VMPC] = {"3vmpc", NULL, hil_fw_3vmpc_predict},
    [HIL_FW_CTRL_HV_MPFC] = {"hv-mpfc", NULL, hil_fw_hv_mpfc_predict},
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
