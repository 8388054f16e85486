/*
 * Reference firmware: shared constants and the measurement / command records.
 * The protocol ids (HIL_FW_CTRL_*, HIL_FW_P_*, HIL_FW_STATUS_*, HIL_FW_MODE_*) are generated from the
 * DBC value tables into hil_ids.h (firmware_stub/generated, python -m pmsm_hil.protocol.gen_c).
 */
#ifndef HIL_FW_TYPES_H
#define HIL_FW_TYPES_H

#include <stdint.h>

#include "hil_ids.h"

#define HIL_FW_MAX_PHASES 6
#define HIL_FW_MAX_SUBSTATES 3
/* Sub-intervals of an applied (mirror-expanded) command: s0..s(n-1), s(n-2)..s0. */
#define HIL_FW_MAX_APPLIED (2 * HIL_FW_MAX_SUBSTATES - 1)

/* Return codes of the configuration calls (0 ok, negative error). */
#define HIL_FW_OK 0
#define HIL_FW_E_PARAM_ID (-1)        /* unknown param_id */
#define HIL_FW_E_PARAM_VALUE (-2)     /* value not finite or outside its physical range */
#define HIL_FW_E_CONTROLLER_ID (-3)   /* unknown controller_id */
#define HIL_FW_E_NOT_IMPLEMENTED (-4) /* known controller_id, not implemented in this firmware */
#define HIL_FW_E_MODE (-5)            /* unknown setpoint mode */
#define HIL_FW_E_REFERENCE (-6)       /* setpoint reference not finite */
#define HIL_FW_E_NULL (-7)            /* null state pointer */

/* One sampled measurement (instant k = t_ns / Ts). */
typedef struct {
    uint16_t seq;                    /* frame sequence number, echoed in the command */
    uint8_t n_phases;                /* 3 (three-phase) or 6 */
    uint8_t status;                  /* plant status code (recorded, not acted on) */
    float i_abc[HIL_FW_MAX_PHASES];  /* phase currents [A]; first n_phases used */
    float theta_e;                   /* rotor electrical angle [rad] */
    float omega_m;                   /* rotor mechanical speed [rad/s] */
    float vdc;                       /* measured DC-link voltage [V]; <= 0: use param vdc */
} hil_fw_meas_t;

/* Command k, applied by the plant over [(k+1)Ts, (k+2)Ts). */
typedef struct {
    uint16_t seq;                                /* echo of the measurement seq */
    uint8_t n_states;                            /* sub-intervals used, 1..3 */
    uint8_t vector_id;                           /* controller-specific vector index (MPCC: 0..7) */
    uint8_t candidates;                          /* candidate vectors evaluated this step */
    uint8_t status;                              /* HIL_FW_STATUS_* */
    uint8_t states[HIL_FW_MAX_SUBSTATES];        /* switching codes 4*Sa + 2*Sb + Sc */
    uint8_t full_miss;                           /* diagnostics (sim target only, untimed): 1 if the
                                                    full DSVM set beat the restricted set, 0 if not,
                                                    255 not computed */
    uint8_t mirror;                              /* 1: the plant applies states[0..n-1] then
                                                    states[n-2..0] with the same durations */
    uint32_t durations_ns[HIL_FW_MAX_SUBSTATES]; /* sub-interval lengths [ns]; sum = Ts [ns], with
                                                    mirror 2*(d0+..+d(n-2)) + d(n-1) = Ts */
    float torque_ref;                            /* debug: torque reference [N*m] */
    float id_ref;                                /* debug: d-axis current reference [A] */
    float iq_ref;                                /* debug: q-axis current reference [A] */
    float duty[HIL_FW_MAX_PHASES];               /* duty-cycle form (n_duties 3 or 6): per-leg duty 0..1 of a
                                                    centre-aligned PWM whose carrier period is Ts */
    uint8_t n_duties;                            /* 0: the switching states above; 3 or 6: the duties */
} hil_fw_cmd_t;

#endif
