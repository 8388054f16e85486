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
#include "hil_fw_im_foc.h"
#include "hil_fw_mpcc.h"
#include "hil_fw_mptc.h"
#include "hil_fw_state.h"

/* One line per controller: id suffix of hil_ids.h, phases, reset, reference stage, prediction stage
 * (NULL: a controller known to the DBC but not implemented here), then the parameters of its own it reads
 * beyond HIL_FW_PARAMS_COMMON (tests/firmware/test_controller_params.py checks each changes its output and
 * no other one does). */
#define ENTRY(ID, phases, reset, reference, predict, own)                                                     \
    [HIL_FW_CTRL_##ID] = {HIL_FW_CTRL_##ID##_NAME, HIL_FW_CTRL_##ID, phases, reset, reference, predict,       \
                          (uint64_t)(HIL_FW_PARAMS_COMMON | (own))}
#define P(name) HIL_FW_PARAM_BIT(HIL_FW_P_##name)

/* a parameter mask holds every id */
typedef char hil_fw_param_ids_fit_a_mask[HIL_FW_P_COUNT <= 64 ? 1 : -1];

static const hil_fw_controller_t table[HIL_FW_CTRL_COUNT] = {
    [HIL_FW_CTRL_OFF] = {HIL_FW_CTRL_OFF_NAME, HIL_FW_CTRL_OFF, 0u, NULL, NULL, NULL, 0u},
    ENTRY(MPCC, 3u, NULL, NULL, hil_fw_mpcc_predict, 0u),
    ENTRY(FCS_MPC_1, 3u, hil_fw_dsvm_reset, hil_fw_fcs_mpc1_reference, hil_fw_dsvm_restricted_predict,
          P(FCS_READING) | P(FLUX_REF) | P(TORQUE_BAND)),
    ENTRY(FCS_MPC_2, 3u, hil_fw_dsvm_reset, hil_fw_fcs_mpc2_reference, hil_fw_dsvm_restricted_predict,
          P(FCS_READING) | P(FLUX_REF) | P(TORQUE_BAND)),
    ENTRY(DSVM_20, 3u, hil_fw_dsvm_reset, NULL, hil_fw_dsvm20_predict, 0u),
    ENTRY(DBCC_MPC, 3u, hil_fw_dsvm_reset, hil_fw_dbcc_reference, hil_fw_dsvm_restricted_predict, 0u),
    ENTRY(FOC, 3u, NULL, hil_fw_foc_reference, hil_fw_foc_predict, P(CURRENT_KP) | P(CURRENT_KI) | P(PWM_DUTIES)),
    ENTRY(MPTC1, 6u, NULL, NULL, hil_fw_mptc1_predict, P(LAMBDA) | P(FLUX_REF)),
    ENTRY(MPTC2, 6u, NULL, NULL, hil_fw_mptc2_predict, P(LAMBDA) | P(FLUX_REF) | P(V3_SYMMETRIC)),
    ENTRY(MPTC3, 6u, NULL, NULL, hil_fw_mptc3_predict, P(FLUX_REF) | P(V3_SYMMETRIC) | P(TORQUE_BAND)),
    ENTRY(3VMPC, 3u, NULL, NULL, hil_fw_3vmpc_predict, P(ZERO_SELECT) | P(DT_COMP) | P(T_DEAD)),
    ENTRY(HV_MPFC, 3u, NULL, NULL, hil_fw_hv_mpfc_predict, P(T_THR) | P(ZERO_SELECT) | P(DT_COMP) | P(T_DEAD)),
    ENTRY(IM_FOC, 3u, NULL, hil_fw_im_foc_reference, hil_fw_im_foc_predict,
          P(CURRENT_KP) | P(CURRENT_KI) | P(RR) | P(LSIGMA) | P(LM) | P(PSI_R_REF)),
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
