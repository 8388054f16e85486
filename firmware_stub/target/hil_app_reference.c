/* The reference firmware (firmware_stub/src) behind the firmware API (hil_app.h). Built with
 * HIL_APP_REFERENCE_PROFILED (the host's native loop, src/pmsm_hil/hil/runner/c/loop.c) each step is timed per stage and the
 * restricted-vs-full candidate diagnostic kept, as the Python in-process target does; read with
 * hil_app_reference_diag. */
#include <string.h>

#include "hil_app.h"
#include "hil_fw.h"
#ifdef HIL_APP_REFERENCE_PROFILED
#include "hil_fw_dsvm.h"
#include "hil_fw_profile.h"

static uint32_t diag_split_ns[3];
static uint8_t diag_full_miss = 255u;

void hil_app_reference_diag(uint32_t split_ns[3], uint8_t *full_miss);

void hil_app_reference_diag(uint32_t split_ns[3], uint8_t *full_miss)
{
    split_ns[0] = diag_split_ns[0];
    split_ns[1] = diag_split_ns[1];
    split_ns[2] = diag_split_ns[2];
    *full_miss = diag_full_miss;
}
#endif

static hil_fw_state_t fw;

void hil_app_init(void)
{
    hil_fw_init(&fw);
}

int hil_app_config(uint8_t param_id, float value)
{
    return hil_fw_set_param(&fw, param_id, value) == HIL_FW_OK ? HIL_APP_OK : HIL_APP_E_PARAM;
}

int hil_app_select(uint8_t controller_id)
{
    return hil_fw_select_controller(&fw, controller_id) == HIL_FW_OK ? HIL_APP_OK : HIL_APP_E_NOT_IMPLEMENTED;
}

void hil_app_reset(void)
{
    hil_fw_controller_reset(&fw); /* hil_fw_set_setpoint resets on the rising edge too: the same state */
}

int hil_app_setpoint(uint8_t enable, uint8_t mode, float reference)
{
    return hil_fw_set_setpoint(&fw, enable, mode, reference) == HIL_FW_OK ? HIL_APP_OK : HIL_APP_E_SETPOINT;
}

void hil_app_step(const hil_app_meas_t *m, hil_app_cmd_t *cmd)
{
    hil_fw_meas_t fm;
    hil_fw_cmd_t fc;
    uint8_t j;
    fm.seq = m->seq;
    fm.n_phases = m->n_phases;
    fm.status = 0u; /* as the Python virtual target: the plant status is not passed to the control law */
    for (j = 0u; j < HIL_FW_MAX_PHASES; ++j) {
        fm.i_abc[j] = m->i[j];
    }
    fm.theta_e = m->theta_e;
    fm.omega_m = m->omega_m;
    fm.vdc = m->vdc;
#ifdef HIL_APP_REFERENCE_PROFILED
    hil_fw_step_profiled(&fw, &fm, m->t_ns, &fc, diag_split_ns);
    diag_full_miss = hil_fw_dsvm_full_miss(&fw);
#else
    hil_fw_step(&fw, &fm, m->t_ns, &fc);
#endif
    cmd->n_states = fc.n_states;
    for (j = 0u; j < HIL_APP_MAX_STATES; ++j) {
        cmd->states[j] = fc.states[j];
        cmd->durations_ns[j] = fc.durations_ns[j];
    }
    cmd->mirror = fc.mirror;
    cmd->vector_id = fc.vector_id;
    cmd->candidates = fc.candidates;
    cmd->status = fc.status;
    cmd->torque_ref = fc.torque_ref;
    cmd->id_ref = fc.id_ref;
    cmd->iq_ref = fc.iq_ref;
    cmd->n_duties = fc.n_duties;
    for (j = 0u; j < HIL_APP_MAX_PHASES; ++j) {
        cmd->duty[j] = fc.n_duties > j ? fc.duty[j] : 0.0f;
    }
}
