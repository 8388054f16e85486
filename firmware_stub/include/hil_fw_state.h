/*
 * Reference firmware: the fixed-size state record and its configuration calls.
 */
#ifndef HIL_FW_STATE_H
#define HIL_FW_STATE_H

#include <stdint.h>

#include "hil_fw_config.h"
#include "hil_fw_dsvm.h"
#include "hil_fw_foc.h"
#include "hil_fw_hv_mpfc.h"
#include "hil_fw_im_foc.h"
#include "hil_fw_mpcc.h"
#include "hil_fw_mptc.h"
#include "hil_fw_speed_pi.h"
#include "hil_fw_types.h"

/* Speed loop runs every HIL_FW_SPEED_DIV control periods. */
#define HIL_FW_SPEED_DIV 1u

/* Outputs of the measurement stage for instant k. */
typedef struct {
    uint64_t t_ns;       /* sample time [ns] */
    uint16_t seq;        /* measurement seq */
    uint8_t n_phases;    /* phases in the frame */
    uint8_t plant_status;/* plant status code of the frame */
    uint8_t fault;       /* HIL_FW_STATUS_* of this frame (0: usable) */
    float i_alpha;       /* stator-frame current [A] */
    float i_beta;
    float i_d;           /* rotor-frame current [A] */
    float i_q;
    float theta_e;       /* electrical angle [rad] */
    float cos_th;        /* cos(theta_e) */
    float sin_th;        /* sin(theta_e) */
    float omega_m;       /* mechanical speed [rad/s] */
    float omega_e;       /* electrical speed [rad/s] */
    float vdc;           /* DC-link voltage used by the model [V] */
    float i_x;           /* six phases: stationary x-y current [A] (0 for three phases) */
    float i_y;
} hil_fw_measured_t;

/* References produced by the outer loop. */
typedef struct {
    float torque; /* [N*m] */
    float i_d;    /* [A] */
    float i_q;    /* [A] */
} hil_fw_refs_t;

/* The command applied by the plant during [k, k+1) (the one issued at step k-1), a mirrored
 * command expanded into its full sequence (so states[n_states - 1] is the last state applied). */
typedef struct {
    uint8_t n_states;
    uint8_t vector_id;
    uint8_t states[HIL_FW_MAX_APPLIED];
    uint32_t durations_ns[HIL_FW_MAX_APPLIED];
} hil_fw_applied_t;

typedef struct hil_fw_state {
    hil_fw_params_t params;
    hil_fw_speed_pi_t speed_pi;
    uint8_t controller_id; /* HIL_FW_CTRL_* */
    uint8_t enable;        /* 1: closed loop running */
    uint8_t mode;          /* HIL_FW_MODE_* */
    uint8_t speed_primed;  /* speed loop schedule started */
    float reference;       /* setpoint [rad/s] or [N*m] */
    uint64_t speed_next_ns;/* next speed-loop update time [ns] */
    hil_fw_measured_t meas;
    hil_fw_refs_t ref;
    hil_fw_applied_t applied;
    union { /* state of the selected controller; zeroed and reset on select and enable */
        hil_fw_mpcc_state_t mpcc;
        hil_fw_mptc_state_t mptc; /* mptc1, mptc2, mptc3 */
        hil_fw_dsvm_state_t dsvm; /* dsvm-20, fcs-mpc-1, fcs-mpc-2, dbcc-mpc */
        hil_fw_foc_state_t foc;
        hil_fw_hv_state_t hv; /* 3vmpc, hv-mpfc */
        hil_fw_im_foc_state_t im_foc;
    } ctrl;
} hil_fw_state_t;

/* Defaults: controller off, disabled, speed mode, Table 3 machine. */
void hil_fw_init(hil_fw_state_t *s);

/* Set one parameter (SI units); 0 or HIL_FW_E_PARAM_ID / HIL_FW_E_PARAM_VALUE (state unchanged). */
int hil_fw_set_param(hil_fw_state_t *s, uint8_t param_id, float value);

/* Read one parameter into *value; 0 or HIL_FW_E_PARAM_ID. */
int hil_fw_get_param(const hil_fw_state_t *s, uint8_t param_id, float *value);

/* Select the controller; a change of controller resets its state (hil_fw_controller_reset), selecting
 * the current one again keeps it. HIL_FW_E_CONTROLLER_ID (unknown) or HIL_FW_E_NOT_IMPLEMENTED leave the
 * previous selection in place. */
int hil_fw_select_controller(hil_fw_state_t *s, uint8_t controller_id);

/* Enable/disable and set the reference (mode 0: rad/s mechanical, 1: N*m). A rising enable edge resets
 * the selected controller's state (hil_fw_controller_reset); on a rising enable edge or a change into
 * speed mode the speed integrator is preset to torque_integrator_init. */
int hil_fw_set_setpoint(hil_fw_state_t *s, uint8_t enable, uint8_t mode, float reference);

#endif
