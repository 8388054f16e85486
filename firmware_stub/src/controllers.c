/* Reference firmware: the controller table (ids and names generated from the DBC into hil_ids.h). */
#include <stddef.h>
#include <string.h>

#include "hil_fw_3vmpc.h"
#include "hil_fw_controllers.h"
#include "hil_fw_dbcc_mpc.h"
#include "hil_fw_dsvm.h"
#include "hil_fw_fcs_mpc.h"
#include "hil_fw_foc.h"
#include "hil_fw_hv_mpfc.h"
#include "hil_fw_mpcc.h"
#include "hil_fw_mptc.h"
#include "hil_fw_state.h"

/* One line per controller: id suffix of hil_ids.h, phases, reset, reference stage, prediction stage
 * (NULL: a controller known to the DBC but not implemented here). */
#define ENTRY(ID, phases, reset, reference, predict)                                                         \
    [HIL_FW_CTRL_##ID] = {HIL_FW_CTRL_##ID##_NAME, HIL_FW_CTRL_##ID, phases, reset, reference, predict}

static const hil_fw_controller_t table[HIL_FW_CTRL_COUNT] = {
    ENTRY(OFF, 0u, NULL, NULL, NULL),
    ENTRY(MPCC, 3u, NULL, NULL, hil_fw_mpcc_predict),
    ENTRY(FCS_MPC_1, 3u, hil_fw_dsvm_reset, hil_fw_fcs_mpc1_reference, hil_fw_dsvm_restricted_predict),
    ENTRY(FCS_MPC_2, 3u, hil_fw_dsvm_reset, hil_fw_fcs_mpc2_reference, hil_fw_dsvm_restricted_predict),
    ENTRY(DSVM_20, 3u, hil_fw_dsvm_reset, NULL, hil_fw_dsvm20_predict),
    ENTRY(DBCC_MPC, 3u, hil_fw_dsvm_reset, hil_fw_dbcc_reference, hil_fw_dsvm_restricted_predict),
    ENTRY(FOC, 3u, NULL, NULL, hil_fw_foc_predict),
    ENTRY(MPTC1, 6u, NULL, NULL, hil_fw_mptc1_predict),
    ENTRY(MPTC2, 6u, NULL, NULL, hil_fw_mptc2_predict),
    ENTRY(MPTC3, 6u, NULL, NULL, hil_fw_mptc3_predict),
    ENTRY(3VMPC, 3u, NULL, NULL, hil_fw_3vmpc_predict),
    ENTRY(HV_MPFC, 3u, NULL, NULL, hil_fw_hv_mpfc_predict),
};

const hil_fw_controller_t *hil_fw_controller_get(uint8_t controller_id)
{
    /* ids of the DBC without a table line have a zeroed entry (no name): unknown to this firmware */
    return controller_id < HIL_FW_CTRL_COUNT && table[controller_id].name != NULL ? &table[controller_id] : NULL;
}

int hil_fw_controller_implemented(uint8_t controller_id)
{
    const hil_fw_controller_t *c = hil_fw_controller_get(controller_id);
    return c != NULL && (c->predict != NULL || controller_id == HIL_FW_CTRL_OFF);
}

const char *hil_fw_controller_name(uint8_t controller_id)
{
    const hil_fw_controller_t *c = hil_fw_controller_get(controller_id);
    return c != NULL ? c->name : "?";
}

void hil_fw_controller_reset(struct hil_fw_state *s)
{
    const hil_fw_controller_t *c = hil_fw_controller_get(s->controller_id);
    memset(&s->ctrl, 0, sizeof s->ctrl);
    if (c != NULL && c->reset != NULL) {
        c->reset(s);
    }
}
